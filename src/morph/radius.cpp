#include "radius.hpp"

#include "csrbf/fit_options.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/units.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <unordered_map>

namespace csrbf::morph::detail {

namespace {

/// At most `most` indices of [0, n), seeded: all of them where n is small.
std::vector<std::size_t> sample(std::size_t n, std::size_t most) {
  std::vector<std::size_t> s;
  if (n <= most) {
    s.resize(n);
    for (std::size_t i = 0; i < n; ++i) s[i] = i;
    return s;
  }
  std::mt19937_64 rng(20261204);
  s.resize(most);
  for (auto& i : s) i = std::size_t(rng() % n);
  return s;
}

std::string num(double v) { return format_significant(v, 4); }

}  // namespace

std::vector<Vec3> sorted_unique(std::vector<Vec3> v) {
  const auto less = [](const Vec3& a, const Vec3& c) {
    return std::lexicographical_compare(a.data(), a.data() + 3, c.data(), c.data() + 3);
  };
  std::sort(v.begin(), v.end(), less);
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

double boundary_spacing(std::span<const Vec3> controls, std::span<const Vec3> moving) {
  if (controls.size() < 2 || moving.empty()) return 0;
  const std::vector<std::size_t> picked = sample(moving.size(), 512);
  std::vector<double> nearest(picked.size(), std::numeric_limits<double>::infinity());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, picked.size(), 4),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t k = r.begin(); k < r.end(); ++k) {
                        const Vec3& p = moving[picked[k]];
                        double best = std::numeric_limits<double>::infinity();
                        for (const Vec3& q : controls) {
                          const double d = (q - p).squaredNorm();
                          if (d > 0 && d < best) best = d;
                        }
                        nearest[k] = std::sqrt(best);
                      }
                    });
  std::nth_element(nearest.begin(), nearest.begin() + std::ptrdiff_t(nearest.size() / 2), nearest.end());
  const double h = nearest[nearest.size() / 2];
  return std::isfinite(h) ? h : 0.0;
}

std::vector<Vec3> fitted_controls(std::span<const Vec3> moving, std::span<const Vec3> staying, double radius,
                                  bool local) {
  std::vector<Vec3> out(moving.begin(), moving.end());
  if (!local || moving.empty()) {
    out.insert(out.end(), staying.begin(), staying.end());
    return out;
  }
  const NeighborIndex near(moving, radius);
  for (const Vec3& s : staying) {
    bool keep = false;
    near.for_each_slot_within(s, [&](std::size_t, double) { keep = true; });
    if (keep) out.push_back(s);
  }
  return out;
}

/// The controls no two of which are closer than `spacing`, each taken where it is farther than that
/// from those taken before it, in order: indices, ascending.
std::vector<std::uint32_t> spaced_subset(std::span<const Vec3> sources, double spacing) {
  std::vector<std::uint32_t> out;
  if (sources.empty()) return out;
  // Cells counted from the sources' lower corner; where the box is more than 2^40 spacings across
  // (coordinates of 1e13 at a spacing of 1e-6) the cell numbers would overflow: every control
  // is taken (a coarse level that is the whole, which the plan then finds not worth it).
  Vec3 lo = sources[0], hi = sources[0];
  for (const Vec3& p : sources) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  if (!(spacing > 0) || !((hi - lo).maxCoeff() / spacing < 1099511627776.0)) {
    out.resize(sources.size());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = std::uint32_t(i);
    return out;
  }
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> cells;
  const double inv = 1.0 / spacing, s2 = spacing * spacing;
  const auto cell = [&](const Vec3& p, int a) { return std::int64_t(std::floor((p[a] - lo[a]) * inv)); };
  const auto key = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return (std::uint64_t(x) * 73856093ull) ^ (std::uint64_t(y) * 19349663ull) ^ (std::uint64_t(z) * 83492791ull);
  };
  for (std::size_t i = 0; i < sources.size(); ++i) {
    const Vec3& p = sources[i];
    const std::int64_t cx = cell(p, 0), cy = cell(p, 1), cz = cell(p, 2);
    bool free = true;
    for (std::int64_t dz = -1; dz <= 1 && free; ++dz)
      for (std::int64_t dy = -1; dy <= 1 && free; ++dy)
        for (std::int64_t dx = -1; dx <= 1 && free; ++dx) {
          const auto it = cells.find(key(cx + dx, cy + dy, cz + dz));
          if (it == cells.end()) continue;
          for (const std::uint32_t j : it->second)
            if ((sources[j] - p).squaredNorm() < s2) {
              free = false;
              break;
            }
        }
    if (!free) continue;
    cells[key(cx, cy, cz)].push_back(std::uint32_t(i));
    out.push_back(std::uint32_t(i));
  }
  return out;
}

