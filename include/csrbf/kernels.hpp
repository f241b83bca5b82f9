// Wendland's compactly supported radial functions (Wendland 1995, "Piecewise polynomial, positive
// definite and compactly supported radial functions of minimal degree"), the members psi_{l,k} that
// are positive definite in R^3. Each has support radius 1: phi(r) = psi(r) for 0 <= r < 1, else 0.
// A support radius R is applied by the caller as r = distance / R.
#pragma once

#include <optional>
#include <string_view>

namespace csrbf {

enum class Kernel {
  C0,  ///< psi_{2,0}(r) = (1-r)^2                      (the paper's choice, C0)
  C2,  ///< psi_{3,1}(r) = (1-r)^4 (4r+1)               (C2, the paper's bouncing-ball example)
  C4,  ///< psi_{4,2}(r) = (1-r)^6 (35r^2+18r+3)        (C4)
  C6,  ///< psi_{5,3}(r) = (1-r)^8 (32r^3+25r^2+8r+1)   (C6)
};

/// Value phi(r) for r >= 0 (r is distance / R, not squared). Zero for r >= 1.
template <class T>
inline T wendland(Kernel k, T r) noexcept {
  if (!(r < T(1))) return T(0);
  const T s = T(1) - r;
  const T s2 = s * s;
  switch (k) {
    case Kernel::C0:
      return s2;
    case Kernel::C2: {
      const T s4 = s2 * s2;
      return s4 * (T(4) * r + T(1));
    }
    case Kernel::C4: {
      const T s6 = s2 * s2 * s2;
      return s6 * ((T(35) * r + T(18)) * r + T(3));
    }
    case Kernel::C6: {
      const T s4 = s2 * s2;
      return s4 * s4 * (((T(32) * r + T(25)) * r + T(8)) * r + T(1));
    }
  }
  return T(0);
}

/// Derivative dphi/dr for r >= 0. Zero for r >= 1. For C0 it is -2 at r = 0 (one-sided: psi_{2,0}
/// is only C0 as a radial function in R^3); C2, C4 and C6 have dphi/dr = 0 at r = 0.
template <class T>
inline T wendland_derivative(Kernel k, T r) noexcept {
  if (!(r < T(1))) return T(0);
  const T s = T(1) - r;
  const T s2 = s * s;
  switch (k) {
    case Kernel::C0:
      return T(-2) * s;
    case Kernel::C2:
      return T(-20) * r * s2 * s;
    case Kernel::C4: {
      const T s5 = s2 * s2 * s;
      return T(-56) * r * s5 * (T(5) * r + T(1));
    }
    case Kernel::C6: {
      const T s7 = s2 * s2 * s2 * s;
      return T(-22) * r * s7 * ((T(16) * r + T(7)) * r + T(1));
    }
  }
  return T(0);
}

/// "c0", "c2", "c4", "c6".
std::string_view kernel_name(Kernel k) noexcept;
/// Inverse of kernel_name (also accepts upper case and Wendland's "psi20", "psi31", "psi42", "psi53").
std::optional<Kernel> parse_kernel(std::string_view name) noexcept;
/// Order of continuity of the radial function in R^3: 0, 2, 4 or 6.
int kernel_smoothness(Kernel k) noexcept;

}  // namespace csrbf
