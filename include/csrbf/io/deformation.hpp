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

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::io {

/// The vertices of one mesh that a deformation moves; the others keep their rest positions.
struct ActiveArea {
  std::size_t vertex_count = 0;          ///< vertices of the mesh it was picked on
  std::vector<std::uint32_t> vertices;   ///< sorted, unique, each < vertex_count
  bool operator==(const ActiveArea&) const = default;
};

struct DeformationSpec {
  FitOptions options;  ///< radius, kernel, polynomial (ordering and solver stay at their defaults)
  std::vector<Vec3> sources, destinations;
  std::optional<ActiveArea> area;  ///< empty: every vertex
  SpaceMap fit() const { return SpaceMap::fit(sources, destinations, options); }
};

/// Throws FileError naming `where` when a mesh of `vertices` vertices is not the one the area was picked on.
void check_active_area(const ActiveArea& area, std::size_t vertices, const std::string& where);
/// Moves `positions` (a mesh's rest vertices, in place) by `map` at `phase`, only inside `area` when
/// one is given. Throws FileError naming `where` when the mesh's vertex count is not the area's.
void apply_deformation(const SpaceMap& map, const std::optional<ActiveArea>& area, std::vector<Vec3>& positions,
                       double phase, const std::string& where);

/// Throws FileError naming the file and the JSON path of a bad or unknown value.
DeformationSpec read_deformation(const std::filesystem::path& path);
/// The same from JSON text: name is used in messages, base resolves a "controls" file.
DeformationSpec read_deformation_text(const std::string& text, const std::string& name,
                                      const std::filesystem::path& base);
/// Writes atomically (temporary file, then rename), numbers in their shortest exact form.
void write_deformation(const std::filesystem::path& path, const DeformationSpec& spec);

}  // namespace csrbf::io
