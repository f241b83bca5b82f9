// libFuzzer target: SpaceMap fit and apply on arbitrary bytes turned into points (scripts/fuzz.sh).
// Byte 0: kernel and polynomial; then doubles: the radius, then up to 64 source/destination pairs;
// the points evaluated are the sources, their midpoints and a few shifted copies. A fit either throws
// one of csrbf's errors or gives finite results that interpolate the controls.
#include "csrbf/space_map.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 + 8) return 0;
  const std::uint8_t mode = data[0];
  csrbf::FitOptions o;
  o.kernel = std::array{csrbf::Kernel::C0, csrbf::Kernel::C2, csrbf::Kernel::C4, csrbf::Kernel::C6}[mode & 3];
  o.polynomial = std::array{csrbf::Polynomial::None, csrbf::Polynomial::Constant, csrbf::Polynomial::Linear,
                            csrbf::Polynomial::None}[(mode >> 2) & 3];
  o.ordering = std::array{csrbf::Ordering::Auto, csrbf::Ordering::BreadthFirst, csrbf::Ordering::ReverseCuthillMcKee,
                          csrbf::Ordering::Identity}[(mode >> 4) & 3];
  o.solver = (mode >> 6) & 1 ? csrbf::Solver::Eigen : csrbf::Solver::Auto;
  std::vector<double> v((size - 1) / 8);
  std::memcpy(v.data(), data + 1, v.size() * 8);
  o.radius = v[0];
  const std::size_t n = std::min<std::size_t>((v.size() - 1) / 6, 64);
  std::vector<csrbf::Vec3> s(n), d(n);
  for (std::size_t i = 0; i < n; ++i) {
    s[i] = csrbf::Vec3(v[1 + 6 * i], v[2 + 6 * i], v[3 + 6 * i]);
    d[i] = csrbf::Vec3(v[4 + 6 * i], v[5 + 6 * i], v[6 + 6 * i]);
  }
  try {
    const auto map = csrbf::SpaceMap::fit(s, d, o);
    std::vector<double> pts;
    for (std::size_t i = 0; i < n; ++i) {
      const csrbf::Vec3 mid = (s[i] + s[(i + 1) % n]) / 2;
      for (const csrbf::Vec3& p : {s[i], mid, csrbf::Vec3(s[i] + csrbf::Vec3::Constant(o.radius / 3))})
        pts.insert(pts.end(), {p.x(), p.y(), p.z()});
    }
    std::vector<double> out(pts.size());
    map.apply(pts.data(), out.data(), pts.size() / 3, 1.0);
    std::vector<float> fin(pts.begin(), pts.end()), fout(pts.size());
    map.apply(fin.data(), fout.data(), fin.size() / 3, 0.5);
    for (const double x : out)
      if (!std::isfinite(x)) __builtin_trap();
    // Interpolation: the map takes each source to its destination, relative to the largest
    // displacement (a displacement of 1e52 next to ones of 1 leaves rounding of 1e36 in all of them)
    // and to the fit's own residual (the fast path rounds differently from the fit's check).
    double gmax = 1;
    for (std::size_t i = 0; i < n; ++i) gmax = std::max(gmax, (d[i] - s[i]).norm());
    const double tol = 1e-6 * gmax + 10 * map.stats().residual_max;
    for (std::size_t i = 0; i < n; ++i) {
      const csrbf::Vec3 y(out[9 * i], out[9 * i + 1], out[9 * i + 2]);
      if ((y - d[i]).norm() > tol) __builtin_trap();
    }
  } catch (const csrbf::InvalidInput&) {
  } catch (const csrbf::NotPositiveDefinite&) {
  }
  return 0;
}