RadiusChoice choose_radius(std::span<const Vec3> moving, std::span<const Vec3> staying, double displacement,
                           double size, double budget, bool local, bool two_levels) {
  std::vector<Vec3> all(moving.begin(), moving.end());
  all.insert(all.end(), staying.begin(), staying.end());
  const double h = boundary_spacing(all, moving);
  RadiusChoice c;
  const double by_motion = kDisplacementFactor * displacement, by_spacing = kSpacingFactor * h;
  c.radius = std::max(by_motion, by_spacing);
  c.why = by_motion >= by_spacing
              ? num(kDisplacementFactor) + " x the largest displacement " + num(displacement) +
                    " (the boundary's spacing is " + num(h) + ")"
              : num(kSpacingFactor) + " x the boundary's spacing " + num(h) + " (above " + num(kDisplacementFactor) +
                    " x the largest displacement " + num(displacement) + ")";
  if (c.radius > size) {
    c.radius = size;
    c.why += ", capped at the mesh's size";
  }
  // The largest R within the budget: memory, and neighbours per control (the time of the fit), of
  // one level, or where two levels may be taken (MorphOptions::levels) of theirs: a coarse level at
  // R of the controls R/4 apart and a fine one at kFineRadius x the boundary's spacing.
  const auto fits = [&](double r, FitMemoryEstimate* out = nullptr) {
    const std::vector<Vec3> s = fitted_controls(moving, staying, r, local);
    const FitMemoryEstimate e = estimate_fit_memory(s, r);
    if (out) *out = e;
    if (e.bytes <= budget && e.mean_neighbors <= kMostNeighbours) return true;
    if (!two_levels || kCoarseSpacing * r < 2 * h) return false;
    std::vector<Vec3> coarse;
    for (const std::uint32_t i : spaced_subset(s, kCoarseSpacing * r)) coarse.push_back(s[i]);
    const FitMemoryEstimate ec = estimate_fit_memory(coarse, r);
    const FitMemoryEstimate ef = estimate_fit_memory(s, std::min(kFineRadius * h, kCoarseSpacing * r));
    return ec.bytes + ef.bytes <= budget && ec.mean_neighbors <= kMostNeighbours &&
           ef.mean_neighbors <= kMostNeighbours;
  };
  FitMemoryEstimate at;
  const bool ok = fits(c.radius, &at);
  if (ok && (at.bytes > budget || at.mean_neighbors > kMostNeighbours)) {
    c.why += ", in two levels (one would need about " + num(at.bytes / kGiB) + " GiB and " + num(at.mean_neighbors) +
             " neighbours a control)";
  } else if (!ok) {
    const bool memory = at.bytes > budget;
    double lo = std::min(c.radius, std::max(h, 1e-9 * size)), hi = c.radius;
    for (int k = 0; k < 24 && hi - lo > 1e-3 * hi; ++k) {
      const double mid = 0.5 * (lo + hi);
      (fits(mid) ? lo : hi) = mid;
    }
    c.why += memory ? ", reduced from " + num(c.radius) + " where the fit would need about " + num(at.bytes / kGiB) +
                          " GiB, above what --memory-limit leaves it (" + num(budget / kGiB) + " GiB)"
                    : ", reduced from " + num(c.radius) + " where each control would have " + num(at.mean_neighbors) +
                          " neighbours (at most " + num(kMostNeighbours) + ")";
    c.radius = lo;
    if (lo < by_motion) c.why += "; below the displacement rule, cells near moving walls may shear: check the quality";
  }
  return c;
}

