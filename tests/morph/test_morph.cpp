// The morph itself (csrbf/morph/morph.hpp): patches resolved into prescribed points, the interpolant
// against dense solves, exact locality, two levels, greedy, auto radius and slip patches.
#include "morph_test_helpers.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "csrbf/morph/quality.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

using csrbf::Vec3;
using namespace csrbf::morph;
using csrbf::test::bits;
using csrbf::test::BoxSpec;
using csrbf::test::error_of;
using csrbf::test::motion_from;
using csrbf::test::TempDir;

TEST_F(BoxMorph, PatchesResolveWithTheirRules) {
  // zmin moves, xmin is fixed: their shared edge moves.
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.01]}, "xmin": "fixed"}})");
  const Prescribed p = prescribe(c.mesh, m);
  EXPECT_EQ(p.points.size(), 49u + 49u - 7u);
  EXPECT_EQ(p.moving(), 49u);
  for (std::size_t i = 0; i < p.points.size(); ++i)
    if (c.mesh.points[p.points[i]].z() == 0) {
      EXPECT_FALSE(p.fixed[i]) << p.points[i];
    }

  // Issue 31, point 7: a patch moved by 0 and a rotation's points on its axis do not count as moving.
  const Motion still = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0]}, "xmin": "fixed"}})");
  EXPECT_EQ(prescribe(c.mesh, still).moving(), 0u);
  const Motion turn = motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [0, 0, 1], "degrees": 5,
                                                                 "origin": [0, 0, 0]}}}})");
  EXPECT_EQ(prescribe(c.mesh, turn).moving(), 48u);  // the corner at the origin stays

  // Two moving patches that disagree at their shared edge.
  const std::string e = error_of([&] {
    prescribe(
        c.mesh,
        motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.01]}, "xmin": {"translate": [0.01, 0, 0]}}})"));
  });
  EXPECT_NE(e.find("patch 'xmin'"), std::string::npos) << e;
  EXPECT_NE(e.find("patch 'zmin'"), std::string::npos) << e;
  EXPECT_NE(e.find("point 0 "), std::string::npos) << e;
  // Agreeing ones are fine.
  EXPECT_EQ(
      prescribe(c.mesh,
                motion_from(
                    dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.01]}, "xmin": {"translate": [0, 0, 0.01]}}})"))
          .moving(),
      91u);

  EXPECT_NE(error_of([&] {
              prescribe(c.mesh, motion_from(dir, R"({"patches": {"wing": "fixed"}})"));
            }).find("its patches: xmin, xmax"),
            std::string::npos);
}

TEST_F(BoxMorph, DisplacementFilesAreCheckedAgainstThePatch) {
  const Patch& zmin = *c.mesh.patch("zmin");
  std::string all;
  for (const auto p : zmin.points) all += std::to_string(p) + " 0 0 0.01\n";
  csrbf::test::write_text(dir / "z.txt", all);
  const std::string json = R"({"patches": {"zmin": {"displacements": "z.txt"}}})";
  EXPECT_EQ(prescribe(c.mesh, motion_from(dir, json)).moving(), 49u);
  const auto err = [&](const std::string& text) {
    csrbf::test::write_text(dir / "z.txt", text);
    return error_of([&] { prescribe(c.mesh, motion_from(dir, json)); });
  };
  EXPECT_NE(err(all + "343 0 0 0\n").find("out of range: the mesh has 343 points"), std::string::npos);
  EXPECT_NE(err(all + "342 0 0 0\n").find("z.txt:50: point 342 is not on patch 'zmin'"), std::string::npos);
  EXPECT_NE(err(all + "0 0 0 0\n").find("given twice (also on line 1)"), std::string::npos);
  EXPECT_NE(err("0 0 0 0.01\n").find("48 of the 49 points of patch 'zmin' have no displacement"), std::string::npos);
}

