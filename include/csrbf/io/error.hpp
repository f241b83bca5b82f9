#pragma once

#include "csrbf/errors.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>

namespace csrbf::io {

/// A file could not be read or written, or its contents are malformed. The message names the
/// file (and the line or field where there is one) and the offending text or value.
class FileError : public csrbf::Error {
 public:
  using csrbf::Error::Error;
};

/// Throws FileError unless path names something to read a file from: a regular file or a pipe.
/// `what` says what was expected ("a mesh"): a folder, a missing file, or a device such as /dev/zero
/// (which would never end) are refused by name.
void check_readable(const std::filesystem::path& path, const char* what);

/// The whole of a file (or a pipe) after check_readable. A FIFO that no writer opens within 60 s
/// is an error, not a hang; more than max_bytes is refused before (regular files) or while it is
/// read. Every error names the file.
std::string read_input(const std::filesystem::path& path, const char* what, double max_bytes = 4.0 * (1ull << 30));

}  // namespace csrbf::io
