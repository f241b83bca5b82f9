// Orderings of the control points that make the CSRBF matrix A band-diagonal, and the profile
// (bandwidth, envelope) they give.
//
// The paper's Figure 3 is a breadth-first sort of the neighbour graph: the first unsorted point
// starts a level, each sorted point in turn appends its unsorted neighbours. It is the Cuthill-McKee
// scheme without the degree sort (George & Liu 1981, ch. 4); reversing it (RCM) never enlarges the
// envelope of a Cuthill-McKee order and usually shrinks it.
#pragma once

#include "csrbf/neighbor_index.hpp"

#include <cstdint>
#include <limits>
#include <span>
#include <string_view>
#include <optional>
#include <vector>

namespace csrbf {

/// Symmetric neighbour graph of a point set in compressed-row form: the neighbours of i (every j != i
/// with ||x_i - x_j|| < R) are neighbors[offsets[i] .. offsets[i+1]), ascending, with the squared
/// distances alongside in dist2.
struct AdjacencyGraph {
  std::vector<std::size_t> offsets{0};
  FillVector<std::uint32_t> neighbors;
  FillVector<double> dist2;

  std::size_t size() const noexcept { return offsets.size() - 1; }
  std::size_t degree(std::size_t i) const noexcept { return offsets[i + 1] - offsets[i]; }
  std::span<const std::uint32_t> neighbors_of(std::size_t i) const noexcept {
    return {neighbors.data() + offsets[i], degree(i)};
  }
  std::span<const double> dist2_of(std::size_t i) const noexcept { return {dist2.data() + offsets[i], degree(i)}; }

  /// Builds the graph of points through the index (which must have been built over the same points).
  /// max_entries: ResourceLimit (before the rows are allocated) where the graph, counted, holds more
  /// entries (both directions) than this.
  static AdjacencyGraph from_index(const NeighborIndex& index, std::span<const Vec3> points,
                                   double max_entries = std::numeric_limits<double>::infinity());
  /// The same graph by testing every pair: O(N^2), the fastest way for a few hundred points.
  static AdjacencyGraph brute_force(std::span<const Vec3> points, double radius);
};

enum class Ordering {
  Identity,             ///< input order
  BreadthFirst,         ///< paper Figure 3
  ReverseBreadthFirst,  ///< Figure 3 reversed
  ReverseCuthillMcKee,  ///< George & Liu's RCM: pseudo-peripheral start, neighbours by degree, reversed
  Auto,                 ///< the smallest envelope of the four (ties: RCM, reverse, forward, identity)
};
std::string_view ordering_name(Ordering o) noexcept;
std::optional<Ordering> parse_ordering(std::string_view name) noexcept;

/// order[k] = index of the point placed at position k.
std::vector<std::uint32_t> breadth_first_order(const AdjacencyGraph& g);
/// Reverse Cuthill-McKee (George & Liu 1981, sections 4.3-4.4): each component starts at a
/// pseudo-peripheral node, neighbours are appended by ascending degree, and the result is reversed.
std::vector<std::uint32_t> reverse_cuthill_mckee_order(const AdjacencyGraph& g);
std::vector<std::uint32_t> identity_order(std::size_t n);
std::vector<std::uint32_t> reversed_order(std::span<const std::uint32_t> order);

/// Geometric nested dissection, the fill-reducing order csrbf gives the general sparse Cholesky
/// (CHOLMOD): the points are cut at the median of their longest axis, the points on one side that
/// have a neighbour on the other (the smaller such set) become the separator, placed after both
/// halves, and each half is cut again, down to `leaf` points or a slab no wider than 2R. The
/// separators are graph separators: no edge of g joins the two halves. The points' coordinates make
/// the cuts cheap (about 0.1 s for 1e5 points, against about 1 s for METIS's multilevel partitioning);
/// on control points over a surface the factor takes about 40% fewer flops than with AMD.
std::vector<std::uint32_t> nested_dissection_order(const AdjacencyGraph& g, std::span<const Vec3> points, double radius,
                                                   std::size_t leaf = 16);

/// The Cholesky factor L of the graph's matrix (plus the diagonal) in `order`, counted from its
/// elimination tree (Liu 1990), each row's subtree walked once, no numbers: its entries and the
/// flops of the factorisation as CHOLMOD's analysis counts them (the column counts squared, summed).
/// What Auto weighs a direct solver by, at a small part of CHOLMOD's analysis's cost. The work is one
/// step per entry of L: past `max_entries` the count stops, and both figures are infinite.
struct FactorCount {
  double entries = 0;
  double flops = 0;
};
FactorCount cholesky_factor_count(const AdjacencyGraph& g, std::span<const std::uint32_t> order,
                                  double max_entries = std::numeric_limits<double>::infinity());

/// First column of each row's envelope, row k being the point order[k]: min(k, positions of its
/// neighbours). The Jennings profile of the graph's matrix in that order.
std::vector<std::size_t> envelope_first_columns(const AdjacencyGraph& g, std::span<const std::uint32_t> order);
/// Multiply-adds of the envelope Cholesky factorisation with these first columns (estimate): row k
/// costs about (row length)^2 / 2.
double envelope_work(std::span<const std::size_t> first_columns) noexcept;

/// Profile of the symmetric matrix with the graph's pattern (plus the diagonal) in the given order.
struct Profile {
  std::size_t bandwidth = 0;  ///< max over rows of (row - first column in the row)
  std::size_t envelope = 0;   ///< off-diagonal entries in the row envelopes (Jennings storage)
};
Profile profile(const AdjacencyGraph& g, std::span<const std::uint32_t> order);

struct OrderingChoice {
  Ordering chosen = Ordering::Identity;
  std::vector<std::uint32_t> order;
  Profile identity, breadth_first, reverse_breadth_first, reverse_cuthill_mckee;
};
/// The profile of ordering o (Auto: RCM's) in anything that holds the four, as OrderingChoice and
/// FitStats do.
template <class Profiles>
auto& profile_of(Profiles& p, Ordering o) noexcept {
  switch (o) {
    case Ordering::Identity:
      return p.identity;
    case Ordering::BreadthFirst:
      return p.breadth_first;
    case Ordering::ReverseBreadthFirst:
      return p.reverse_breadth_first;
    default:
      return p.reverse_cuthill_mckee;
  }
}

/// Computes the requested ordering; the four profiles are always reported. `rcm`: the reverse
/// Cuthill-McKee order where the caller has already computed it (else it is computed here).
OrderingChoice choose_ordering(const AdjacencyGraph& g, Ordering requested, std::vector<std::uint32_t> rcm = {});

}  // namespace csrbf