TEST_F(BoxMorph, InteriorPointsFollowTheDenseInterpolantAndBoundariesLandExactly) {
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "xmin": "fixed", "xmax": "free",
                                                    "ymin": "free", "ymax": "free"}})");
  MorphOptions o;
  o.fit.radius = 0.6;
  const MorphResult r = morph(c.mesh, m, o);
  const Prescribed p = prescribe(c.mesh, m);
  // The controls: every moving point, and every staying one within R of a moving one (exact
  // locality), by brute force.
  std::vector<std::uint32_t> fitted;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    bool keep = p.displacements[i] != Vec3::Zero();
    for (std::size_t j = 0; j < p.points.size() && !keep; ++j)
      keep = p.displacements[j] != Vec3::Zero() &&
             (c.mesh.points[p.points[i]] - c.mesh.points[p.points[j]]).norm() < o.fit.radius;
    if (keep) fitted.push_back(std::uint32_t(i));
  }
  EXPECT_LT(fitted.size(), p.points.size());  // zmax, 1 from zmin, is left out
  EXPECT_EQ(r.report.far_fixed, p.points.size() - fitted.size());
  EXPECT_EQ(r.report.reach, 1.2);
  // The dense solve of the whole system: A alpha = d over the controls (C2, no polynomial).
  const std::size_t n = fitted.size();
  Eigen::MatrixXd A(n, n);
  Eigen::MatrixXd d(n, 3);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j)
      A(Eigen::Index(i), Eigen::Index(j)) = csrbf::wendland(
          csrbf::Kernel::C2, (c.mesh.points[p.points[fitted[i]]] - c.mesh.points[p.points[fitted[j]]]).norm() / 0.6);
    d.row(Eigen::Index(i)) = p.displacements[fitted[i]].transpose();
  }
  const Eigen::MatrixXd alpha = A.llt().solve(d);
  std::vector<char> prescribed(c.mesh.points.size(), 0);
  for (const auto q : p.points) prescribed[q] = 1;
  const double scale = r.report.max_displacement;
  EXPECT_GT(scale, 0.02);
  std::size_t moved = 0;
  for (std::size_t q = 0; q < c.mesh.points.size(); ++q) {
    if (prescribed[q]) continue;
    Vec3 want = c.mesh.points[q];
    for (std::size_t j = 0; j < n; ++j)
      want += alpha.row(Eigen::Index(j)).transpose() *
              csrbf::wendland(csrbf::Kernel::C2, (c.mesh.points[q] - c.mesh.points[p.points[fitted[j]]]).norm() / 0.6);
    EXPECT_NEAR((r.points[q] - want).norm(), 0.0, 1e-10 * scale) << q;
    moved += r.points[q] != c.mesh.points[q];
  }
  EXPECT_GT(moved, 50u);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t q = p.points[i];
    if (p.fixed[i]) {
      for (int k = 0; k < 3; ++k) EXPECT_EQ(bits(r.points[q][k]), bits(c.mesh.points[q][k]));
    } else {
      EXPECT_NEAR((r.points[q] - (c.mesh.points[q] + p.displacements[i])).norm(), 0.0, 1e-15);
    }
  }
  EXPECT_LT(r.report.max_boundary_error, 1e-12);
  EXPECT_EQ(r.report.controls, n);
  // The phase scales the whole motion.
  o.phase = 0.5;
  const MorphResult half = morph(c.mesh, m, o);
  for (std::size_t q = 0; q < c.mesh.points.size(); ++q)
    EXPECT_NEAR((half.points[q] - c.mesh.points[q] - 0.5 * (r.points[q] - c.mesh.points[q])).norm(), 0.0, 1e-14);
}

/// A 12^3 box case of side 1, written into dir and read back.
static FoamCase box12(const TempDir& dir) {
  BoxSpec spec;
  spec.nx = spec.ny = spec.nz = 12;
  spec.h = 1.0 / 12;
  csrbf::test::write_box_case(dir.path / "case", spec);
  return read_openfoam(dir.path / "case");
}

