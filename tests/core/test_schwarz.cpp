// CG's Schwarz preconditioner (src/core/schwarz.hpp), against its definition by dense solves, and
// the steps it saves on random 2-D points (csrbf::Interpolator's fits).
#include "../../src/core/schwarz.hpp"
#include "../../src/core/sparse_solver.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/interpolator.hpp"
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/space_map.hpp"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <random>
#include <set>

using namespace csrbf;

namespace {

/// A's rows in CSR (input order), as CG hands them to its preconditioners.
struct Rows {
  std::vector<std::size_t> row;
  std::vector<std::uint32_t> col;
  std::vector<double> val;
};
Rows rows_of(const KernelMatrix& a) {
  Rows r;
  r.row.assign(1, 0);
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto nb = a.pattern().neighbors_of(i);
    const auto v = a.values_of(i);
    r.col.insert(r.col.end(), nb.begin(), nb.end());
    r.val.insert(r.val.end(), v.begin(), v.end());
    r.row.push_back(r.col.size());
  }
  return r;
}

std::vector<Vec3> random_points(std::size_t n, int dims, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> p(n, Vec3::Zero());
  for (auto& x : p)
    for (int d = 0; d < dims; ++d) x[d] = u(rng);
  return p;
}

double radius_for(double neighbors, std::size_t n, int dims) {
  return dims == 2 ? std::sqrt(neighbors / (M_PI * double(n))) : std::cbrt(neighbors / (4.0 / 3.0 * M_PI * double(n)));
}

/// n seeded random points in the unit square or cube, R for `neighbors` neighbours, A and its rows.
struct Case {
  std::vector<Vec3> pts;
  double radius;
  KernelMatrix a;
  Rows r;
};
Case make_case(std::size_t n, int dims, std::uint64_t seed, double neighbors = 40) {
  Case c;
  c.pts = random_points(n, dims, seed);
  c.radius = radius_for(neighbors, n, dims);
  c.a = KernelMatrix(AdjacencyGraph::from_index(NeighborIndex(c.pts, c.radius), c.pts), Kernel::C2, c.radius);
  c.r = rows_of(c.a);
  return c;
}

/// sum_p R_p^T A_pp^-1 R_p r, each block solved densely in double.
Eigen::MatrixXd by_definition(const detail::SchwarzPreconditioner& s, const Eigen::MatrixXd& dense,
                              const Eigen::MatrixXd& r) {
  Eigen::MatrixXd z = Eigen::MatrixXd::Zero(r.rows(), r.cols());
  for (std::size_t p = 0; p < s.patches(); ++p) {
    const auto m = s.patch(p);
    const auto size = Eigen::Index(m.size());
    Eigen::MatrixXd app(size, size), rp(size, r.cols());
    for (Eigen::Index i = 0; i < size; ++i) {
      rp.row(i) = r.row(m[i]);
      for (Eigen::Index j = 0; j < size; ++j) app(i, j) = dense(m[i], m[j]);
    }
    const Eigen::MatrixXd y = app.llt().solve(rp);
    for (Eigen::Index i = 0; i < size; ++i) z.row(m[i]) += y.row(i);
  }
  return z;
}

}  // namespace

// M^-1 r is the sum of the patches' solves (L in float: to float's precision times a patch's
// condition), for 1, 3 and 5 right-hand sides, in 2-D and 3-D.
TEST(Schwarz, ApplyIsTheSumOfThePatchesDenseSolves) {
  for (int dims : {2, 3}) {
    const std::size_t n = 600;
    const Case c = make_case(n, dims, 400 + std::uint64_t(dims));
    const Rows& r = c.r;
    const detail::SchwarzPreconditioner s(c.pts, c.radius, r.row, r.col, r.val, c.a.diagonal(), {}, 1e9);
    EXPECT_EQ(s.shift(), 0.0);
    EXPECT_GT(s.patches(), n / detail::kSchwarzLeafPoints);
    Eigen::MatrixXd dense = Eigen::MatrixXd::Identity(Eigen::Index(n), Eigen::Index(n));
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t e = r.row[i]; e < r.row[i + 1]; ++e) dense(Eigen::Index(i), r.col[e]) = r.val[e];
    for (std::size_t m : {1, 3, 5}) {
      std::mt19937_64 rng(m);
      std::normal_distribution<double> g;
      const auto rows = Eigen::Index(n), cols = Eigen::Index(m);
      RowMatrix rhs(rows, cols), z(rows, cols);
      for (Eigen::Index i = 0; i < rhs.size(); ++i) rhs.data()[i] = g(rng);
      s.apply(rhs.data(), z.data(), m);
      const Eigen::MatrixXd exact = by_definition(s, dense, rhs);
      EXPECT_LT((Eigen::MatrixXd(z) - exact).norm() / exact.norm(), 1e-4) << dims << "-D, " << m << " columns";
      // Symmetric: r2 . M^-1 r1 = r1 . M^-1 r2 (the columns as two vectors).
      if (m >= 3) {
        const double a12 = rhs.col(1).dot(z.col(0)), a21 = rhs.col(0).dot(z.col(1));
        EXPECT_NEAR(a12, a21, 1e-4 * std::abs(a12) + 1e-9);
        EXPECT_GT(rhs.col(0).dot(z.col(0)), 0.0);  // positive definite along r
      }
    }
  }
}

