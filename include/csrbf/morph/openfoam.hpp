// OpenFOAM polyMesh: read points, faces, owner, neighbour and boundary (ASCII or binary, gzip'd or
// not, as OpenFOAM writes them) and write the points back in the input's own format and
// compression, every other byte as it was.
#pragma once

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/morph/volume_mesh.hpp"
#include "csrbf/units.hpp"

#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace csrbf::morph {

/// The points file as read, kept to write new points the same way.
struct FoamPointsFile {
  std::filesystem::path path;  ///< as found: ".../points" or ".../points.gz"
  /// Where moved points go: path, or with a time, that time's polyMesh/points (which may not exist
  /// yet: a time whose mesh is constant's gets its own moved points, as moveMesh writes them).
  std::filesystem::path target;
  bool binary = false;
  bool gzip = false;
  int scalar_bytes = 8;        ///< binary: 4 or 8 (arch "scalar=32|64")
  std::string text;            ///< the whole file, uncompressed
  std::size_t body_begin = 0;  ///< just past the list's '('
  std::size_t body_end = 0;    ///< at the list's ')'
};

struct FoamCase {
  std::filesystem::path root;       ///< the folder given: a case, or a polyMesh folder
  std::filesystem::path poly_mesh;  ///< root/constant/polyMesh, or root itself, or root/TIME/polyMesh
  std::string time;                 ///< the time folder read ("0.5"), or empty: constant
  VolumeMesh mesh;
  FoamPointsFile points_file;
};

/// Whether path is an OpenFOAM case folder (with constant/polyMesh) or a polyMesh folder.
bool is_openfoam(const std::filesystem::path& path);

/// Reads the polyMesh of a case folder or of a polyMesh folder. Every file is checked against the
/// others (point labels against the points, owner against faces, patches against faces) and any
/// error names the file, its line (ASCII) or the entry, and the value. Files are refused past
/// max_file_bytes (uncompressed). Throws io::FileError.
/// time: empty (constant/polyMesh), "latest" (the largest time folder) or a time ("0.5", matched
/// by value as OpenFOAM matches it): that time's polyMesh where it has one, file by file (points
/// from TIME/polyMesh/points when there, faces and the rest from TIME/polyMesh when it has faces),
/// else constant's, as OpenFOAM falls back. The moved points are written to TIME/polyMesh.
FoamCase read_openfoam(const std::filesystem::path& path, double max_file_bytes = 8.0 * kGiB,
                       const std::string& time = {});

/// The case's time folders (names that are numbers, "0" included), in increasing time.
std::vector<std::string> foam_times(const std::filesystem::path& case_folder);

/// The points file's bytes (uncompressed) with points in place of the old ones: the header, the
/// layout and every coordinate that did not change are kept byte for byte; a changed one is
/// written in the shortest form that reads back exactly.
std::string foam_points_bytes(const FoamCase& c, std::span<const Vec3> points);

/// Writes a copy of the case (or polyMesh folder) to out, a new folder, with the new points; out
/// must not exist and must not be inside the case. Atomic: a partial folder beside out is renamed
/// to out only when complete. Throws io::FileError.
void write_openfoam_copy(const FoamCase& c, std::span<const Vec3> points, const std::filesystem::path& out);
/// write_openfoam_copy's checks of out alone (it must not exist, nor lie inside the case, links
/// followed). Throws io::FileError.
void check_openfoam_copy_target(const FoamCase& c, const std::filesystem::path& out);

/// Copies c's case folder into the folder into (a partial of out, which messages name), links in
/// it kept as links; a case named through a link is copied from the folder it links to. Throws
/// io::FileError.
void copy_openfoam_case(const FoamCase& c, const std::filesystem::path& into, const std::filesystem::path& out);

/// Rewrites the points file alone, atomically (other files untouched).
void write_openfoam_in_place(const FoamCase& c, std::span<const Vec3> points);

/// For a case decomposed over MPI ranks, whose parts are written together, and for a motion
/// series (one moved mesh a time). time: where the points go, TIME/polyMesh of c's case (empty:
/// c's own target, FoamPointsFile::target):
/// - the points of c written into copy_root, a copy of c.root made by the caller (c's points file
///   at the same place in it), through a new file renamed over the copied one;
void write_openfoam_points_into(const FoamCase& c, std::span<const Vec3> points, const std::filesystem::path& copy_root,
                                const std::string& time = {});
/// - the points of c written beside c's points file, complete and checked, in a partial file of
///   csrbf's own (a new name, made exclusively: never a file or link already there), for
///   commit_openfoam_points to rename over it once every part has been staged. A partial that is
///   not committed is removed when it goes, or on a signal.
std::unique_ptr<io::Partial> stage_openfoam_points(const FoamCase& c, std::span<const Vec3> points,
                                                   const std::string& time = {});
void commit_openfoam_points(const FoamCase& c, io::Partial& staged, const std::string& time = {});
/// Where c's points go for a time (c's own target where time is empty). Throws io::FileError where
/// c was read from a polyMesh folder, not a case (it has no time folders).
std::filesystem::path foam_points_target(const FoamCase& c, const std::string& time);

}  // namespace csrbf::morph