// Issue 31, point 1: exact locality as a contract. With polynomial none, a point 2R or farther from
// every moving control keeps its coordinates bit for bit, for every kernel, with or without greedy:
// staying controls carried coefficients of 1e-16 and moved the whole connected mesh (a flow
// solver's residuals jumped 63x on such a mesh). Measured on a 12^3 box, zmin moving, R = 0.3.
TEST(ExactLocality, PointsTwoRadiiFromEveryMovingOneKeepTheirBits) {
  TempDir dir;
  const FoamCase c = box12(dir);
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 4, "origin": [0.5, 0.5, 0]}},
                             "zmax": "fixed", "xmin": "fixed", "xmax": "fixed", "ymin": "fixed", "ymax": "fixed"}})");
  const Prescribed p = prescribe(c.mesh, m);
  std::vector<Vec3> moving;
  for (std::size_t i = 0; i < p.points.size(); ++i)
    if (p.displacements[i] != Vec3::Zero()) moving.push_back(c.mesh.points[p.points[i]]);
  const double radius = 0.3;
  for (const auto kernel : {csrbf::Kernel::C0, csrbf::Kernel::C2, csrbf::Kernel::C4, csrbf::Kernel::C6})
    for (const int variant : {0, 1, 2}) {  // plain, greedy, two levels
      const double greedy = variant == 1 ? 1e-3 : 0.0;
      SCOPED_TRACE(std::string(csrbf::kernel_name(kernel)) + (variant == 1   ? " greedy"
                                                              : variant == 2 ? " two levels"
                                                                             : ""));
      MorphOptions o;
      o.fit.radius = radius;
      o.fit.kernel = kernel;
      o.greedy = greedy;
      o.levels = variant == 2 ? 2 : 1;
      const MorphResult r = morph(c.mesh, m, o);
      EXPECT_EQ(r.report.levels, o.levels);
      EXPECT_EQ(r.report.reach, 2 * radius);
      std::size_t far = 0, near_moved = 0;
      for (std::size_t q = 0; q < c.mesh.points.size(); ++q) {
        double nearest = std::numeric_limits<double>::infinity();
        for (const Vec3& s : moving) nearest = std::min(nearest, (c.mesh.points[q] - s).norm());
        if (nearest >= 2 * radius) {
          ++far;
          for (int k = 0; k < 3; ++k) EXPECT_EQ(bits(r.points[q][k]), bits(c.mesh.points[q][k])) << q;
        } else if (nearest < radius) {
          near_moved += r.points[q] != c.mesh.points[q];
        }
      }
      EXPECT_GT(far, 700u);         // z >= 0.6: 6 of 13 layers of 169 points
      EXPECT_GT(near_moved, 300u);  // the field itself is there
    }
  // A polynomial moves the whole space: no reach.
  MorphOptions linear;
  linear.fit.radius = radius;
  linear.fit.polynomial = csrbf::Polynomial::Linear;
  EXPECT_TRUE(std::isinf(morph(c.mesh, m, linear).report.reach));
}

// A far point's -0 stays -0 (bit for bit, as the reach promises) where a slip patch brings the
// correction's branch and the placement of slip points in (the attacker's finding: -0 came back 0).
TEST(ExactLocality, NegativeZeroStaysNegativeZeroWithSlipPatches) {
  TempDir dir;
  FoamCase c = box12(dir);
  std::vector<std::uint32_t> signed_zero;
  for (const auto p : c.mesh.patch("ymin")->points)
    if (c.mesh.points[p].z() >= 0.75 && c.mesh.points[p].x() > 0 && c.mesh.points[p].x() < 1) {
      c.mesh.points[p].y() = -0.0;
      signed_zero.push_back(p);
    }
  ASSERT_GT(signed_zero.size(), 10u);
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0.02, 0.01, 0.03]}, "zmax": "fixed",
                                          "xmin": "fixed", "xmax": "fixed", "ymin": "slip", "ymax": "slip"}})");
  for (const int levels : {1, 2}) {
    MorphOptions o;
    o.fit.radius = 0.3;
    o.levels = levels;
    const MorphResult r = morph(c.mesh, m, o);
    for (const auto p : signed_zero) EXPECT_TRUE(std::signbit(r.points[p].y())) << p << " levels " << levels;
  }
}