// The property its steps rest on: every pair of points closer than R / 4 is in one patch together
// (brute force over all pairs), every point is in a patch, and no patch passes its bound.
TEST(Schwarz, EveryPairCloserThanAQuarterOfTheRadiusSharesAPatch) {
  for (int dims : {2, 3}) {
    const std::size_t n = 4000;
    const Case c = make_case(n, dims, 500 + std::uint64_t(dims));
    const auto& pts = c.pts;
    const double radius = c.radius;
    const detail::SchwarzPreconditioner s(pts, radius, c.r.row, c.r.col, c.r.val, c.a.diagonal(), {}, 1e9);
    std::vector<std::vector<std::uint32_t>> of(n);
    for (std::size_t p = 0; p < s.patches(); ++p) {
      EXPECT_LE(s.patch(p).size(), detail::kSchwarzPatchPoints);
      for (std::uint32_t k : s.patch(p)) of[k].push_back(std::uint32_t(p));
    }
    std::size_t pairs = 0, apart = 0;
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_FALSE(of[i].empty()) << i;
      for (std::size_t j = i + 1; j < n; ++j) {
        if ((pts[i] - pts[j]).norm() >= 0.25 * radius) continue;
        ++pairs;
        std::vector<std::uint32_t> both;
        std::set_intersection(of[i].begin(), of[i].end(), of[j].begin(), of[j].end(), std::back_inserter(both));
        apart += both.empty();
      }
    }
    EXPECT_GT(pairs, n / 4) << dims << "-D";
    EXPECT_EQ(apart, 0u) << dims << "-D: of " << pairs << " close pairs";
    // Each point is in about 2-3 patches: the overlap is a quarter of R, not more.
    EXPECT_LT(double(s.patch_points()) / double(n), 4.0) << dims << "-D";
  }
}

// The same bits on one thread as on many (a fit gives the same bits on any machine).
TEST(Schwarz, SameBitsOnOneThreadAsOnMany) {
  const std::size_t n = 20000;
  const Case c = make_case(n, 2, 600);
  const auto& [pts, radius, a, r] = c;
  std::vector<double> rhs(n * 4);
  std::mt19937_64 rng(601);
  std::normal_distribution<double> g;
  for (double& v : rhs) v = g(rng);
  std::vector<double> many(n * 4), one(n * 4);
  const detail::SchwarzPreconditioner s(pts, radius, r.row, r.col, r.val, a.diagonal(), {}, 1e9);
  s.apply(rhs.data(), many.data(), 4);
  tbb::task_arena(1).execute([&] {
    const detail::SchwarzPreconditioner s1(pts, radius, r.row, r.col, r.val, a.diagonal(), {}, 1e9);
    s1.apply(rhs.data(), one.data(), 4);
  });
  EXPECT_EQ(one, many);
}

// Points at one position (allowed where smoothed: a shifted diagonal) cannot be split by a cut:
// their leaf is halved by count, and every patch stays within its bound.
TEST(Schwarz, PointsAtOnePositionAreSplitByCount) {
  auto pts = random_points(300, 2, 700);
  for (int i = 0; i < 500; ++i) pts.push_back(Vec3(0.5, 0.5, 0.0));
  const std::size_t n = pts.size();
  const double radius = 0.2;
  const KernelMatrix a(AdjacencyGraph::from_index(NeighborIndex(pts, radius), pts), Kernel::C2, radius);
  const Rows r = rows_of(a);
  std::vector<double> diagonal(n, a.diagonal());
  for (std::size_t i = 300; i < n; ++i) diagonal[i] += 0.1;
  const detail::SchwarzPreconditioner s(pts, radius, r.row, r.col, r.val, a.diagonal(), diagonal, 1e9);
  for (std::size_t p = 0; p < s.patches(); ++p) EXPECT_LE(s.patch(p).size(), detail::kSchwarzPatchPoints);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
  for (std::size_t i = 0; i < n; ++i) {
    dense(Eigen::Index(i), Eigen::Index(i)) = diagonal[i];
    for (std::size_t e = r.row[i]; e < r.row[i + 1]; ++e) dense(Eigen::Index(i), r.col[e]) = r.val[e];
  }
  RowMatrix rhs = RowMatrix::Ones(Eigen::Index(n), 1), z(Eigen::Index(n), 1);
  for (std::size_t i = 0; i < n; ++i) rhs(Eigen::Index(i), 0) = std::sin(double(i));
  s.apply(rhs.data(), z.data(), 1);
  ASSERT_TRUE(z.allFinite());
  const Eigen::MatrixXd exact = by_definition(s, dense, rhs);
  EXPECT_LT((Eigen::MatrixXd(z) - exact).norm() / exact.norm(), 1e-3);
}

