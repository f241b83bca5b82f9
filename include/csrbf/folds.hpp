// Fold detection: where a space mapping turns space inside out. RBF warps fold when a displacement
// is large against the radius of support; det(dT/dx) <= 0 marks it. For T(x) = x + t d(x) the
// determinant is a cubic in the phase t, det(I + t A) = 1 + t tr A + t^2 m2(A) + t^3 det A with A = dd/dx
// and m2 the sum of A's principal 2x2 minors, so the first phase at which a point folds is that
// cubic's smallest positive root.
#pragma once

#include "csrbf/space_map.hpp"

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace csrbf {

struct FoldReport {
  double phase = 1.0;        ///< the phase checked
  std::size_t vertices = 0;  ///< vertices checked
  std::size_t samples = 0;   ///< points checked: the vertices and 4 points inside each triangle
  double min_det = std::numeric_limits<double>::infinity();  ///< smallest det(dT/dx) at `phase`
  Vec3 min_at = Vec3::Zero();                                ///< where
  std::size_t folded = 0;                                    ///< points (of `samples`) with det <= 0 at `phase`
  std::vector<std::uint32_t> folded_vertices;                ///< vertices with det <= 0 at `phase`
  /// The largest t such that every point checked has det > 0 for all phases in [0, t): the first
  /// fold over the samples. Infinity if none of them ever folds.
  double fold_free_phase = std::numeric_limits<double>::infinity();
  /// With an active area (check_folds_in_area): triangles across its edge, and those of them turned
  /// over at `phase` (the displacement stops at the edge, so these can flip without det <= 0).
  std::size_t edge_triangles = 0, edge_flipped = 0;
};

/// The cubic's smallest positive root for one point: the first phase at which it folds (infinity
/// if it never does). `jacobian_at_1` = dT/dx at phase 1, i.e. I + A.
double first_fold_phase(const Eigen::Matrix3d& jacobian_at_1);

/// Checks the vertices and, for each polygon (fanned into triangles), 4 points inside each triangle
/// (the centroid and the points halfway between it and each corner). Runs in parallel.
FoldReport check_folds(const SpaceMap& map, std::span<const Vec3> vertices, const PolygonList& faces,
                       double phase = 1.0);

/// The same for a map that moves only the `area` vertices (sorted indices; the Picker's active area):
/// the area's vertices, 4 points inside each triangle wholly inside it, and every triangle across its
/// edge, which folds when it turns over (its normal against the rest normal). fold_free_phase covers
/// all three; folded_vertices are indices into `vertices`.
FoldReport check_folds_in_area(const SpaceMap& map, std::span<const Vec3> vertices, const PolygonList& faces,
                               const std::vector<std::uint32_t>& area, double phase = 1.0);

}  // namespace csrbf