// Two levels (MorphOptions::levels): a coarse fit at R of the controls no two of which are closer
// than R / 4 (taken in the controls' order), then a fit at the fine radius of what it leaves at
// every control. Checked against the two dense solves, done here by brute force, on a 12^3 box.
TEST(TwoLevels, AreTheSumOfTwoDenseSolvesAndExactAtTheControls) {
  TempDir dir;
  const FoamCase c = box12(dir);
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 4, "origin": [0.5, 0.5, 0]}},
                             "zmax": "fixed", "xmin": "fixed", "xmax": "free", "ymin": "free", "ymax": "free"}})");
  const double R = 0.6;
  MorphOptions o;
  o.fit.radius = R;
  o.levels = 2;
  const MorphResult r = morph(c.mesh, m, o);
  const Prescribed p = prescribe(c.mesh, m);
  // The controls: moving, and staying within R of a moving one, in the prescribed points' order.
  std::vector<Vec3> x, d;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    bool keep = p.displacements[i] != Vec3::Zero();
    for (std::size_t j = 0; j < p.points.size() && !keep; ++j)
      keep = p.displacements[j] != Vec3::Zero() && (c.mesh.points[p.points[i]] - c.mesh.points[p.points[j]]).norm() < R;
    if (!keep) continue;
    x.push_back(c.mesh.points[p.points[i]]);
    d.push_back(p.displacements[i]);
  }
  // The coarse controls, first come first taken, by brute force.
  EXPECT_DOUBLE_EQ(r.report.coarse_spacing, R / 4);
  std::vector<std::size_t> coarse;
  for (std::size_t i = 0; i < x.size(); ++i) {
    bool free = true;
    for (const std::size_t j : coarse) free = free && (x[i] - x[j]).norm() >= R / 4;
    if (free) coarse.push_back(i);
  }
  EXPECT_EQ(r.report.levels, 2);
  EXPECT_EQ(r.report.coarse_controls, coarse.size());
  EXPECT_GT(coarse.size(), 20u);
  EXPECT_LT(coarse.size(), x.size() / 3);  // 70 of 261
  // The fine radius: 1.75 x the boundary's spacing, here the grid's 1/12.
  const double Rf = r.report.fine_radius;
  EXPECT_NEAR(Rf, 1.75 / 12, 1e-12);
  EXPECT_EQ(r.report.reach, 2 * R);
  const auto dense = [](const std::vector<Vec3>& at, const Eigen::MatrixXd& rhs, double radius) {
    const auto n = Eigen::Index(at.size());
    Eigen::MatrixXd A(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < n; ++j)
        A(i, j) = csrbf::wendland(csrbf::Kernel::C2, (at[std::size_t(i)] - at[std::size_t(j)]).norm() / radius);
    return Eigen::MatrixXd(A.llt().solve(rhs));
  };
  const auto sum = [](const std::vector<Vec3>& at, const Eigen::MatrixXd& alpha, double radius, const Vec3& q) {
    Vec3 v = Vec3::Zero();
    for (std::size_t j = 0; j < at.size(); ++j)
      v += alpha.row(Eigen::Index(j)).transpose() * csrbf::wendland(csrbf::Kernel::C2, (q - at[j]).norm() / radius);
    return v;
  };
  std::vector<Vec3> xc;
  Eigen::MatrixXd dc(Eigen::Index(coarse.size()), 3);
  for (std::size_t k = 0; k < coarse.size(); ++k) {
    xc.push_back(x[coarse[k]]);
    dc.row(Eigen::Index(k)) = d[coarse[k]].transpose();
  }
  const Eigen::MatrixXd ac = dense(xc, dc, R);
  Eigen::MatrixXd left(Eigen::Index(x.size()), 3);
  for (std::size_t i = 0; i < x.size(); ++i) left.row(Eigen::Index(i)) = (d[i] - sum(xc, ac, R, x[i])).transpose();
  EXPECT_GT(left.cwiseAbs().maxCoeff(), 1e-4);  // the coarse level alone misses the controls
  const Eigen::MatrixXd af = dense(x, left, Rf);
  std::vector<char> prescribed(c.mesh.points.size(), 0);
  for (const auto q : p.points) prescribed[q] = 1;
  const double scale = r.report.max_displacement;
  std::size_t compared = 0;
  for (std::size_t q = 0; q < c.mesh.points.size(); ++q) {
    if (prescribed[q]) continue;
    const Vec3 want = c.mesh.points[q] + sum(xc, ac, R, c.mesh.points[q]) + sum(x, af, Rf, c.mesh.points[q]);
    EXPECT_NEAR((r.points[q] - want).norm(), 0.0, 1e-10 * scale) << q;
    ++compared;
  }
  EXPECT_GT(compared, 1000u);
  // Exact at the controls before their exact placement, as one level is.
  EXPECT_LT(r.report.max_boundary_error, 1e-12 * scale);
  EXPECT_EQ(r.report.controls, x.size());
  // Auto: this fit is far below a second, one level.
  o.levels = 0;
  const MorphResult a = morph(c.mesh, m, o);
  EXPECT_EQ(a.report.levels, 1);
  EXPECT_GT(a.report.seconds_plain_predicted, 0.0);
  EXPECT_LT(a.report.seconds_plain_predicted, 1.0);
  // Two levels and what excludes them.
  o.levels = 3;
  EXPECT_THROW(morph(c.mesh, m, o), csrbf::InvalidInput);
  o.levels = 2;
  o.greedy = 1e-3;
  EXPECT_THROW(morph(c.mesh, m, o), csrbf::InvalidInput);
  o.greedy = 0;
  o.fit.polynomial = csrbf::Polynomial::Linear;
  EXPECT_THROW(morph(c.mesh, m, o), csrbf::InvalidInput);
}