TwoLevelPlan plan_two_levels(std::span<const Vec3> sources, std::span<const Vec3> targets, double radius, double budget,
                             double neighbours, double bytes) {
  TwoLevelPlan plan;
  const std::size_t n = sources.size();
  plan.spacing = kCoarseSpacing * radius;
  if (n == 0) return plan;
  // The boundary's spacing: the median distance from a sampled moving control to its nearest other
  // control, looked for within the coarse spacing (the controls' grid at that size: a few
  // candidates each, where boundary_spacing's brute force costs N a sample).
  std::vector<std::size_t> moving;
  for (std::size_t i = 0; i < n; ++i)
    if (targets[i] != sources[i]) moving.push_back(i);
  // A spacing too small for the controls' extent (an index of more than 1e8 cells a side) plans
  // nothing: the boundary's spacing is taken as the coarse spacing, and a fit asked for anyway
  // meets the limit in its own index, which names it.
  Vec3 lo = sources[0], hi = sources[0];
  for (const Vec3& p : sources) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  std::optional<NeighborIndex> near;
  if ((hi - lo).maxCoeff() / plan.spacing <= 1e8) near.emplace(sources, plan.spacing);
  std::vector<double> nearest;
  for (const std::size_t k : sample(moving.size(), 512)) {
    const Vec3& p = sources[moving[k]];
    double best = plan.spacing * plan.spacing;
    if (near)
      near->for_each_slot_within(p, [&](std::size_t, double d2) {
        if (d2 > 0 && d2 < best) best = d2;
      });
    nearest.push_back(std::sqrt(best));
  }
  if (!nearest.empty()) {
    std::nth_element(nearest.begin(), nearest.begin() + std::ptrdiff_t(nearest.size() / 2), nearest.end());
    plan.boundary_spacing = nearest[nearest.size() / 2];
  }
  plan.fine_radius = std::min(kFineRadius * plan.boundary_spacing, plan.spacing);
  if (!(plan.fine_radius > 0)) plan.fine_radius = plan.spacing;
  // The fine level's neighbours per control, from the same sample and index (R_f <= the spacing).
  double fine_neighbours = 0;
  for (const std::size_t k : sample(moving.size(), 512))
    if (near)
      near->for_each_slot_within(sources[moving[k]], [&](std::size_t, double d2) {
        fine_neighbours += d2 > 0 && d2 < plan.fine_radius * plan.fine_radius;
      });
  if (!moving.empty()) fine_neighbours /= double(std::min<std::size_t>(moving.size(), 512));
  // The coarse controls: each one farther than the spacing from those taken before it, in order.
  plan.coarse = spaced_subset(sources, plan.spacing);
  std::vector<Vec3> coarse(plan.coarse.size());
  for (std::size_t k = 0; k < coarse.size(); ++k) coarse[k] = sources[plan.coarse[k]];
  if (neighbours < 0) {
    const FitMemoryEstimate e = estimate_fit_memory(sources, radius);
    neighbours = e.mean_neighbors;
    bytes = e.bytes;
  }
  const double nb_plain = neighbours;
  const double nb_coarse = estimate_fit_memory(coarse, radius).mean_neighbors;
  plan.seconds_plain = kSecondsPerEntry * double(n) * (1 + nb_plain);
  plan.seconds_two = kSecondsPerEntry * (double(coarse.size()) * (1 + nb_coarse) + double(n) * (1 + fine_neighbours));
  plan.plain_too_large = bytes > budget;
  plan.worth_it = plan.spacing >= 2 * plan.boundary_spacing &&
                  (plan.plain_too_large ||
                   (plan.seconds_plain >= kTwoLevelSeconds && plan.seconds_plain >= kTwoLevelGain * plan.seconds_two));
  return plan;
}

MorphPrediction predict(std::span<const Vec3> controls, std::span<const Vec3> points, int flat_axis, double mid,
                        double radius, double total_points, MorphBackend& b) {
  MorphPrediction p;
  const FitMemoryEstimate e = estimate_fit_memory(controls, radius);
  p.neighbours_per_control = e.mean_neighbors;
  p.bytes = e.bytes;
  double terms = 0, counted = 0;
  if (!controls.empty() && !points.empty()) {
    const NeighborIndex near(controls, radius);
    for (const std::size_t i : sample(points.size(), 512)) {
      Vec3 q = points[i];
      if (flat_axis >= 0) q[flat_axis] = mid;
      near.for_each_slot_within(q, [&](std::size_t, double) { terms += 1; });
      counted += 1;
    }
  }
  terms = b.sum(terms);
  counted = b.sum(counted);
  p.neighbours_per_point = counted > 0 ? terms / counted : 0.0;
  const double entries = double(controls.size()) * (1 + p.neighbours_per_control);
  p.seconds_fit = kSecondsPerEntry * entries;
  p.seconds_evaluate = total_points * (kSecondsPerPoint + kSecondsPerTerm * p.neighbours_per_point);
  return p;
}

}  // namespace csrbf::morph::detail
