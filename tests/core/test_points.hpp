// Seeded random point sets shared by the core tests.
#pragma once

#include "csrbf/neighbor_index.hpp"

#include <random>
#include <vector>

namespace csrbf::test {

/// n points uniform in the cube [lo, hi]^3.
inline std::vector<Vec3> random_points(std::size_t n, std::mt19937& rng, double lo = 0, double hi = 1) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<Vec3> p(n);
  for (auto& x : p) x = Vec3(u(rng), u(rng), u(rng));
  return p;
}

}  // namespace csrbf::test