// Auto's R with two levels (issue 31, a new user's finding): where one level would pass the memory
// budget and two levels fit it, R is kept and two levels are taken, where before R was cut to what
// one level could hold (and the smaller R inverted cells on windAroundBuildings).
TEST(TwoLevels, AutoRadiusIsKeptWhereTwoLevelsFitTheMemory) {
  TempDir dir;
  const FoamCase c = box12(dir);
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.05]}, "zmax": "fixed",
                                          "xmin": "fixed", "xmax": "fixed", "ymin": "fixed", "ymax": "fixed"}})");
  const auto run = [&](double limit_bytes, int levels) {
    MorphOptions o;
    o.radius_auto = true;
    o.fit.memory_limit_bytes = limit_bytes;
    o.levels = levels;
    return morph(c.mesh, m, o);
  };
  const MorphResult free = run(4e9, 0);
  EXPECT_NEAR(free.report.radius, 1.0, 1e-12);  // 20 x 0.05
  EXPECT_EQ(free.report.levels, 1);
  EXPECT_NE(free.report.levels_why.find("auto: one level"), std::string::npos) << free.report.levels_why;
  // Half of one level's predicted memory: one level cannot hold R = 1, two levels can.
  const double one = free.report.predicted.bytes;
  const MorphResult two = run(one, 0);
  EXPECT_NEAR(two.report.radius, 1.0, 1e-12);
  EXPECT_NE(two.report.radius_why.find("in two levels"), std::string::npos) << two.report.radius_why;
  EXPECT_EQ(two.report.levels, 2);
  EXPECT_NE(two.report.levels_why.find("memory budget"), std::string::npos) << two.report.levels_why;
  EXPECT_LT(two.report.max_boundary_error, 1e-12);
  // Asked for one level: R shrinks to what one level holds, as before.
  const MorphResult cut = run(one, 1);
  EXPECT_LT(cut.report.radius, 1.0);
  EXPECT_EQ(cut.report.levels, 1);
  EXPECT_EQ(cut.report.levels_why, "asked for");
}

