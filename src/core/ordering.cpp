#include "csrbf/ordering.hpp"

#include "csrbf/names.hpp"
#include "evaluator.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "csrbf/errors.hpp"

#include <algorithm>
#include <limits>
#include <cctype>
#include <cmath>
#include <numeric>
#include <string>

namespace csrbf {

AdjacencyGraph AdjacencyGraph::from_index(const NeighborIndex& index, std::span<const Vec3> points,
                                          double max_entries) {
  // Two parallel passes (the index's queries are const and thread-safe): count each point's
  // neighbours, then write each row, sorted by neighbour, into arrays allocated once at their size.
  // Both passes go through the points in the index's order (cell by cell), so that consecutive
  // queries visit the same cells while they are in cache; in the input order (a point cloud, a
  // spiral) each query fetched its 27 cells anew.
  AdjacencyGraph g;
  const std::size_t n = points.size();
  const std::span<const std::uint32_t> ids = index.sorted_ids();
  g.offsets.assign(n + 1, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 2048), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t slot = r.begin(); slot < r.end(); ++slot) {
      const std::size_t i = ids[slot];
      std::size_t c = 0;
      index.for_each_within(index.point(slot), [&](std::size_t j, double) { c += j != i; });
      g.offsets[i + 1] = c;
    }
  });
  for (std::size_t i = 0; i < n; ++i) g.offsets[i + 1] += g.offsets[i];
  detail::check_graph_entries(double(g.offsets[n]), max_entries, n);
  g.neighbors.resize(g.offsets[n]);
  g.dist2.resize(g.offsets[n]);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 2048), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<std::pair<std::uint32_t, double>> row;
    for (std::size_t slot = r.begin(); slot < r.end(); ++slot) {
      const std::size_t i = ids[slot];
      row.clear();
      index.for_each_within(index.point(slot), [&](std::size_t j, double d2) {
        if (j != i) row.emplace_back(std::uint32_t(j), d2);
      });
      std::sort(row.begin(), row.end());
      std::size_t at = g.offsets[i];
      for (const auto& [j, d2] : row) {
        g.neighbors[at] = j;
        g.dist2[at++] = d2;
      }
    }
  });
  return g;
}

AdjacencyGraph AdjacencyGraph::brute_force(std::span<const Vec3> points, double radius) {
  AdjacencyGraph g;
  const std::size_t n = points.size();
  const double r2 = radius * radius;
  g.offsets.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p = points[i];
    for (std::size_t j = 0; j < n; ++j) {
      const double d2 = (points[j] - p).squaredNorm();
      if (d2 < r2 && j != i) {
        g.neighbors.push_back(std::uint32_t(j));
        g.dist2.push_back(d2);
      }
    }
    g.offsets[i + 1] = g.neighbors.size();
  }
  return g;
}

std::string_view ordering_name(Ordering o) noexcept { return name_of(o); }
std::optional<Ordering> parse_ordering(std::string_view name) noexcept { return parse_name<Ordering>(name); }

std::vector<std::uint32_t> breadth_first_order(const AdjacencyGraph& g) {
  const std::size_t n = g.size();
  std::vector<std::uint32_t> out;
  out.reserve(n);
  std::vector<char> taken(n, 0);
  std::size_t next_start = 0;  // the first element of the paper's input_list
  while (out.size() < n) {
    while (taken[next_start]) ++next_start;
    taken[next_start] = 1;
    out.push_back(std::uint32_t(next_start));
    for (std::size_t i = out.size() - 1; i < out.size(); ++i)
      for (std::uint32_t j : g.neighbors_of(out[i]))
        if (!taken[j]) {
          taken[j] = 1;
          out.push_back(j);
        }
  }
  return out;
}

