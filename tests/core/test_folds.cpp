#include "csrbf/folds.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using csrbf::Vec3;

TEST(Folds, FirstFoldPhaseOfClosedForms) {
  const double inf = std::numeric_limits<double>::infinity();
  // det(I + t A) for A = diag(-2, 1, 3): (1 - 2t)(1 + t)(1 + 3t), first positive root 1/2.
  EXPECT_NEAR(csrbf::first_fold_phase(Eigen::Vector3d(-1, 2, 4).asDiagonal()), 0.5, 1e-12);
  // A = diag(-0.25, -4, 0): roots 4 and 1/4.
  EXPECT_NEAR(csrbf::first_fold_phase(Eigen::Vector3d(0.75, -3, 1).asDiagonal()), 0.25, 1e-12);
  // The identity map, a shear (nilpotent A: det = 1 at every phase) and a growth never fold.
  EXPECT_EQ(csrbf::first_fold_phase(Eigen::Matrix3d::Identity()), inf);
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = 5;
  EXPECT_EQ(csrbf::first_fold_phase(shear), inf);
  EXPECT_EQ(csrbf::first_fold_phase(Eigen::Vector3d(2, 3, 4).asDiagonal()), inf);
  // A rotation generator: det(I + tA) = 1 + t^2 > 0, complex roots only.
  Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
  rot(0, 1) = -1;
  rot(1, 0) = 1;
  EXPECT_EQ(csrbf::first_fold_phase(rot), inf);
}

namespace {

/// One control pushing along x by g (in units of R = 1), and points on the x axis in front of it.
/// For the C2 kernel d_x(x) = g phi(x), phi'(r) = -20 r (1 - r)^3, steepest at r = 1/4 with
/// phi' = -135/64: the map first folds at phase t* = 1 / (g * 135/64).
csrbf::FoldReport push(double g, double phase) {
  const std::vector<Vec3> s{Vec3::Zero()}, d{Vec3(g, 0, 0)};
  const auto map = csrbf::SpaceMap::fit(s, d, csrbf::FitOptions{1.0, csrbf::Kernel::C2});
  std::vector<Vec3> line;
  for (int i = 0; i <= 4000; ++i) line.emplace_back(i / 4000.0, 0, 0);
  return csrbf::check_folds(map, line, {}, phase);
}

}  // namespace

TEST(Folds, AMapKnownToFold) {
  const auto r = push(0.6, 1.0);
  const double t_star = 1 / (0.6 * 135.0 / 64.0);  // 0.790
  EXPECT_NEAR(r.fold_free_phase, t_star, 1e-6);
  EXPECT_GT(r.folded, 0u);
  EXPECT_EQ(r.folded, r.folded_vertices.size());  // no faces: the samples are the vertices
  EXPECT_NEAR(r.min_det, 1 - 0.6 * 135.0 / 64.0, 1e-6);
  EXPECT_NEAR(r.min_at.x(), 0.25, 1e-3);
  // Just below t*, nothing folds; just above, the points around r = 1/4 do.
  EXPECT_EQ(push(0.6, t_star - 1e-3).folded, 0u);
  EXPECT_GT(push(0.6, t_star + 1e-3).folded, 0u);
}

TEST(Folds, AMapKnownNotToFold) {
  const auto r = push(0.3, 1.0);
  EXPECT_EQ(r.folded, 0u);
  EXPECT_GT(r.min_det, 0.3);
  EXPECT_NEAR(r.fold_free_phase, 1 / (0.3 * 135.0 / 64.0), 1e-6);  // 1.58: folds only beyond phase 1
  // Triangles add points inside them; a bad face index is an error, not a crash.
  const std::vector<Vec3> s{Vec3::Zero()}, d{Vec3(0.1, 0, 0)};
  const auto map = csrbf::SpaceMap::fit(s, d, csrbf::FitOptions{1.0});
  const std::vector<Vec3> tri{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const auto t = csrbf::check_folds(map, tri, {{0, 1, 2}});
  EXPECT_EQ(t.samples, 3u + 4u);
  EXPECT_THROW(csrbf::check_folds(map, tri, {{0, 1, 7}}), csrbf::InvalidInput);
}
