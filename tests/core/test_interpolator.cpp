// csrbf::Interpolator in C++: against a dense solve of the same saddle-point system (Eigen's LU), in
// double and float, with a linear polynomial and per-point smoothing on 2-D points with 4 values; a
// fit restored from its levels evaluates as the fit; the refusals. The Python tests
// (tests/python/test_interpolator.py) cover every dimension, value shape, degree and the multiscale levels.
#include "csrbf/errors.hpp"
#include "csrbf/interpolator.hpp"

#include "../../src/core/sparse_solver.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace {

using namespace csrbf;

double c2(double r) { return r < 1 ? std::pow(1 - r, 4) * (4 * r + 1) : 0.0; }

TEST(Interpolator, EqualsADenseSolveWithAPolynomialAndSmoothing) {
  std::mt19937_64 rng(34);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr std::size_t P = 300, V = 4, Q = 200;
  constexpr double R = 0.22;
  std::vector<double> pts(2 * P), vals(V * P), lambda(P), x(2 * Q);
  for (double& a : pts) a = u(rng);
  for (double& a : vals) a = u(rng) - 0.5;
  for (double& a : lambda) a = 0.02 * u(rng);
  for (double& a : x) a = 1.2 * u(rng) - 0.1;
  InterpolatorOptions o;
  o.radius = R;
  o.degree = 1;
  o.smoothing = lambda;
  const Interpolator s = Interpolator::fit(pts, 2, vals, V, o);
  // [[A + Lambda, P], [P^T, 0]] [alpha; beta] = [f; 0], P = [1, x, y].
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(P + 3, P + 3), rhs = Eigen::MatrixXd::Zero(P + 3, V);
  for (std::size_t i = 0; i < P; ++i) {
    for (std::size_t j = 0; j < P; ++j)
      m(i, j) = c2(std::hypot(pts[2 * i] - pts[2 * j], pts[2 * i + 1] - pts[2 * j + 1]) / R);
    m(i, i) += lambda[i];
    m(i, P) = m(P, i) = 1;
    m(i, P + 1) = m(P + 1, i) = pts[2 * i];
    m(i, P + 2) = m(P + 2, i) = pts[2 * i + 1];
    for (std::size_t v = 0; v < V; ++v) rhs(i, v) = vals[i * V + v];
  }
  const Eigen::MatrixXd sol = m.lu().solve(rhs);
  std::vector<double> got(Q * V);
  std::vector<float> xf(x.begin(), x.end()), gotf(Q * V);
  s.evaluate(x.data(), Q, got.data());
  s.evaluate(xf.data(), Q, gotf.data());
  double largest = 0, err = 0, errf = 0;
  for (std::size_t q = 0; q < Q; ++q)
    for (std::size_t v = 0; v < V; ++v) {
      double want = sol(P, v) + sol(P + 1, v) * x[2 * q] + sol(P + 2, v) * x[2 * q + 1];
      for (std::size_t i = 0; i < P; ++i)
        want += sol(i, v) * c2(std::hypot(x[2 * q] - pts[2 * i], x[2 * q + 1] - pts[2 * i + 1]) / R);
      largest = std::max(largest, std::abs(want));
      err = std::max(err, std::abs(got[q * V + v] - want));
      errf = std::max(errf, std::abs(double(gotf[q * V + v]) - want));
    }
  EXPECT_LT(err, 1e-9 * largest);
  EXPECT_LT(errf, 1e-4 * largest);
  EXPECT_EQ(s.levels().size(), 1u);
  EXPECT_LE(s.levels()[0].residual_relative, kResidualLimit);

  // Restored from its levels (pickling), it evaluates as the fit.
  const Interpolator t = Interpolator::from_levels(2, V, s.kernel(), s.degree(), s.levels());
  std::vector<double> again(Q * V);
  t.evaluate(x.data(), Q, again.data());
  for (std::size_t k = 0; k < again.size(); ++k) EXPECT_NEAR(again[k], got[k], 1e-13 * largest);

  // A value count whose product with the points wraps size_t (a forged pickle: 2^62 values, no
  // coefficients) is refused, not read past the coefficients' end.
  auto forged = s.levels();
  forged[0].alpha.clear();
  EXPECT_THROW(Interpolator::from_levels(2, std::size_t(1) << 62, s.kernel(), s.degree(), forged), InvalidInput);
  forged[0].alpha.assign(4, 0.0);
  EXPECT_THROW(Interpolator::from_levels(2, (std::size_t(1) << 62) + 1, s.kernel(), s.degree(), forged), InvalidInput);
}