// Its bytes are counted before its factors are allocated, and refused above its share.
TEST(Schwarz, RefusesMoreBytesThanItsShare) {
  // The share CG sets aside holds the patches at 40 neighbours and at a multiscale fit's finest level
  // (about 12), in 2-D and 3-D, with room to spare (a fit at the edge fell back to the incomplete
  // Cholesky at some sizes and not others).
  for (int dims : {2, 3})
    for (double neighbors : {6.0, 12.5, 40.0}) {
      const Case c = make_case(20000, dims, 810, neighbors);
      const detail::SchwarzPreconditioner s(c.pts, c.radius, c.r.row, c.r.col, c.r.val, c.a.diagonal(), {}, 1e9);
      EXPECT_LE(s.bytes(), 0.75 * detail::schwarz_share(c.r.col.size(), c.pts.size()))
          << dims << "-D, " << neighbors << " neighbours";
    }
  const std::size_t n = 2000;
  const Case c = make_case(n, 3, 800);
  const auto& [pts, radius, a, r] = c;
  const detail::SchwarzPreconditioner s(pts, radius, r.row, r.col, r.val, a.diagonal(), {}, 1e9);
  EXPECT_LE(s.bytes(), detail::schwarz_share(r.col.size(), n));
  EXPECT_THROW(detail::SchwarzPreconditioner(pts, radius, r.row, r.col, r.val, a.diagonal(), {}, 0.5 * s.bytes()),
               ResourceLimit);
}

// Issue 34: random 2-D points at 40 neighbours, where the incomplete Cholesky of the space mapping's
// CG took 652 steps at 1e5 points: the interpolator's CG with Schwarz patches converges in a few
// tens of steps (29 at 1e4 and 1e5 points in the prototype), and reproduces the data.
TEST(Schwarz, InterpolatorCgConvergesInFewStepsOnRandomPlanarPoints) {
  const std::size_t n = 20000;
  const auto pts3 = random_points(n, 2, 900);
  std::vector<double> pts(2 * n), values(n);
  for (std::size_t i = 0; i < n; ++i) {
    pts[2 * i] = pts3[i].x();
    pts[2 * i + 1] = pts3[i].y();
    values[i] = std::sin(6 * pts3[i].x()) * std::cos(5 * pts3[i].y());
  }
  InterpolatorOptions o;
  o.solver = Solver::Cg;
  const Interpolator f = Interpolator::fit(pts, 2, values, 1, o);
  ASSERT_EQ(f.levels().size(), 1u);
  const InterpolatorLevel& level = f.levels()[0];
  EXPECT_EQ(level.solver, Solver::Cg);
  EXPECT_LT(level.iterations, 80u);
  std::vector<double> at(n);
  f.evaluate(pts.data(), n, at.data());
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(at[i] - values[i]));
  EXPECT_LT(worst, 1e-9);
  // The space mapping's CG on the same matrix (the incomplete Cholesky) takes several times the steps.
  FitOptions so{level.radius, Kernel::C2};
  so.solver = Solver::Cg;
  std::vector<Vec3> d(pts3);
  for (std::size_t i = 0; i < n; ++i) d[i].z() += values[i];
  const SpaceMap m = SpaceMap::fit(pts3, d, so);
  EXPECT_GT(m.stats().iterations, 3 * level.iterations) << level.iterations;
}

