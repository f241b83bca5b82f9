// The points of a kernel system and of the maps evaluated over them, with their neighbour structures
// built on first use and kept: NeighborIndex, and the evaluation grid (evaluator.hpp), whose cell lists
// also give the kernel system its neighbour graph. Shared by a KernelSystem and the SpaceMaps made
// from it; kept alone where the system is gone (a map made from a solution, an interpolator's level).
// Private to csrbf::core.
#pragma once

#include "csrbf/neighbor_index.hpp"
#include "csrbf/units.hpp"

#include "evaluator.hpp"

#include <mutex>
#include <span>
#include <vector>

namespace csrbf::detail {

/// Coordinates (and so distances) stay below this, so that their squares are finite.
inline constexpr double kMaxCoordinate = 1e150;
/// InvalidInput naming `what` and its index where a point is not finite or beyond kMaxCoordinate:
/// the fit's check of its sources and destinations, estimate()'s of the sources, and the kernel
/// system's of its points.
void check_points(std::span<const Vec3> pts, const char* what);

// The most memory the evaluation lists of one fit may take (evaluator.hpp), and never more than
// what the fit's own predicted memory leaves of the memory limit; past it, evaluation goes through
// NeighborIndex.
inline constexpr std::size_t kEvalListBytes = std::size_t(512) << 20;

struct PointCloud {
  PointCloud(std::span<const Vec3> pts, double r, double limit)
      : points(pts.begin(), pts.end()), radius(r), memory_limit_bytes(limit) {}
  std::vector<Vec3> points;  // input order
  double radius = 1.0;
  double memory_limit_bytes = 4.0 * kGiB;
  /// csrbf::Interpolator's points of 1 or 2 dimensions: the axes from `dims` on are 0 for every point
  /// and every point evaluated (EvalGrid::build).
  int dims = 3;
  int max_subdivision = EvalGrid::kMaxSubdivision;  // 1: cells of side R (few points evaluated)
  /// The most the evaluation lists may take: kEvalListBytes for a SpaceMap; csrbf::Interpolator's
  /// levels, whose lists are their evaluation, take up to what the memory limit leaves (1e6 2-D
  /// points: 650 MB, which 512 MB sent through NeighborIndex at 40x the time).
  std::size_t eval_list_bytes = kEvalListBytes;
  double fit_bytes = 0;  // the fit's predicted memory (graph, matrix, factor), set before the grid is built

  /// Built on first use (the simple path, the Jacobian) unless the fit needs it (when the evaluation
  /// grid is unusable).
  const NeighborIndex& index() const {
    std::call_once(index_once_, [this] { index_ = NeighborIndex(points, radius); });
    return index_;
  }
  /// Built by the fit when its lists give the neighbour graph (N > kBruteForceGraph), else on first
  /// evaluation.
  const EvalGrid& grid() const {
    std::call_once(grid_once_, [this] {
      const double left = memory_limit_bytes - fit_bytes;
      const std::size_t budget = left >= double(eval_list_bytes) ? eval_list_bytes : left > 0 ? std::size_t(left) : 0;
      grid_ = EvalGrid::build(points, radius, budget, max_subdivision, dims);
    });
    return grid_;
  }

 private:
  mutable std::once_flag index_once_, grid_once_;
  mutable NeighborIndex index_;
  mutable EvalGrid grid_;
};

}  // namespace csrbf::detail