namespace {

// Breadth-first levels from root over the nodes not yet taken; returns the nodes in visiting order and
// the start of the last level. mark[] is set to stamp for visited nodes.
std::size_t levels_from(const AdjacencyGraph& g, std::uint32_t root, const std::vector<char>& taken,
                        std::vector<std::uint32_t>& mark, std::uint32_t stamp, std::vector<std::uint32_t>& visit,
                        std::size_t& depth) {
  visit.clear();
  visit.push_back(root);
  mark[root] = stamp;
  std::size_t level_begin = 0;
  depth = 0;
  while (true) {
    const std::size_t level_end = visit.size();
    for (std::size_t i = level_begin; i < level_end; ++i)
      for (std::uint32_t j : g.neighbors_of(visit[i]))
        if (!taken[j] && mark[j] != stamp) {
          mark[j] = stamp;
          visit.push_back(j);
        }
    if (visit.size() == level_end) return level_begin;
    level_begin = level_end;
    ++depth;
  }
}

}  // namespace

std::vector<std::uint32_t> reverse_cuthill_mckee_order(const AdjacencyGraph& g) {
  const std::size_t n = g.size();
  std::vector<std::uint32_t> out, visit, mark(n, 0);
  out.reserve(n);
  std::vector<char> taken(n, 0);
  std::uint32_t stamp = 0;
  std::vector<std::uint32_t> nb;
  for (std::size_t start = 0; start < n; ++start) {
    if (taken[start]) continue;
    // Pseudo-peripheral node (George & Liu's algorithm): move to a minimum-degree node of the last
    // level while the eccentricity grows.
    auto root = std::uint32_t(start);
    std::size_t depth = 0;
    std::size_t last = levels_from(g, root, taken, mark, ++stamp, visit, depth);
    for (int iter = 0; iter < 16; ++iter) {
      std::uint32_t best = visit[last];
      for (std::size_t i = last; i < visit.size(); ++i)
        if (g.degree(visit[i]) < g.degree(best)) best = visit[i];
      std::size_t d2 = 0;
      std::vector<std::uint32_t> v2;
      const std::size_t last2 = levels_from(g, best, taken, mark, ++stamp, v2, d2);
      if (d2 <= depth) break;
      root = best;
      depth = d2;
      last = last2;
      visit.swap(v2);
    }
    const std::size_t begin = out.size();
    taken[root] = 1;
    out.push_back(root);
    for (std::size_t i = begin; i < out.size(); ++i) {
      nb.clear();
      for (std::uint32_t j : g.neighbors_of(out[i]))
        if (!taken[j]) nb.push_back(j);
      std::stable_sort(nb.begin(), nb.end(),
                       [&](std::uint32_t a, std::uint32_t b) { return g.degree(a) < g.degree(b); });
      for (std::uint32_t j : nb) {
        taken[j] = 1;
        out.push_back(j);
      }
    }
  }
  std::reverse(out.begin(), out.end());
  return out;
}

std::vector<std::uint32_t> identity_order(std::size_t n) {
  std::vector<std::uint32_t> o(n);
  std::iota(o.begin(), o.end(), 0u);
  return o;
}

std::vector<std::uint32_t> reversed_order(std::span<const std::uint32_t> order) {
  return {order.rbegin(), order.rend()};
}

std::vector<std::size_t> envelope_first_columns(const AdjacencyGraph& g, std::span<const std::uint32_t> order) {
  const std::size_t n = g.size();
  std::vector<std::uint32_t> pos(n);
  for (std::size_t k = 0; k < n; ++k) pos[order[k]] = std::uint32_t(k);
  std::vector<std::size_t> first(n);
  for (std::size_t k = 0; k < n; ++k) {
    std::size_t f = k;
    for (std::uint32_t j : g.neighbors_of(order[k])) f = std::min<std::size_t>(f, pos[j]);
    first[k] = f;
  }
  return first;
}

