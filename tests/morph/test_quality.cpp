// Cell quality (csrbf/morph/quality.hpp): closed forms on boxes, prisms and pyramids either way,
// a QualityMeter's later measures against whole ones, and the volume ratio of an affine map.
#include "morph_test_helpers.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "csrbf/morph/quality.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

using csrbf::Vec3;
using namespace csrbf::morph;
using csrbf::test::BoxSpec;
using csrbf::test::TempDir;

// Quality: closed forms on boxes.
TEST(Quality, UnitCellsHaveTheirVolumeAndNoNonOrthogonality) {
  const auto box = csrbf::test::make_box({});
  TempDir dir;
  csrbf::test::write_box_case(dir.path / "case", {});
  const FoamCase c = read_openfoam(dir.path / "case");
  const PolyQuality q = poly_quality(c.mesh.poly, c.mesh.points);
  EXPECT_EQ(q.cells, 24u);
  EXPECT_NEAR(q.min_volume, 0.125, 1e-15);
  EXPECT_NEAR(q.total_volume, 24 * 0.125, 1e-13);
  EXPECT_NEAR(q.max_non_orthogonality, 0.0, 1e-6);
  EXPECT_NEAR(q.max_skewness, 0.0, 1e-12);
  EXPECT_EQ(q.inverted_cells, 0u);
  EXPECT_EQ(q.bad_pyramids, 0u);
  // The cell determinant of a cube is (internal faces along x)(along y)(along z) / 8: 1 x 1 x 1 at a
  // corner of the 4 x 3 x 2 box; the mean is (6/4)(4/3)(2/2) / 8.
  EXPECT_NEAR(q.min_determinant, 0.125, 1e-15);
  EXPECT_NEAR(q.mean_determinant, 0.25, 1e-15);
  // A uniform scaling changes no determinant (faces are scaled by their mean).
  std::vector<Vec3> big = c.mesh.points;
  for (Vec3& p : big) p *= 7.0;
  EXPECT_NEAR(poly_quality(c.mesh.poly, big).min_determinant, 0.125, 1e-14);
  (void)box;
}

TEST(Quality, ShearGivesItsAngleAsNonOrthogonality) {
  for (const double shear : {0.1, 0.5, 1.0}) {
    TempDir dir;
    BoxSpec s;
    s.warp = [shear](int, int, int, double& x, double& y, double&) { x += shear * y; };
    csrbf::test::write_box_case(dir.path / "case", s);
    const FoamCase c = read_openfoam(dir.path / "case");
    const PolyQuality q = poly_quality(c.mesh.poly, c.mesh.points);
    EXPECT_NEAR(q.max_non_orthogonality, std::atan(shear) * 180 / std::numbers::pi, 1e-9) << shear;
    EXPECT_NEAR(q.min_volume, 0.125, 1e-14);  // a shear keeps volumes
    EXPECT_EQ(q.inverted_cells, 0u);
  }
}

TEST(Quality, APointPushedThroughItsCellInvertsIt) {
  TempDir dir;
  BoxSpec s;
  s.nx = s.ny = s.nz = 3;
  csrbf::test::write_box_case(dir.path / "case", s);
  const FoamCase c = read_openfoam(dir.path / "case");
  std::vector<Vec3> p = c.mesh.points;
  p[1 + 4 * (1 + 4 * 1)] += Vec3(0.9, 0.9, 0.9);  // interior point (1,1,1) past (2,2,2)'s cell
  const PolyQuality q = poly_quality(c.mesh.poly, p);
  EXPECT_GT(q.inverted_cells, 0u);
  EXPECT_GT(q.bad_pyramids, 0u);
}

TEST(Cells, PrismsAndPyramidsAreMeasuredAndOrientedEitherWay) {
  // A unit prism and pyramid in VTK's corner order, then mirrored as another convention would
  // store them: both read as valid; pushing the apex through the base inverts the pyramid.
  std::vector<Vec3> p{{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 1},      {1, 0, 1},
                      {2, 0, 0}, {3, 0, 0}, {3, 1, 0}, {2, 1, 0}, {2.5, 0.5, 0.7}};
  for (const bool mirrored : {false, true}) {
    CellTopology t;
    const std::uint32_t wedge[] = {0, 1, 2, 3, 4, 5}, wedge_m[] = {0, 2, 1, 3, 5, 4};
    const std::uint32_t pyr[] = {6, 7, 8, 9, 10}, pyr_m[] = {6, 9, 8, 7, 10};
    t.add(13, mirrored ? wedge_m : wedge);
    t.add(14, mirrored ? pyr_m : pyr);
    orient_cells(t, p);
    const CellQuality q = cell_quality(t, p, p);
    EXPECT_EQ(q.prisms, 1u);
    EXPECT_EQ(q.pyramids, 1u);
    EXPECT_EQ(q.inverted_cells, 0u) << mirrored;
    EXPECT_GT(q.min_scaled_jacobian, 0.5);
    std::vector<Vec3> pushed = p;
    pushed[10].z() = -0.7;
    EXPECT_EQ(cell_quality(t, pushed, p).inverted_cells, 1u);
  }
}

