// Seeded random point sets and displacements shared by the core tests.
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/neighbor_index.hpp"

#include <cmath>
#include <random>
#include <vector>

namespace csrbf::test {

/// Every kernel the paper's tests run over, and every polynomial part.
inline constexpr Kernel kKernels[] = {Kernel::C0, Kernel::C2, Kernel::C4, Kernel::C6};
inline constexpr Polynomial kPolys[] = {Polynomial::None, Polynomial::Constant, Polynomial::Linear};

/// n points uniform in the cube [lo, hi]^3.
inline std::vector<Vec3> random_points(std::size_t n, std::mt19937& rng, double lo = 0, double hi = 1) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<Vec3> p(n);
  for (auto& x : p) x = Vec3(u(rng), u(rng), u(rng));
  return p;
}

/// n points uniform in the cube [lo, hi]^3, from their own generator seeded with seed.
inline std::vector<Vec3> seeded_points(std::size_t n, unsigned seed, double lo = 0, double hi = 1) {
  std::mt19937 rng(seed);
  return random_points(n, rng, lo, hi);
}

/// Destinations: sources moved by a smooth field plus noise (a realistic, non-affine deformation).
inline std::vector<Vec3> displaced(const std::vector<Vec3>& s, std::mt19937& rng) {
  std::normal_distribution<double> nd(0, 0.02);
  std::vector<Vec3> d(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    d[i] = s[i] + Vec3(0.05 * std::sin(3 * s[i].y()) + nd(rng), 0.03 * s[i].x() + nd(rng), nd(rng));
  return d;
}

}  // namespace csrbf::test
