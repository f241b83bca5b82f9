#include "csrbf/folds.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

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

TEST(Folds, TrianglesAcrossAnActiveAreasEdgeTurnOverAsABruteForceFinds) {
  // A flat 11 x 11 grid in z = 0, two triangles a cell. The area is the left half; one control in it
  // pushes +x towards the edge, so the displacement stops dead at the edge and the triangles across
  // it are squashed and turned over (det dT/dx stays positive inside the area).
  std::vector<Vec3> grid;
  csrbf::PolygonList faces;
  const int n = 11;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) grid.emplace_back(i / 10.0, j / 10.0, 0.0);
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const std::uint32_t a = std::uint32_t(j * n + i), b = a + 1, c = a + std::uint32_t(n), d = c + 1;
      faces.push_back({a, b, d});
      faces.push_back({a, d, c});
    }
  std::vector<std::uint32_t> area;
  for (std::uint32_t v = 0; v < grid.size(); ++v)
    if (grid[v].x() < 0.45) area.push_back(v);
  const std::vector<Vec3> s{Vec3(0.38, 0.5, 0)}, d{Vec3(0.56, 0.5, 0)};
  const auto map = csrbf::SpaceMap::fit(s, d, csrbf::FitOptions{0.5, csrbf::Kernel::C2});
  // Brute force: move the area's vertices at phase t and count triangles whose normal turned over.
  const auto flipped_at = [&](double t) {
    std::vector<Vec3> moved = grid, part;
    for (const auto v : area) part.push_back(grid[v]);
    map.apply(part, part, t);
    for (std::size_t k = 0; k < area.size(); ++k) moved[area[k]] = part[k];
    std::size_t count = 0;
    for (const auto& f : faces) {
      const Vec3 n0 = (grid[f[1]] - grid[f[0]]).cross(grid[f[2]] - grid[f[0]]);
      const Vec3 n1 = (moved[f[1]] - moved[f[0]]).cross(moved[f[2]] - moved[f[0]]);
      count += n0.dot(n1) <= 0;
    }
    return count;
  };
  const auto r = csrbf::check_folds_in_area(map, grid, faces, area, 1.0);
  EXPECT_EQ(r.edge_triangles, 20u);  // one column of cells across x = 0.4 .. 0.5
  EXPECT_EQ(r.edge_flipped, flipped_at(1.0));
  EXPECT_GT(r.edge_flipped, 0u);
  EXPECT_EQ(r.folded, 0u) << "inside the area nothing folds: the edge is what turns over";
  // The first turning over, from the quadratics, against the brute force on either side of it.
  ASSERT_TRUE(std::isfinite(r.fold_free_phase));
  ASSERT_LT(r.fold_free_phase, 1.0);
  EXPECT_EQ(flipped_at(r.fold_free_phase * (1 - 1e-9)), 0u);
  EXPECT_GT(flipped_at(r.fold_free_phase * (1 + 1e-6) + 1e-12), 0u);
  // Folded vertices are given as the mesh's indices; an area of every vertex is the plain check.
  std::vector<std::uint32_t> all(grid.size());
  for (std::uint32_t v = 0; v < all.size(); ++v) all[v] = v;
  const auto whole = csrbf::check_folds_in_area(map, grid, faces, all, 1.0);
  const auto plain = csrbf::check_folds(map, grid, faces, 1.0);
  EXPECT_EQ(whole.edge_triangles, 0u);
  EXPECT_EQ(whole.samples, plain.samples);
  EXPECT_EQ(whole.fold_free_phase, plain.fold_free_phase);
  EXPECT_EQ(whole.folded_vertices, plain.folded_vertices);
}