// Conjugate gradients and its incomplete Cholesky preconditioner with a smoothing a point (A's
// diagonal no longer constant), over the levels of a multiscale fit: each level's system is solved
// (residual <= 1e-6) and, without smoothing, the sum reproduces the data at every point.
TEST(Interpolator, MultiscaleLevelsThroughConjugateGradientsWithSmoothing) {
  std::mt19937_64 rng(341);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr std::size_t P = 4000;
  std::vector<double> pts(2 * P), vals(P), lambda(P);
  for (double& a : pts) a = u(rng);
  for (std::size_t i = 0; i < P; ++i) {
    vals[i] = std::sin(6 * pts[2 * i]) * std::cos(5 * pts[2 * i + 1]);
    lambda[i] = i % 3 == 0 ? 1e-3 : 0.0;
  }
  InterpolatorOptions o;
  o.levels = 3;
  o.solver = Solver::Cg;
  o.smoothing = lambda;
  const Interpolator s = Interpolator::fit(pts, 2, vals, 1, o);
  ASSERT_EQ(s.levels().size(), 3u);
  for (const auto& level : s.levels()) {
    EXPECT_EQ(level.solver, Solver::Cg);
    EXPECT_LE(level.residual_relative, kResidualLimit);
  }
  // One scale at 40 neighbours: random points' close pairs make CG slow enough to take its
  // incomplete Cholesky preconditioner, built from the shifted diagonal.
  InterpolatorOptions one = o;
  one.levels = 1;
  one.neighbors = 40;
  const Interpolator single = Interpolator::fit(pts, 2, vals, 1, one);
  EXPECT_LE(single.levels()[0].residual_relative, kResidualLimit);
  EXPECT_GT(single.levels()[0].iterations, 12u);  // past CG's probe, where it takes the preconditioner
  o.smoothing = {};
  const Interpolator exact = Interpolator::fit(pts, 2, vals, 1, o);
  std::vector<double> at(P);
  exact.evaluate(pts.data(), P, at.data());
  for (std::size_t i = 0; i < P; ++i) EXPECT_NEAR(at[i], vals[i], 1e-6) << i;
}

// The automatic radius on clustered points (a dense cluster and a few points far away, where the
// guess from the box's volume holds every point of the cluster): equal to its definition by brute
// force over every pair (below 4096 points every point is sampled): just past the distance within
// which the points have `neighbors` others on average.
TEST(Interpolator, AutomaticRadiusOnClusteredPointsIsTheBruteForceOne) {
  std::mt19937_64 rng(3434);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr std::size_t P = 3000, far = 6;
  std::vector<double> pts;
  for (std::size_t i = 0; i < P - far; ++i) pts.insert(pts.end(), {1e-3 * u(rng), 1e-3 * u(rng)});
  for (std::size_t i = 0; i < far; ++i) pts.insert(pts.end(), {5.0 + u(rng), 5.0 * u(rng)});
  for (const double neighbors : {10.0, 40.0}) {
    std::vector<double> d2;
    for (std::size_t i = 0; i < P; ++i)
      for (std::size_t j = 0; j < P; ++j)
        if (i != j) d2.push_back(std::pow(pts[2 * i] - pts[2 * j], 2) + std::pow(pts[2 * i + 1] - pts[2 * j + 1], 2));
    const auto need = std::size_t(std::ceil(neighbors * double(P)));
    std::nth_element(d2.begin(), d2.begin() + std::ptrdiff_t(need - 1), d2.end());
    InterpolatorOptions o;
    o.neighbors = neighbors;
    const Interpolator s = Interpolator::fit(pts, 2, std::vector<double>(P, 1.0), 1, o);
    EXPECT_DOUBLE_EQ(s.levels()[0].radius, std::sqrt(d2[need - 1]) * (1 + 1e-9)) << neighbors;
    EXPECT_NEAR(s.levels()[0].mean_neighbors, neighbors, 0.01 * neighbors) << neighbors;
  }
  // 3-D points in a slab 1e-7 thick: the guess from the box's volume is a radius of 3e-4 of its
  // side, more cells than NeighborIndex's counting sort takes (its comparison sort does), and the
  // guess doubles until the points have enough neighbours, few cells by then (the counting sort).
  std::vector<double> slab;
  for (std::size_t i = 0; i < P; ++i) slab.insert(slab.end(), {u(rng), u(rng), 1e-7 * u(rng)});
  std::vector<double> d2;
  for (std::size_t i = 0; i < P; ++i)
    for (std::size_t j = 0; j < P; ++j)
      if (i != j)
        d2.push_back(std::pow(slab[3 * i] - slab[3 * j], 2) + std::pow(slab[3 * i + 1] - slab[3 * j + 1], 2) +
                     std::pow(slab[3 * i + 2] - slab[3 * j + 2], 2));
  const auto need = std::size_t(std::ceil(20.0 * double(P)));
  std::nth_element(d2.begin(), d2.begin() + std::ptrdiff_t(need - 1), d2.end());
  InterpolatorOptions o;
  o.neighbors = 20;
  const Interpolator s = Interpolator::fit(slab, 3, std::vector<double>(P, 1.0), 1, o);
  EXPECT_NEAR(s.levels()[0].radius, std::sqrt(d2[need - 1]) * (1 + 1e-9), 1e-12);
}

