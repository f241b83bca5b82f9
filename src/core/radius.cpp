// The radius module (radius.hpp): the radius at which points have a number of neighbours, for
// csrbf::suggest_radius (estimate.hpp) and the interpolator's automatic radius (interpolator.cpp).
#include "radius.hpp"

#include "csrbf/neighbor_index.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace csrbf::detail {

/// The radius at which a point of `pts` has `neighbors` others within R on average, measured on a
/// seeded sample of kRadiusSample points: their distances to every point within a guess found with
/// NeighborIndex (linear time, where a bisection on R counting a sample against every point took ~25
/// steps, 0.4 s at 1e5 points), the radius being the distance that many of them fall
/// within. The guess comes from the box's volume in the dimensions it spans and doubles until the
/// sample has enough neighbours. Where there are too few points to have that many neighbours, the
/// box's diagonal (every point sees every other). Only the distances that can still be among the
/// `neighbors` x sample smallest are kept (at most twice that many), and that count is held to kRadiusPairs by
/// sampling fewer points for large `neighbors`: a guess far too large for clustered points (1e5
/// points in a box of side 1e-3, 10 far away) found 4e8 distances, 3.2 GB and 30-50 s, where the
/// memory limit allowed 0.5 GB.
constexpr std::size_t kRadiusSample = 4096;
constexpr double kRadiusPairs = double(std::size_t(1) << 22);
double neighbour_radius(std::span<const Vec3> pts, int dim, double neighbors) {
  const std::size_t n = pts.size();
  Vec3 lo = pts[0], hi = pts[0];
  for (const Vec3& p : pts) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double diag = (hi - lo).norm();
  if (!(diag > 0)) return 1.0;  // one point, or all at one position (refused later as duplicates)
  if (neighbors >= double(n) - 1) return diag * 1.0000001;
  double volume = 1;
  int spanned = 0;
  for (int a = 0; a < dim; ++a)
    if (hi[a] - lo[a] > 1e-9 * diag) {
      volume *= hi[a] - lo[a];
      ++spanned;
    }
  double r = std::pow(2.0 * neighbors / double(n) * volume / unit_ball(spanned), 1.0 / spanned);
  r = std::clamp(r, 1e-8 * diag, diag);
  const std::size_t samples =
      std::min({n, kRadiusSample, std::max<std::size_t>(1, std::size_t(kRadiusPairs / std::max(neighbors, 1.0)))});
  std::mt19937_64 rng(20261205);
  std::vector<std::size_t> picked(samples);
  for (std::size_t k = 0; k < samples; ++k) picked[k] = samples == n ? k : std::size_t(rng() % n);
  const auto need = std::max<std::size_t>(1, std::size_t(std::ceil(neighbors * double(samples))));
  // The squared distances found, cut back to the need smallest whenever they reach twice that
  // (nth_element: linear, where a heap's pushes took 0.02 s of the common case).
  std::vector<double> d2;
  d2.reserve(2 * need);
  const auto smallest = [&] { std::nth_element(d2.begin(), d2.begin() + std::ptrdiff_t(need - 1), d2.end()); };
  for (;;) {
    d2.clear();
    double bound = std::numeric_limits<double>::infinity();  // the need-th smallest after a cut
    const auto take = [&](std::size_t i, std::size_t j, double dd) {
      if (j == i || dd >= bound) return;
      d2.push_back(dd);
      if (d2.size() == 2 * need) {
        smallest();
        d2.resize(need);
        bound = d2[need - 1];
      }
    };
    const NeighborIndex index(pts, r);  // its points sorted by cell by a counting sort (neighbor_index.cpp)
    for (std::size_t i : picked) index.for_each_within(pts[i], [&](std::size_t j, double dd) { take(i, j, dd); });
    if (d2.size() >= need) {
      smallest();
      // Just past the need-th distance, so that it counts (neighbours are strictly within R).
      return std::max(std::sqrt(d2[need - 1]) * (1 + 1e-9), 1e-8 * diag);
    }
    if (r >= diag) return diag * 1.0000001;
    r = std::min(2 * r, diag);
  }
}

}  // namespace csrbf::detail