TEST_F(BoxMorph, GreedyUsesFewerControlsWithinItsTolerance) {
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "xmin": "fixed", "xmax": "fixed"}})");
  MorphOptions o;
  o.fit.radius = 0.8;
  o.greedy = 0.05;
  // Unbounded: a loaded machine (the sanitizer pass) must not stop greedy by its time budget.
  o.greedy_budget = std::numeric_limits<double>::infinity();
  const MorphResult r = morph(c.mesh, m, o);
  const Prescribed p = prescribe(c.mesh, m);
  EXPECT_LT(r.report.controls, p.points.size());
  EXPECT_GE(r.report.greedy_rounds, 2u);
  EXPECT_LE(r.report.max_boundary_error, 0.05 * r.report.max_displacement);
  for (std::size_t i = 0; i < p.points.size(); ++i)
    EXPECT_NEAR((r.points[p.points[i]] - (c.mesh.points[p.points[i]] + p.displacements[i])).norm(), 0.0, 1e-15);
  // A tighter tolerance takes more controls.
  o.greedy = 1e-3;
  const MorphResult tight = morph(c.mesh, m, o);
  EXPECT_GT(tight.report.controls, r.report.controls);
  EXPECT_LE(tight.report.max_boundary_error, 1e-3 * r.report.max_displacement);
}

TEST_F(BoxMorph, TheLargestSafePhaseInvertsNothing) {
  // zmin pushed up by more than a cell layer: the first layer inverts.
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.4]}, "zmax": "fixed"}})");
  MorphOptions o;
  o.fit.radius = 0.3;
  const MorphResult r = morph(c.mesh, m, o);
  const PolyQuality after = poly_quality(c.mesh.poly, r.points);
  ASSERT_GT(after.inverted_cells, 0u);
  const double s = largest_safe_phase(c.mesh, r.points, 1.0, 0);
  EXPECT_GT(s, 0.1);
  EXPECT_LT(s, 1.0);
  const auto at = [&](double t) {
    std::vector<Vec3> p(r.points.size());
    for (std::size_t i = 0; i < p.size(); ++i) p[i] = c.mesh.points[i] + t * (r.points[i] - c.mesh.points[i]);
    return poly_quality(c.mesh.poly, p).inverted_cells;
  };
  EXPECT_EQ(at(s), 0u);
  EXPECT_GT(at(s + 2e-4), 0u);
}

TEST_F(BoxMorph, ThePatchesOfAnEmptyPatchAreRefused) {
  TempDir d2;
  BoxSpec s;
  s.empty_patch = true;
  csrbf::test::write_box_case(d2.path / "case", s);
  const FoamCase e = read_openfoam(d2.path / "case");
  EXPECT_NE(error_of([&] {
              prescribe(e.mesh, motion_from(dir, R"({"patches": {"nothing": "fixed"}})"));
            }).find("has no points"),
            std::string::npos);
}

TEST_F(BoxMorph, AGreedyToleranceBelowTheSolvesAccuracyStillEnds) {
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "xmin": "free", "xmax": "free",
                                                    "ymin": "free", "ymax": "free"}})");
  MorphOptions o;
  o.fit.radius = 0.5;
  o.greedy = 1e-300;
  o.greedy_budget = std::numeric_limits<double>::infinity();  // it must end by itself
  const MorphResult r = morph(c.mesh, m, o);
  EXPECT_LE(r.report.controls, 98u);
  EXPECT_LT(r.report.max_boundary_error, 1e-10);
}