// Many scattered 2-D points: their level is sorted into the Schwarz patches' order before A is
// built, and CG reads A in place. Under a memory limit that holds A and CG without a copy of A's
// rows, but not with one, the fit is the same as without a limit: CG with the Schwarz patches.
TEST(Interpolator, ConjugateGradientsReadTheSortedMatrixInPlace) {
  std::mt19937_64 rng(3435);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr std::size_t P = 20000, Q = 500;
  std::vector<double> pts(2 * P), vals(P), x(2 * Q);
  for (double& a : pts) a = u(rng);
  for (std::size_t i = 0; i < P; ++i) vals[i] = std::sin(5 * pts[2 * i]) * pts[2 * i + 1];
  for (double& a : x) a = u(rng);
  InterpolatorOptions o;
  const Interpolator free = Interpolator::fit(pts, 2, vals, 1, o);
  const InterpolatorLevel& level = free.levels()[0];
  ASSERT_EQ(level.solver, Solver::Cg);
  ASSERT_LE(level.iterations, 60u);  // the Schwarz patches (IC(0) takes hundreds of steps here)
  const auto entries = std::size_t(std::llround(level.mean_neighbors * double(P)));
  const double a_bytes = 12.0 * double(entries) + 8.0 * double(P + 1);
  const double in_place = a_bytes + detail::cg_bytes(entries, P, true, false);
  const double copied = a_bytes + detail::cg_bytes(entries, P, true, true);
  ASSERT_GT(copied - in_place, 12.0 * double(entries));
  o.memory_limit_bytes = 0.5 * (in_place + copied);
  const Interpolator tight = Interpolator::fit(pts, 2, vals, 1, o);
  EXPECT_EQ(tight.levels()[0].solver, Solver::Cg);
  // CG's sums are reduced in parallel, their order left to the threads: equal to rounding, not in
  // every bit (nor always in the step that reaches the tolerance).
  EXPECT_NEAR(double(tight.levels()[0].iterations), double(level.iterations), 1.0);
  std::vector<double> a(Q), b(Q);
  free.evaluate(x.data(), Q, a.data());
  tight.evaluate(x.data(), Q, b.data());
  for (std::size_t q = 0; q < Q; ++q) EXPECT_NEAR(a[q], b[q], 1e-9) << q;
  // The level keeps its points in the patches' order; evaluated at them, the fit gives the values.
  std::vector<double> at(P);
  free.evaluate(pts.data(), P, at.data());
  for (std::size_t i = 0; i < P; ++i) EXPECT_NEAR(at[i], vals[i], 1e-9) << i;
}

TEST(Interpolator, RefusesWhatItCannotFit) {
  const std::vector<double> pts{0, 0, 1, 0, 0, 1, 1, 1}, vals{1, 2, 3, 4};
  InterpolatorOptions o;
  o.radius = 1.5;
  EXPECT_THROW(Interpolator::fit(std::vector<double>(8, 0.0), 4, std::vector<double>(2, 0.0), 1, o), InvalidInput);
  EXPECT_THROW(Interpolator::fit(pts, 2, std::vector<double>{1, 2, 3}, 1, o), InvalidInput);
  EXPECT_THROW(Interpolator::fit(std::vector<double>{0, 0, 1, 0, 0, 0, 1, 1}, 2, vals, 1, o), DuplicateSource);
  o.degree = 1;
  EXPECT_THROW(Interpolator::fit(std::vector<double>{0, 0, 1, 1, 2, 2, 3, 3}, 2, vals, 1, o), DegeneratePolynomial);
  o.degree = -1;
  o.smoothing = {-1.0};
  EXPECT_THROW(Interpolator::fit(pts, 2, vals, 1, o), InvalidInput);
  o.smoothing = {};
  o.memory_limit_bytes = 100;
  std::vector<double> many(2 * 2000), ones(2000, 1.0);
  std::mt19937_64 rng(1);
  for (double& a : many) a = std::uniform_real_distribution<double>(0, 1)(rng);
  o.radius = 2.0;
  EXPECT_THROW(Interpolator::fit(many, 2, ones, 1, o), ResourceLimit);
}

}  // namespace