// The premise of the interpolator's shortcut to CG (fit.cpp): from kSchwarzOnlyPoints planar points
// with kSchwarzOnlyNeighbors neighbours on average, the envelope's work in RCM order is above
// kEnvelopeWorkLimit, so Auto could not have chosen it; and such a fit goes to CG.
TEST(Schwarz, WhereTheInterpolatorSkipsTheEnvelopeItCouldNotHaveWon) {
  const std::size_t n = detail::kSchwarzOnlyPoints;
  const auto pts = random_points(n, 2, 1000);
  const double radius = radius_for(detail::kSchwarzOnlyNeighbors, n, 2);
  std::vector<Vec3> d(pts);
  for (auto& x : d) x.z() += 0.01;
  FitOptions o{radius, Kernel::C2};
  o.solver = Solver::Envelope;
  o.ordering = Ordering::ReverseCuthillMcKee;
  const SpaceMap m = SpaceMap::fit(pts, d, o);
  EXPECT_GT(m.stats().envelope_work, kEnvelopeWorkLimit);
  EXPECT_GT(m.stats().mean_neighbors, 0.9 * detail::kSchwarzOnlyNeighbors);
  std::vector<double> flat(2 * n), values(n);
  for (std::size_t i = 0; i < n; ++i) {
    flat[2 * i] = pts[i].x();
    flat[2 * i + 1] = pts[i].y();
    values[i] = pts[i].x() * pts[i].y();
  }
  InterpolatorOptions io;
  io.radius = radius * std::sqrt(1.1);  // at least kSchwarzOnlyNeighbors on average
  const Interpolator f = Interpolator::fit(flat, 2, values, 1, io);
  EXPECT_EQ(f.levels()[0].solver, Solver::Cg);
  std::vector<double> at(n);
  f.evaluate(flat.data(), n, at.data());
  for (std::size_t i = 0; i < n; i += 97) EXPECT_NEAR(at[i], values[i], 1e-9);
}

// Large arrays (FillVector, types.hpp) start on 2 MiB boundaries, where transparent huge pages can
// back them; small ones come from the usual allocator; both hold what is written.
TEST(Memory, LargeArraysStartOnHugePageBoundaries) {
  FillVector<double> big(detail::kHugePageArray / sizeof(double) + 1);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(big.data()) % (std::uintptr_t(2) << 20), 0u);
  for (std::size_t i = 0; i < big.size(); i += 4096) big[i] = double(i);
  big.back() = -1.0;
  FillVector<double> copy = big;
  EXPECT_EQ(copy[4096], 4096.0);
  EXPECT_EQ(copy.back(), -1.0);
  FillVector<float> small(1000, 2.0f);
  EXPECT_EQ(small[999], 2.0f);
  big.resize(2 * big.size());  // reallocation through the same allocator
  EXPECT_EQ(big[4096], 4096.0);
  EXPECT_THROW(FillVector<double>(std::size_t(-1) / 4), std::length_error);
}

// A patch is factorised scaled to a unit diagonal: a smoothing of 1e100 on some points (a diagonal
// whose Cholesky factor a float cannot hold) leaves M^-1 finite and equal to its definition.
TEST(Schwarz, AHugeSmoothingStaysWithinTheFloatFactors) {
  const Case c = make_case(2000, 2, 1100);
  const std::size_t n = c.pts.size();
  std::vector<double> diagonal(n, c.a.diagonal());
  for (std::size_t i = 0; i < n; i += 50) diagonal[i] = 1.2e100;
  const detail::SchwarzPreconditioner s(c.pts, c.radius, c.r.row, c.r.col, c.r.val, c.a.diagonal(), diagonal, 1e9);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(Eigen::Index(n), Eigen::Index(n));
  for (std::size_t i = 0; i < n; ++i) {
    dense(Eigen::Index(i), Eigen::Index(i)) = diagonal[i];
    for (std::size_t e = c.r.row[i]; e < c.r.row[i + 1]; ++e) dense(Eigen::Index(i), c.r.col[e]) = c.r.val[e];
  }
  RowMatrix rhs(Eigen::Index(n), 1), z(Eigen::Index(n), 1);
  for (std::size_t i = 0; i < n; ++i) rhs(Eigen::Index(i), 0) = std::cos(double(i));
  s.apply(rhs.data(), z.data(), 1);
  ASSERT_TRUE(z.allFinite());
  const Eigen::MatrixXd exact = by_definition(s, dense, rhs);
  EXPECT_LT((Eigen::MatrixXd(z) - exact).norm() / exact.norm(), 1e-5);
  EXPECT_NE(z(0, 0), 0.0);  // the smoothed rows are solved, not zeroed
}

// Values near 1e-165 (sums of their squares underflow): CG scales each right-hand side first, and
// the interpolant reproduces them (it was 0 everywhere, with a residual of 0 reported).
TEST(Schwarz, TinyValuesAreInterpolatedThroughConjugateGradients) {
  const std::size_t n = detail::kSchwarzOnlyPoints;
  const auto pts3 = random_points(n, 2, 1200);
  std::vector<double> pts(2 * n), values(n);
  for (std::size_t i = 0; i < n; ++i) {
    pts[2 * i] = pts3[i].x();
    pts[2 * i + 1] = pts3[i].y();
    values[i] = 1e-165 * std::sin(5 * pts3[i].x());
  }
  const Interpolator f = Interpolator::fit(pts, 2, values, 1, InterpolatorOptions{});
  EXPECT_EQ(f.levels()[0].solver, Solver::Cg);
  std::vector<double> at(n);
  f.evaluate(pts.data(), n, at.data());
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(at[i] - values[i]));
  EXPECT_LT(worst, 1e-9 * 1e-165);
}