// Issue 31, point 2: patches the motion leaves unlisted slip where planar (they left their planes:
// the ground of windAroundBuildings), and entries name patches by regular expression.
TEST_F(BoxMorph, UnlistedPlanarPatchesSlipWithinTheirPlanes) {
  const std::string twist = R"("zmin": {"rotate": {"axis": [0, 0, 1], "degrees": 4, "origin": [0.5, 0.5, 0]}},
                               "zmax": "fixed")";
  const auto run = [&](const std::string& more) {
    const Motion m = motion_from(dir, "{\"patches\": {" + twist + more + "}}");
    MorphOptions o;
    o.fit.radius = 0.6;
    return morph(c.mesh, m, o);
  };
  const MorphResult slip = run("");
  const MorphResult free = run(R"j(, "[xy]m(in|ax)": "free")j");
  const double size = std::sqrt(3.0);
  // The sides' points off the twisted face: on their planes to 1e-12 of the size, yet moved along
  // them; left free, they leave their planes.
  double along = 0, off_free = 0;
  std::size_t checked = 0;
  for (const char* name : {"xmin", "xmax", "ymin", "ymax"}) {
    const Patch* patch = c.mesh.patch(name);
    ASSERT_NE(patch, nullptr);
    const int axis = name[0] == 'x' ? 0 : 1;
    const double plane = name[1 + 1] == 'i' ? 0.0 : 1.0;
    for (const auto p : patch->points) {
      if (c.mesh.points[p].z() == 0) continue;  // the twisted face's edge moves with it
      EXPECT_LE(std::abs(slip.points[p][axis] - plane), 1e-12 * size) << name << " point " << p;
      along = std::max(along, (slip.points[p] - c.mesh.points[p]).norm());
      off_free = std::max(off_free, std::abs(free.points[p][axis] - plane));
      ++checked;
    }
  }
  EXPECT_GT(checked, 100u);
  EXPECT_GT(along, 1e-3);
  EXPECT_GT(off_free, 1e-3);
  EXPECT_GT(slip.report.slip, 100u);
  // The report: every patch, its kind and why.
  std::map<std::string, std::pair<std::string, std::string>> kinds;
  for (const auto& p : slip.report.patches) kinds[p.name] = {p.kind, p.why};
  EXPECT_EQ(kinds["zmin"], std::make_pair(std::string("moving"), std::string("listed")));
  EXPECT_EQ(kinds["zmax"], std::make_pair(std::string("fixed"), std::string("listed")));
  EXPECT_EQ(kinds["xmin"], std::make_pair(std::string("slip"), std::string("planar")));
  for (const auto& p : free.report.patches)
    if (p.name != "zmin" && p.name != "zmax") {
      EXPECT_EQ(p.kind, "free") << p.name;
      EXPECT_EQ(p.why, "listed as '[xy]m(in|ax)'") << p.name;
    }
  // Exact locality holds with slip: points 2R from every moving one (here none: the box is small)
  // and a pattern that names nothing is an error that lists the patches.
  const std::string e = error_of([&] { run(R"(, "wall.*": "fixed")"); });
  EXPECT_NE(e.find("the mesh has no patch 'wall.*'; its patches: "), std::string::npos) << e;
}

// Issue 31, point 3: --radius auto.
TEST_F(BoxMorph, AutoRadiusFollowsTheDisplacementTheSpacingAndTheMemoryLimit) {
  const auto run = [&](double dz, double limit_bytes) {
    const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, )" + std::to_string(dz) +
                                          R"j(]}, "zmax": "fixed", "[xy]m(in|ax)": "fixed"}})j");
    MorphOptions o;
    o.radius_auto = true;
    o.fit.memory_limit_bytes = limit_bytes;
    return morph(c.mesh, m, o);
  };
  // 20 x the largest displacement, where that is above 4 x the boundary's spacing (1/6).
  const MorphResult big = run(0.05, 4e9);
  EXPECT_NEAR(big.report.radius, 1.0, 1e-12);
  EXPECT_NE(big.report.radius_why.find("20 x the largest displacement 0.05"), std::string::npos)
      << big.report.radius_why;
  EXPECT_EQ(big.report.reach, 2 * big.report.radius);
  // A small motion: 4 x the spacing.
  const MorphResult small = run(0.002, 4e9);
  EXPECT_NEAR(small.report.radius, 4.0 / 6, 1e-12);
  EXPECT_NE(small.report.radius_why.find("4 x the boundary's spacing 0.1667"), std::string::npos)
      << small.report.radius_why;
  // The prediction: neighbours per control as the fit found them (every source counted, at most
  // 256 of them, or a sample), and per point against brute force over every point.
  for (const MorphResult* r : {&big, &small}) {
    const double R = r->report.radius;
    EXPECT_NEAR(r->report.predicted.neighbours_per_control, r->report.fit.mean_neighbors,
                0.05 * r->report.fit.mean_neighbors);
    std::vector<Vec3> moving, fitted;
    for (const auto p : c.mesh.patch("zmin")->points) moving.push_back(c.mesh.points[p]);
    fitted = moving;
    for (const Patch& patch : c.mesh.patches)
      for (const auto p : patch.points) {
        const Vec3& x = c.mesh.points[p];
        if (x.z() == 0) continue;
        bool near = false;
        for (const Vec3& m : moving) near |= (m - x).norm() < R;
        if (near && std::find(fitted.begin(), fitted.end(), x) == fitted.end()) fitted.push_back(x);
      }
    EXPECT_EQ(fitted.size(), r->report.controls);
    double terms = 0;
    for (const Vec3& x : c.mesh.points)
      for (const Vec3& s : fitted) terms += (s - x).norm() < R;
    EXPECT_NEAR(r->report.predicted.neighbours_per_point, terms / double(c.mesh.points.size()), 1e-12);
    EXPECT_GT(r->report.predicted.bytes, 0);
    EXPECT_GT(r->report.predicted.seconds_fit, 0);
  }
  // A memory limit that the displacement's R would pass: R shrinks until the prediction fits half
  // of it, and the report says so.
  const double at_one = big.report.predicted.bytes;
  const MorphResult capped = run(0.05, at_one);
  EXPECT_LT(capped.report.radius, 1.0);
  EXPECT_GT(capped.report.radius, 0.3);
  EXPECT_NE(capped.report.radius_why.find("above what --memory-limit leaves it"), std::string::npos)
      << capped.report.radius_why;
  EXPECT_LE(capped.report.predicted.bytes, 0.5 * at_one);
  // Nothing moves: no radius is needed, and none is chosen.
  const MorphResult still = run(0.0, 4e9);
  EXPECT_EQ(still.report.radius, 0.0);
  EXPECT_EQ(still.report.radius_why, "nothing moves");
  EXPECT_EQ(still.points, c.mesh.points);
}

