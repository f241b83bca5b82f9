#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace csrbf::io {

/// A file could not be read or written, or its contents are malformed. The message names the
/// file (and the line or field where there is one) and the offending text or value.
class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Throws FileError unless path names something to read a file from: a regular file or a pipe.
/// `what` says what was expected ("a mesh"): a folder, a missing file, or a device such as /dev/zero
/// (which would never end) are refused by name.
void check_readable(const std::filesystem::path& path, const char* what);

}  // namespace csrbf::io