FactorCount cholesky_factor_count(const AdjacencyGraph& g, std::span<const std::uint32_t> order, double max_entries) {
  const std::size_t n = g.size();
  constexpr std::uint32_t none = ~std::uint32_t(0);
  std::vector<std::uint32_t> position(n), parent(n, none), ancestor(n, none), mark(n, none), count(n, 1);
  for (std::size_t k = 0; k < n; ++k) position[order[k]] = std::uint32_t(k);
  // The elimination tree: for each entry (k, i) below the diagonal, i's root so far (path
  // compressed) gets parent k.
  for (std::uint32_t k = 0; k < n; ++k)
    for (std::uint32_t nb : g.neighbors_of(order[k]))
      for (std::uint32_t i = position[nb]; i != none && i < k;) {
        const std::uint32_t next = ancestor[i];
        ancestor[i] = k;
        if (next == none) parent[i] = k;
        i = next;
      }
  // Row k of L holds the nodes on the tree's paths from each i (A(k, i) != 0, i < k) up to k.
  double entries = double(n);
  for (std::uint32_t k = 0; k < n; ++k) {
    mark[k] = k;
    for (std::uint32_t nb : g.neighbors_of(order[k]))
      for (std::uint32_t j = position[nb]; j < k && mark[j] != k; j = parent[j]) {
        ++count[j];
        mark[j] = k;
        entries += 1;
      }
    if (entries > max_entries) {
      constexpr double inf = std::numeric_limits<double>::infinity();
      return {inf, inf};
    }
  }
  FactorCount f;
  for (std::uint32_t c : count) {
    f.entries += double(c);
    f.flops += double(c) * double(c);
  }
  return f;
}

double envelope_work(std::span<const std::size_t> first_columns) noexcept {
  double work = 0.0;
  for (std::size_t k = 0; k < first_columns.size(); ++k) {
    const double len = double(k - first_columns[k] + 1);
    work += 0.5 * len * len;
  }
  return work;
}

Profile profile(const AdjacencyGraph& g, std::span<const std::uint32_t> order) {
  Profile p;
  const auto first = envelope_first_columns(g, order);
  for (std::size_t k = 0; k < first.size(); ++k) {
    p.envelope += k - first[k];
    p.bandwidth = std::max(p.bandwidth, k - first[k]);
  }
  return p;
}

OrderingChoice choose_ordering(const AdjacencyGraph& g, Ordering requested, std::vector<std::uint32_t> rcm) {
  OrderingChoice c;
  auto id = identity_order(g.size());
  auto bf = breadth_first_order(g);
  auto rbf = reversed_order(bf);
  if (rcm.empty()) rcm = reverse_cuthill_mckee_order(g);
  c.identity = profile(g, id);
  c.reverse_cuthill_mckee = profile(g, rcm);
  c.breadth_first = profile(g, bf);
  c.reverse_breadth_first = profile(g, rbf);
  if (requested == Ordering::Auto) {
    requested = Ordering::ReverseCuthillMcKee;
    std::size_t best = c.reverse_cuthill_mckee.envelope;
    if (c.reverse_breadth_first.envelope < best) {
      requested = Ordering::ReverseBreadthFirst;
      best = c.reverse_breadth_first.envelope;
    }
    if (c.breadth_first.envelope < best) {
      requested = Ordering::BreadthFirst;
      best = c.breadth_first.envelope;
    }
    if (c.identity.envelope < best) requested = Ordering::Identity;
  }
  c.chosen = requested;
  switch (requested) {
    case Ordering::Identity:
      c.order = std::move(id);
      break;
    case Ordering::BreadthFirst:
      c.order = std::move(bf);
      break;
    case Ordering::ReverseCuthillMcKee:
      c.order = std::move(rcm);
      break;
    default:
      c.order = std::move(rbf);
      break;
  }
  return c;
}

namespace {

/// One nested dissection: the state shared by the recursion.
class Dissection {
 public:
  Dissection(const AdjacencyGraph& g, std::span<const Vec3> points, double radius, std::size_t leaf)
      : g_(g), points_(points), radius_(radius), leaf_(std::max<std::size_t>(leaf, 1)), side_(points.size(), 0) {
    order_.reserve(points.size());
  }

  std::vector<std::uint32_t> run() {
    std::vector<std::uint32_t> ids = identity_order(points_.size());
    cut(ids, 0, ids.size());
    return std::move(order_);
  }