// Issue 31, point 4: greedy never loses. Past its budget it stops and fits every control: the
// result is then the plain morph's, bit for bit, and the report says why.
TEST_F(BoxMorph, GreedyPastItsBudgetFitsEveryControl) {
  const Motion m =
      motion_from(dir, R"j({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "[xy]m(in|ax)": "fixed"}})j");
  MorphOptions plain;
  plain.fit.radius = 0.8;
  const MorphResult all = morph(c.mesh, m, plain);
  MorphOptions o = plain;
  o.greedy = 1e-3;
  o.greedy_budget = 0;  // no time at all: one round, then every control
  o.greedy_budget_floor = 0;
  const MorphResult stopped = morph(c.mesh, m, o);
  EXPECT_EQ(stopped.report.greedy_rounds, 1u);
  EXPECT_EQ(stopped.report.controls, all.report.controls);
  EXPECT_EQ(stopped.points, all.points);
  EXPECT_NE(stopped.report.greedy_stopped.find("every control is fitted instead"), std::string::npos)
      << stopped.report.greedy_stopped;
  EXPECT_NE(stopped.report.greedy_stopped.find("after 1 round ("), std::string::npos) << stopped.report.greedy_stopped;
  // Unbounded, it runs to its tolerance with fewer controls.
  o.greedy_budget = std::numeric_limits<double>::infinity();
  const MorphResult ran = morph(c.mesh, m, o);
  EXPECT_TRUE(ran.report.greedy_stopped.empty());
  EXPECT_LT(ran.report.controls, all.report.controls);
  EXPECT_LE(ran.report.max_boundary_error, 1e-3 * ran.report.max_displacement);

  // With slip sides a second fit corrects the slip points: once greedy stopped in the first fit,
  // the correction takes every control too, so the result is still the plain morph's.
  const Motion slip =
      motion_from(dir, R"j({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "[xy]m(in|ax)": "slip"}})j");
  const MorphResult slip_all = morph(c.mesh, slip, plain);
  ASSERT_GT(slip_all.report.controls, all.report.controls);  // the two fits' controls: a correction ran
  o.greedy_budget = 0;
  const MorphResult slip_stopped = morph(c.mesh, slip, o);
  EXPECT_EQ(slip_stopped.report.greedy_rounds, 1u);
  EXPECT_EQ(slip_stopped.report.controls, slip_all.report.controls);
  EXPECT_EQ(slip_stopped.points, slip_all.points);
  EXPECT_NE(slip_stopped.report.greedy_stopped.find("(and in a slip correction's fit, if one follows)"),
            std::string::npos)
      << slip_stopped.report.greedy_stopped;
}
