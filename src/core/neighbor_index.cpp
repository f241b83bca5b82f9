#include "csrbf/neighbor_index.hpp"

#include "csrbf/errors.hpp"

#include <algorithm>
#include <bit>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace csrbf {

void NeighborIndex::check_extent(const Vec3& lo, const Vec3& hi, double radius, const char* what) {
  if ((hi - lo).maxCoeff() / radius > 1e9) {
    std::ostringstream os;
    os << "radius " << radius << " is too small for " << what << " spanning " << (hi - lo).maxCoeff()
       << " (more than 1e9 radii): scale the points or raise the radius";
    throw InvalidInput(os.str());
  }
}

NeighborIndex::NeighborIndex(std::span<const Vec3> points, double radius) : radius_(radius) {
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    std::ostringstream os;
    os << "neighbour index: radius must be a positive finite number, got " << radius;
    throw InvalidInput(os.str());
  }
  if (points.size() >= std::size_t(UINT32_MAX)) throw InvalidInput("neighbour index: too many points");
  if (points.empty()) return;
  Vec3 lo = points[0], hi = points[0];
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      std::ostringstream os;
      os << "neighbour index: point " << i << " is not finite (" << points[i].transpose() << ")";
      throw InvalidInput(os.str());
    }
    lo = lo.cwiseMin(points[i]);
    hi = hi.cwiseMax(points[i]);
  }
  check_extent(lo, hi, radius, "points");
  origin_ = lo;
  inv_cell_ = 1.0 / radius;
  const std::size_t n = points.size();
  std::vector<Eigen::Vector3i> cell(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 c = ((points[i] - lo) * inv_cell_).array().floor();
    cell[i] = c.cast<int>();
    max_cell_ = max_cell_.cwiseMax(cell[i]);
  }
  std::vector<std::uint32_t> order(n);
  // z-major, then y, then x: cells adjacent in x are adjacent in memory; within a cell, by index.
  // Where the box holds few cells for its points, a counting sort over the cells numbered in that
  // order (the same order as the comparison sort's, stable as it is: 1e5 points, 4e3 cells, 20 ms
  // -> 1 ms); else the comparison sort.
  const double cells = (double(max_cell_.x()) + 1) * (double(max_cell_.y()) + 1) * (double(max_cell_.z()) + 1);
  if (cells <= 4.0 * double(n) + 4096.0) {
    const auto key = [&](const Eigen::Vector3i& c) {
      return (std::size_t(c.z()) * std::size_t(max_cell_.y() + 1) + std::size_t(c.y())) *
                 std::size_t(max_cell_.x() + 1) +
             std::size_t(c.x());
    };
    std::vector<std::uint32_t> start(std::size_t(cells) + 1, 0);
    for (std::size_t i = 0; i < n; ++i) ++start[key(cell[i]) + 1];
    for (std::size_t c = 0; c + 1 < start.size(); ++c) start[c + 1] += start[c];
    for (std::size_t i = 0; i < n; ++i) order[start[key(cell[i])]++] = std::uint32_t(i);
  } else {
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      const auto& ca = cell[a];
      const auto& cb = cell[b];
      if (ca.z() != cb.z()) return ca.z() < cb.z();
      if (ca.y() != cb.y()) return ca.y() < cb.y();
      return ca.x() < cb.x();
    });
  }
  points_.resize(n);
  ids_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    points_[k] = points[order[k]];
    ids_[k] = order[k];
  }
  std::size_t distinct = 0;
  for (std::size_t k = 0; k < n; ++k)
    if (k == 0 || cell[order[k]] != cell[order[k - 1]]) ++distinct;
  const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(16, 2 * distinct));
  table_.assign(capacity, Cell{});
  mask_ = capacity - 1;
  cells_used_ = distinct;
  std::size_t k = 0;
  while (k < n) {
    const Eigen::Vector3i c = cell[order[k]];
    std::size_t e = k + 1;
    while (e < n && cell[order[e]] == c) ++e;
    std::uint64_t h = hash(c.x(), c.y(), c.z()) & mask_;
    while (table_[h].end != 0) h = (h + 1) & mask_;
    table_[h] = Cell{c.x(), c.y(), c.z(), std::uint32_t(k), std::uint32_t(e)};
    k = e;
  }
}

std::vector<std::size_t> NeighborIndex::query(const Vec3& q) const {
  std::vector<std::size_t> out;
  for_each_within(q, [&](std::size_t i, double) { out.push_back(i); });
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace csrbf
