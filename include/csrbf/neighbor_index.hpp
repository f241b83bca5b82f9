// Fixed-radius neighbour search over a fixed point set: all points closer than R to a query point.
//
// The paper (section 4.1) uses a variable-depth octree. For a query radius fixed at build time a
// hashed uniform grid with cell size R is simpler and faster (every query visits exactly 27 cells and
// no tree levels); bench/bench_neighbor_index.cpp measures it against an octree and brute force.
#pragma once

#include "csrbf/types.hpp"

#include <Eigen/Core>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace csrbf {

/// Hashed uniform grid over a copy of the points. Immutable after construction; queries are const
/// and thread-safe. The index owns its copy of the points, so the caller's buffer may go away.
class NeighborIndex {
 public:
  NeighborIndex() = default;
  /// radius: the search radius R (not squared), > 0 and finite; points must be finite.
  /// Throws InvalidInput otherwise, or when R is below 1e-9 of the points'
  /// extent.
  NeighborIndex(std::span<const Vec3> points, double radius);
  /// The extent rule above on its own: throws InvalidInput when the box [lo, hi] spans more than
  /// 1e9 radii (a grid of cells of side R could not index it). `what` names the points in the message.
  static void check_extent(const Vec3& lo, const Vec3& hi, double radius, const char* what);

  std::size_t size() const noexcept { return points_.size(); }
  bool empty() const noexcept { return points_.empty(); }
  double radius() const noexcept { return radius_; }

  /// Calls f(slot, distance_squared) for every stored point with distance < R from q. A slot is the
  /// point's position in the index's internal (cell-sorted) order; original_index(slot) maps back.
  template <class F>
  void for_each_slot_within(const Vec3& q, F&& f) const;

  /// Calls f(original_index, distance_squared) for every point with distance < R from q.
  template <class F>
  void for_each_within(const Vec3& q, F&& f) const {
    for_each_slot_within(q, [&](std::size_t slot, double d2) { f(std::size_t(ids_[slot]), d2); });
  }

  /// Original indices of every point with distance < R from q, in ascending order.
  std::vector<std::size_t> query(const Vec3& q) const;

  const Vec3& point(std::size_t slot) const noexcept { return points_[slot]; }
  std::size_t original_index(std::size_t slot) const noexcept { return ids_[slot]; }
  std::span<const Vec3> sorted_points() const noexcept { return points_; }
  std::span<const std::uint32_t> sorted_ids() const noexcept { return ids_; }
  std::size_t cell_count() const noexcept { return cells_used_; }

 private:
  struct Cell {
    std::int32_t x = 0, y = 0, z = 0;
    std::uint32_t begin = 0, end = 0;  // end == 0 and begin == 0 marks an empty slot
  };
  static std::uint64_t hash(std::int32_t x, std::int32_t y, std::int32_t z) noexcept {
    return (std::uint64_t(std::uint32_t(x)) * 73856093u) ^ (std::uint64_t(std::uint32_t(y)) * 19349663u) ^
           (std::uint64_t(std::uint32_t(z)) * 83492791u);
  }
  const Cell* find(std::int32_t x, std::int32_t y, std::int32_t z) const noexcept {
    std::uint64_t h = hash(x, y, z) & mask_;
    for (;;) {
      const Cell& c = table_[h];
      if (c.end == 0) return nullptr;
      if (c.x == x && c.y == y && c.z == z) return &c;
      h = (h + 1) & mask_;
    }
  }

  std::vector<Vec3> points_;        // sorted by cell
  std::vector<std::uint32_t> ids_;  // original index of each sorted point
  std::vector<Cell> table_;         // open addressing, power-of-two size
  std::uint64_t mask_ = 0;
  std::size_t cells_used_ = 0;
  Vec3 origin_ = Vec3::Zero();
  double radius_ = 0.0, inv_cell_ = 0.0;
  Eigen::Vector3i max_cell_ = Eigen::Vector3i::Zero();
};

template <class F>
void NeighborIndex::for_each_slot_within(const Vec3& q, F&& f) const {
  if (points_.empty()) return;
  const double r2 = radius_ * radius_;
  const double fx = std::floor((q.x() - origin_.x()) * inv_cell_);
  const double fy = std::floor((q.y() - origin_.y()) * inv_cell_);
  const double fz = std::floor((q.z() - origin_.z()) * inv_cell_);
  // Outside the grid by more than one cell (or NaN): nothing can be within R.
  if (!(fx >= -1.0 && fy >= -1.0 && fz >= -1.0 && fx <= max_cell_.x() + 1.0 && fy <= max_cell_.y() + 1.0 &&
        fz <= max_cell_.z() + 1.0))
    return;
  const auto cx = std::int32_t(fx), cy = std::int32_t(fy), cz = std::int32_t(fz);
  for (std::int32_t dz = -1; dz <= 1; ++dz)
    for (std::int32_t dy = -1; dy <= 1; ++dy)
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        const Cell* c = find(cx + dx, cy + dy, cz + dz);
        if (!c) continue;
        for (std::uint32_t k = c->begin; k < c->end; ++k) {
          const double d2 = (points_[k] - q).squaredNorm();
          if (d2 < r2) f(std::size_t(k), d2);
        }
      }
}

}  // namespace csrbf
