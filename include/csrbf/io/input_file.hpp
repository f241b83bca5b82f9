// Inputs as csrbf reads them: only what can be read as a file (a regular file or a pipe), bounded
// in size, every error a FileError naming the file (csrbf::files, src/io/atomic_file.cpp).
#pragma once

#include "csrbf/io/error.hpp"
#include "csrbf/units.hpp"

#include <filesystem>
#include <string>

namespace csrbf::io {

/// Throws FileError unless path names something to read a file from: a regular file or a pipe.
/// `what` says what was expected ("a mesh"): a folder, a missing file, or a device such as /dev/zero
/// (which would never end) are refused by name.
void check_readable(const std::filesystem::path& path, const char* what);

/// The whole of a file (or a pipe) after check_readable. A FIFO that no writer opens within 60 s
/// is an error, not a hang; more than max_bytes is refused before (regular files) or while it is
/// read. Every error names the file.
std::string read_input(const std::filesystem::path& path, const char* what, double max_bytes = 4.0 * kGiB);

}  // namespace csrbf::io
