// Deformation JSON: one CSRBF space mapping as the Picker saves it and the CLI and scenes read it.
//   {"format": "csrbf-deformation", "version": 1,
//    "kernel": "c2", "radius": 0.3, "polynomial": "none",
//    "sources": [[x, y, z], ...], "destinations": [[x, y, z], ...]}
// Instead of sources and destinations, "controls": "file.controls" names a controls text file,
// relative to the JSON file's folder. An optional "active_area": {"vertex_count": N, "vertices":
// [i, ...]} limits the deformation to those vertices of a mesh of N vertices (the Picker's ctrl + drag
// area); the others stay where they are. docs/scene-format.md describes every key.
#pragma once

#include "csrbf/io/error.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/units.hpp"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::io {

/// The vertices of one mesh that a deformation moves; the others keep their rest positions.
struct ActiveArea {
  std::size_t vertex_count = 0;         ///< vertices of the mesh it was picked on
  std::vector<std::uint32_t> vertices;  ///< sorted, unique, each < vertex_count
  /// Bounding box (min, max corners) of those vertices' rest positions, when written: a mesh of the
  /// same count but in another vertex order (an STL, a re-export) is refused, not deformed wrongly.
  std::optional<std::array<Vec3, 2>> bounds;
  bool operator==(const ActiveArea&) const = default;
  /// The area of `vertices` of a mesh with rest positions `rest`, its bounds included.
  static ActiveArea of(const std::vector<Vec3>& rest, std::vector<std::uint32_t> vertices);
};

struct DeformationSpec {
  FitOptions options;  ///< radius, kernel, polynomial (ordering and solver stay at their defaults)
  std::vector<Vec3> sources, destinations;
  std::optional<ActiveArea> area;  ///< empty: every vertex
  /// The phase in [0, 1] it was made to be seen at (the Picker writes the one it showed); `csrbf
  /// deform` uses it where --phase is not given. A scene's schedule sets its own phase instead.
  std::optional<double> phase;
  SpaceMap fit() const { return SpaceMap::fit(sources, destinations, options); }
};

/// Throws FileError naming `where` (the deformation file) and `mesh` when a mesh with rest positions
/// `rest` is not the one the area was picked on: another vertex count, or the area's vertices
/// outside its bounds by more than 1e-6 of their size (another vertex order).
void check_active_area(const ActiveArea& area, const std::vector<Vec3>& rest, const std::string& where,
                       const std::string& mesh);
/// Moves `positions` (a mesh's rest vertices, in place) by `map` at `phase`, only inside `area` when
/// one is given. The area must have been checked against the mesh (check_active_area).
void apply_deformation(const SpaceMap& map, const std::optional<ActiveArea>& area, std::vector<Vec3>& positions,
                       double phase);

/// Throws FileError naming the file and the JSON path of a bad or unknown value.
/// max_bytes bounds the JSON text (also from a pipe; parsed JSON takes about 16 times its text):
/// at most 1 GiB.
DeformationSpec read_deformation(const std::filesystem::path& path, double max_bytes = kGiB);
/// The same from JSON text: name is used in messages, base resolves a "controls" file.
DeformationSpec read_deformation_text(const std::string& text, const std::string& name,
                                      const std::filesystem::path& base);
/// Writes atomically (temporary file, then rename), numbers in their shortest exact form.
void write_deformation(const std::filesystem::path& path, const DeformationSpec& spec);

}  // namespace csrbf::io
