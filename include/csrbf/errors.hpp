// The exceptions of csrbf, one hierarchy. Each message names the offending value and where it came
// from (the index of the control point, the option); callers add file names and line numbers.
//
//   Error                      every failure csrbf reports
//   +- InvalidInput            bad input: sizes, non-finite numbers, a radius <= 0, an unknown name
//   |  +- DuplicateSource      two sources at one position
//   |  +- DegeneratePolynomial the sources do not determine the polynomial
//   |  +- IllConditioned       the fit cannot reach its accuracy
//   |  +- UsageError           options that contradict each other or lack a value (exit status 2)
//   +- NotPositiveDefinite     a factorisation met a pivot <= 0
//   +- ResourceLimit           more memory than allowed would be needed
//   +- io::FileError           a file cannot be read or written, or is malformed (csrbf/io/error.hpp)
//   +- render::RenderError     a movie cannot be rendered or encoded (csrbf/render/process.hpp)
//   +- mpi::Failure            an error agreed by every MPI rank (csrbf/mpi/runtime.hpp)
// Nothing else is thrown on purpose (std::bad_alloc aside): programs map UsageError to exit status 2
// and every other Error to 1.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

namespace csrbf {

/// text with every control character (below 0x20, and DEL) written as a JSON-style escape
/// ("\u001b"), so that a name from a file cannot drive the terminal, forge a line of output, or end
/// a message early (a NUL would end what()). keep_newlines: for many-line texts such as --help.
inline std::string printable(std::string_view text, bool keep_newlines = false) {
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if ((c < 0x20 && !(keep_newlines && c == '\n')) || c == 0x7f) {
      static constexpr char hex[] = "0123456789abcdef";
      out += "\\u00";
      out += hex[c >> 4];
      out += hex[c & 15];
    } else {
      out += ch;
    }
  }
  return out;
}

/// The base of every exception csrbf throws on purpose. Its message is printable() text.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(printable(message)) {}
  explicit Error(const char* message) : std::runtime_error(printable(message)) {}
};

/// Bad input: sizes, non-finite numbers, a radius <= 0, an unknown name.
class InvalidInput : public Error {
 public:
  using Error::Error;
};

/// Two control sources at the same position (the interpolation matrix would be singular).
/// first() < second() are their indices in the input.
class DuplicateSource : public InvalidInput {
 public:
  DuplicateSource(std::size_t first, std::size_t second, const std::string& message)
      : InvalidInput(message), first_(first), second_(second) {}
  std::size_t first() const noexcept { return first_; }
  std::size_t second() const noexcept { return second_; }

 private:
  std::size_t first_, second_;
};

/// The polynomial part cannot be determined by the sources: too few of them, or all coplanar or
/// collinear for a linear polynomial.
class DegeneratePolynomial : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// The fit cannot interpolate the controls to the documented accuracy (relative residual 1e-6):
/// sources too close together for the radius make the matrix nearly singular. The message names
/// the closest pair and the condition estimate.
class IllConditioned : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// A usage error: options or arguments that contradict each other or lack a value (no radius anywhere,
/// an output of another format, an unknown scenario). The programs exit with status 2 on it.
class UsageError : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// A pivot of a Cholesky factorisation is not positive: the matrix is not (numerically) positive
/// definite. row() is the row in the matrix's own order where it is known.
class NotPositiveDefinite : public Error {
 public:
  NotPositiveDefinite(std::size_t row, double pivot);
  /// When the failing row is not known (sparse solvers): row() is SIZE_MAX, pivot() NaN.
  explicit NotPositiveDefinite(const std::string& message);
  std::size_t row() const noexcept { return row_; }
  double pivot() const noexcept { return pivot_; }

 private:
  std::size_t row_;
  double pivot_;
};

/// A fit, an evaluation or a read would need more memory than allowed (FitOptions::memory_limit_bytes,
/// `--memory-limit`); the message says how much it would take. Not bad input: the same input fits
/// under a larger limit.
class ResourceLimit : public Error {
 public:
  using Error::Error;
};

/// Throws InvalidInput unless phase is finite and within [-1e6, 1e6].
void check_phase(double phase);

}  // namespace csrbf
