#pragma once

#include "csrbf/errors.hpp"

#include <string>

namespace csrbf::io {

/// A file could not be read or written, or its contents are malformed. The message names the
/// file (and the line or field where there is one) and the offending text or value.
class FileError : public csrbf::Error {
 public:
  using csrbf::Error::Error;
};

}  // namespace csrbf::io
