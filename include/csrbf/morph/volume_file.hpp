// A volume mesh file of any format csrbf morph reads, behind one interface: its mesh, and writing
// it back with new points, to a new file or folder or in place, every other part as it was.
//   OpenFOAM case or polyMesh folder  csrbf/morph/openfoam.hpp (every byte but the coordinates kept)
//   .vtu, .vtk (unstructured grid)    VTK's readers and writers (every array kept; the encoding too)
//   .msh (Gmsh 2.2, 4.1)              Gmsh's library (version, ASCII or binary kept)
//   .cgns (unstructured zones)        the CGNS library: a copy whose coordinates are overwritten
#pragma once

#include "csrbf/morph/quality.hpp"
#include "csrbf/morph/volume_mesh.hpp"
#include "csrbf/units.hpp"

#include <filesystem>
#include <memory>
#include <span>
#include <string>

namespace csrbf::morph {

struct OpenOptions {
  /// VTK: the integer point or cell data array whose values name the patches ("patch_array" in
  /// the motion file).
  std::string patch_array;
  double max_file_bytes = 8.0 * kGiB;
  /// OpenFOAM: the time folder's mesh ("latest" or a time; empty: constant). Other formats refuse it.
  std::string time;
};

struct FoamCase;

class VolumeFile {
 public:
  virtual ~VolumeFile() = default;
  virtual const VolumeMesh& mesh() const = 0;
  /// "openfoam", "vtu", "vtk", "msh", "cgns".
  virtual std::string format() const = 0;
  /// How the input is encoded, kept on output ("ascii", "binary", "ascii, gzip", "msh 4.1 binary").
  virtual std::string encoding() const = 0;
  /// Writes the mesh with points to out, a new file (or folder, for OpenFOAM) of the same format,
  /// atomically. Throws io::FileError.
  virtual void write_copy(std::span<const Vec3> points, const std::filesystem::path& out) const = 0;
  /// Rewrites the input with points, atomically.
  virtual void write_in_place(std::span<const Vec3> points) const = 0;
  /// Where the mesh has no patches: what could name them ("; its integer arrays: a, b"), or "".
  virtual std::string patch_hint() const { return {}; }
  /// An OpenFOAM case's files (the decomposed morph writes each processor's points itself); null
  /// for the other formats.
  virtual const FoamCase* foam() const { return nullptr; }
};

/// Opens path by its kind: a folder is an OpenFOAM case, a file goes by its extension. Throws
/// io::FileError naming the file.
std::unique_ptr<VolumeFile> open_volume(const std::filesystem::path& path, const OpenOptions& options = {});

namespace detail {
/// The readers that need VTK's, CGNS's or Gmsh's libraries, and the standard cells' measure
/// (VTK's Verdict), reached through this table. The csrbf::morph_formats target fills it: linking
/// it registers them (its one object registers the table as the program starts), so that
/// csrbf::morph itself links none of those libraries. A program without it (csrbf's morph program
/// for OpenFOAM cases, which starts in a fraction of the time: docs/PERFORMANCE.md) has an empty
/// table, and open_volume then throws io::FileError naming the library and the target.
struct StandardFormats {
  std::unique_ptr<VolumeFile> (*open_vtk)(const std::filesystem::path&, const OpenOptions&) = nullptr;
  std::unique_ptr<VolumeFile> (*open_gmsh)(const std::filesystem::path&, const OpenOptions&) = nullptr;
  std::unique_ptr<VolumeFile> (*open_cgns)(const std::filesystem::path&, const OpenOptions&) = nullptr;
  CellQuality (*cell_quality)(const CellTopology&, std::span<const Vec3>, std::span<const Vec3>) = nullptr;
};
/// The registered table, or an empty one.
const StandardFormats& standard_formats();
/// Registers formats (which must outlive every call of standard_formats()); csrbf::morph_formats
/// calls it.
void register_standard_formats(const StandardFormats& formats);
}  // namespace detail

/// The formats by extension, for messages.
inline constexpr const char* kVolumeFormats =
    "an OpenFOAM case folder (or its constant/polyMesh), .vtu, .vtk, .msh or .cgns";

}  // namespace csrbf::morph
