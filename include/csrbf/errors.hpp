// Exceptions for bad input to the core. Each message names the offending value and where it came
// from (the index of the control point, the option); callers add file names and line numbers.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace csrbf {

/// Bad input: sizes, non-finite numbers, a radius <= 0, an unknown name.
class InvalidInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
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

/// A fit or evaluation would need more memory than allowed (FitOptions::memory_limit_bytes); the
/// message says how much it would take.
class ResourceLimit : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

/// Throws InvalidInput unless phase is finite and within [-1e6, 1e6].
void check_phase(double phase);

}  // namespace csrbf