 private:
  // side_ flags: which half (kLeft or kRight) and whether the point touches the other half.
  static constexpr std::uint8_t kLeft = 1, kRight = 2, kHalf = 3, kTouches = 4;

  void keep(const std::vector<std::uint32_t>& ids, std::size_t b, std::size_t e) {
    order_.insert(order_.end(), ids.begin() + std::ptrdiff_t(b), ids.begin() + std::ptrdiff_t(e));
  }

  // Orders ids[b, e) (a set with no edges to the points not yet ordered outside it, but for
  // separators placed later) and appends it to order_.
  void cut(std::vector<std::uint32_t>& ids, std::size_t b, std::size_t e) {
    const auto first = ids.begin() + std::ptrdiff_t(b), last = ids.begin() + std::ptrdiff_t(e);
    if (e - b <= leaf_) return keep(ids, b, e);
    Vec3 lo = points_[ids[b]], hi = lo;
    for (auto it = first; it != last; ++it) {
      lo = lo.cwiseMin(points_[*it]);
      hi = hi.cwiseMax(points_[*it]);
    }
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    if (!(hi[axis] - lo[axis] > 2 * radius_)) return keep(ids, b, e);  // a dense block anyway
    const auto mid = first + std::ptrdiff_t((e - b) / 2);
    std::nth_element(first, mid, last,
                     [&](std::uint32_t p, std::uint32_t q) { return points_[p][axis] < points_[q][axis]; });
    const double m = points_[*mid][axis];
    for (auto it = first; it != last; ++it) side_[*it] = points_[*it][axis] < m ? kLeft : kRight;
    // Only points closer than R to the plane can have a neighbour across it.
    std::size_t touching[3] = {0, 0, 0};
    for (auto it = first; it != last; ++it) {
      const std::uint32_t v = *it;
      if (!(std::abs(points_[v][axis] - m) < radius_)) continue;
      const std::uint8_t other = (side_[v] & kHalf) == kLeft ? kRight : kLeft;
      for (std::uint32_t u : g_.neighbors_of(v))
        if ((side_[u] & kHalf) == other) {
          ++touching[side_[v] & kHalf];
          side_[v] |= kTouches;
          break;
        }
    }
    const std::uint8_t sep = touching[kLeft] <= touching[kRight] ? kLeft : kRight;
    const auto part = [&](std::uint32_t v) {  // 0 left half, 1 right half, 2 separator
      const std::uint8_t f = side_[v];
      return (f & kTouches) && (f & kHalf) == sep ? 2 : (f & kHalf) == kLeft ? 0 : 1;
    };
    const auto left_end = std::partition(first, last, [&](std::uint32_t v) { return part(v) == 0; });
    const auto right_end = std::partition(left_end, last, [&](std::uint32_t v) { return part(v) == 1; });
    for (auto it = first; it != last; ++it) side_[*it] = 0;
    const auto l = std::size_t(left_end - ids.begin()), r = std::size_t(right_end - ids.begin());
    if (l == b || r == l) return keep(ids, b, e);  // nothing to cut off
    cut(ids, b, l);  // each cut reorders only its own range: ids[r, e) stays the separator
    cut(ids, l, r);
    keep(ids, r, e);
  }

  const AdjacencyGraph& g_;
  std::span<const Vec3> points_;
  double radius_;
  std::size_t leaf_;
  std::vector<std::uint8_t> side_;
  std::vector<std::uint32_t> order_;
};

}  // namespace

std::vector<std::uint32_t> nested_dissection_order(const AdjacencyGraph& g, std::span<const Vec3> points, double radius,
                                                   std::size_t leaf) {
  if (points.size() != g.size())
    throw InvalidInput("nested_dissection_order: " + std::to_string(points.size()) + " points for a graph of " +
                       std::to_string(g.size()));
  return Dissection(g, points, radius, leaf).run();
}

}  // namespace csrbf
