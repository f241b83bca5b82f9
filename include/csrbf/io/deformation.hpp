// Deformation JSON: one CSRBF space mapping as the Picker saves it and the CLI and scenes read it.
//   {"format": "csrbf-deformation", "version": 1,
//    "kernel": "c2", "radius": 0.3, "polynomial": "none",
//    "sources": [[x, y, z], ...], "destinations": [[x, y, z], ...]}
// Instead of sources and destinations, "controls": "file.controls" names a controls text file,
// relative to the JSON file's folder. docs/scene-format.md describes every key.
#pragma once

#include "csrbf/io/error.hpp"
#include "csrbf/space_map.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace csrbf::io {

struct DeformationSpec {
  FitOptions options;  ///< radius, kernel, polynomial (ordering and solver stay at their defaults)
  std::vector<Vec3> sources, destinations;
  SpaceMap fit() const { return SpaceMap::fit(sources, destinations, options); }
};

/// Throws FileError naming the file and the JSON path of a bad or unknown value.
DeformationSpec read_deformation(const std::filesystem::path& path);
/// The same from JSON text: name is used in messages, base resolves a "controls" file.
DeformationSpec read_deformation_text(const std::string& text, const std::string& name,
                                      const std::filesystem::path& base);
/// Writes atomically (temporary file, then rename), numbers in their shortest exact form.
void write_deformation(const std::filesystem::path& path, const DeformationSpec& spec);

}  // namespace csrbf::io
