// csrbf::core alone: a fit moves a control's source to its destination.
#include <csrbf/space_map.hpp>
#include <csrbf/version.hpp>

#include <cmath>
#include <iostream>
#include <vector>

int main() {
  const std::vector<csrbf::Vec3> s{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, d{{0, 0, 0.1}, {1, 0, 0}, {0, 1, 0}};
  const auto map = csrbf::SpaceMap::fit(s, d, csrbf::FitOptions{0.8});
  const bool ok = std::abs(map.map(s[0]).z() - 0.1) < 1e-12 && map.map(csrbf::Vec3(5, 5, 5)) == csrbf::Vec3(5, 5, 5);
  std::cout << (ok ? "ok" : "wrong") << " (csrbf " << csrbf::kVersion << ")\n";
  return ok ? 0 : 1;
}