// A QualityMeter's later measures recompute only the faces and cells of points that differ from
// the mesh's (now or at the last measure): each equals a whole measure of the same points (a
// fresh poly_quality) bit for bit, through a sequence that moves a corner, moves more, inverts a
// cell, moves back part of the way and returns to the mesh's own points.
TEST_F(BoxMorph, ALaterMeasureEqualsAWholeOne) {
  const auto same = [](const PolyQuality& a, const PolyQuality& b) {
    EXPECT_EQ(a.max_non_orthogonality, b.max_non_orthogonality);
    EXPECT_EQ(a.mean_non_orthogonality, b.mean_non_orthogonality);
    EXPECT_EQ(a.max_skewness, b.max_skewness);
    EXPECT_EQ(a.negative_volumes, b.negative_volumes);
    EXPECT_EQ(a.bad_pyramids, b.bad_pyramids);
    EXPECT_EQ(a.inverted_cells, b.inverted_cells);
    EXPECT_EQ(a.min_volume, b.min_volume);
    EXPECT_EQ(a.total_volume, b.total_volume);
    EXPECT_EQ(a.min_determinant, b.min_determinant);
    EXPECT_EQ(a.mean_determinant, b.mean_determinant);
  };
  const std::vector<Vec3>& own = c.mesh.points;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02);
  const auto moved = [&](double within, double scale) {  // points within a distance of the origin
    std::vector<Vec3> p = own;
    for (Vec3& x : p)
      if (x.norm() < within) x += scale * Vec3(jitter(rng), jitter(rng), jitter(rng));
    return p;
  };
  std::vector<Vec3> inverted = own;
  const std::size_t inner =
      std::size_t(std::min_element(own.begin(), own.end(),
                                   [](const Vec3& a, const Vec3& b) {
                                     return (a - Vec3(0.5, 0.5, 0.5)).norm() < (b - Vec3(0.5, 0.5, 0.5)).norm();
                                   }) -
                  own.begin());
  inverted[inner] += Vec3(0.4, 0.0, 0.0);  // through its neighbours' cells
  const std::vector<std::vector<Vec3>> sets{own, moved(0.3, 1.0), moved(0.8, 2.0), inverted, moved(0.2, 0.5), own};
  QualityMeter meter(c.mesh);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    SCOPED_TRACE("point set " + std::to_string(k));
    const MeshQuality later = meter.measure(sets[k]);
    ASSERT_TRUE(later.poly);
    same(*later.poly, poly_quality(c.mesh.poly, sets[k]));
  }
  EXPECT_GT(meter.measure(inverted).inverted_cells(), 0u);
}

// Issue 31, point 7: the smallest cell volume ratio, after / before. Under an affine map x -> Ax
// every cell's volume is multiplied by det A: the closed form, for OpenFOAM's polyhedra (against
// the meter's first measure) and for every standard cell type (against the reference points).
TEST_F(BoxMorph, TheVolumeRatioIsTheDeterminantOfAnAffineMap) {
  Eigen::Matrix3d a;
  a << 1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 0.8;
  const double det = a.determinant();
  const auto mapped = [&](const std::vector<Vec3>& p, const Eigen::Matrix3d& m) {
    std::vector<Vec3> out(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) out[i] = m * p[i] + Vec3(0.3, -2, 5);
    return out;
  };
  QualityMeter meter(c.mesh);
  EXPECT_EQ(meter.measure(c.mesh.points).poly->min_volume_ratio, 1.0);
  EXPECT_NEAR(meter.measure(mapped(c.mesh.points, a)).poly->min_volume_ratio, det, 1e-12);
  // Squeezing the box's bottom layer to a fifth of its height: 0.2.
  std::vector<Vec3> squeezed = c.mesh.points;
  for (Vec3& p : squeezed) p.z() = p.z() < 1.0 / 6 + 1e-9 ? p.z() / 5 : p.z() - (1.0 / 6) * 4 / 5;
  EXPECT_NEAR(meter.measure(squeezed).poly->min_volume_ratio, 0.2, 1e-12);
  // A tetrahedron, a hexahedron, a prism, a pyramid; then a triangle and a quadrilateral alone.
  std::vector<Vec3> p{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1},  // tet
                      {2, 0, 0}, {3, 0, 0}, {3, 1, 0}, {2, 1, 0}, {2, 0, 1},      {3, 0, 1},
                      {3, 1, 1}, {2, 1, 1},                                                   // hex
                      {4, 0, 0}, {5, 0, 0}, {4, 1, 0}, {4, 0, 1}, {5, 0, 1},      {4, 1, 1},  // prism
                      {6, 0, 0}, {7, 0, 0}, {7, 1, 0}, {6, 1, 0}, {6.5, 0.5, 0.8}};           // pyramid
  CellTopology solid;
  const std::uint32_t tet[] = {0, 1, 2, 3}, hex[] = {4, 5, 6, 7, 8, 9, 10, 11}, prism[] = {12, 13, 14, 15, 16, 17},
                      pyramid[] = {18, 19, 20, 21, 22};
  solid.add(10, tet);
  solid.add(12, hex);
  solid.add(13, prism);
  solid.add(14, pyramid);
  EXPECT_EQ(cell_quality(solid, p, p).min_volume_ratio, 1.0);
  EXPECT_NEAR(cell_quality(solid, mapped(p, a), p).min_volume_ratio, det, 1e-12);
  // One cell crushed to a third: the smallest ratio is its.
  std::vector<Vec3> crushed = p;
  for (int k : {8, 9, 10, 11}) crushed[std::size_t(k)].z() = 1.0 / 3;
  EXPECT_NEAR(cell_quality(solid, crushed, p).min_volume_ratio, 1.0 / 3, 1e-12);
  // In-plane cells (a 2-D mesh): a map that keeps the plane z = 0 scales areas by its 2x2 block.
  CellTopology flat;
  const std::uint32_t tri[] = {0, 1, 2}, quad[] = {4, 5, 6, 7};
  flat.add(5, tri);
  flat.add(9, quad);
  Eigen::Matrix3d b = Eigen::Matrix3d::Identity();
  b.topLeftCorner<2, 2>() << 1.3, 0.4, -0.2, 0.7;
  EXPECT_NEAR(cell_quality(flat, mapped(p, b), p).min_volume_ratio, b.determinant(), 1e-12);
}
