// Controls text: one control vector a line, "sx sy sz dx dy dz" (source, then destination);
// "#" starts a comment; blank lines are allowed.
#pragma once

#include "csrbf/io/error.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/units.hpp"

#include <filesystem>
#include <istream>
#include <string>
#include <vector>

namespace csrbf::io {

struct Controls {
  std::vector<Vec3> sources, destinations;
  std::vector<int> lines;             ///< 1-based line of each control in its file
  std::vector<std::string> warnings;  ///< e.g. exact duplicates that were merged
  std::string name;                   ///< the file name, for messages
};

/// Parses controls; `name` is used in messages ("name:line: ..."). Exact duplicates (same source and
/// destination) are merged with a warning; the same source with another destination, a malformed
/// line, a non-finite number or no controls at all throw FileError.
Controls parse_controls(std::istream& in, const std::string& name);
/// memory_limit_bytes bounds the whole process (--memory-limit): the file's text (also from a pipe)
/// is read within what the process leaves of it (and 1 GiB, about 1.5e7 controls), and the controls
/// within what is left beside the text (57 bytes a line, counted before they are parsed).
Controls read_controls(const std::filesystem::path& path, double memory_limit_bytes = 4.0 * kGiB);
/// Writes controls atomically (temporary file, then rename).
void write_controls(const std::filesystem::path& path, const std::vector<Vec3>& sources,
                    const std::vector<Vec3>& destinations);

/// Shortest text that reads back as exactly the same double.
std::string format_number(double v);

}  // namespace csrbf::io
