// What a fit is asked to do (csrbf/fit_options.hpp): FitOptions' defaults, the polynomial and solver
// names, Auto's rule between the envelope solver and CG, and the estimate of a fit's neighbours.
#include "csrbf/fit_options.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

using namespace csrbf;

TEST(FitOptions, DefaultsAreTheDocumentedOnes) {
  const FitOptions o;
  EXPECT_EQ(o.radius, 0.0);  // no radius: the caller must give one
  EXPECT_EQ(o.kernel, Kernel::C2);
  EXPECT_EQ(o.polynomial, Polynomial::None);
  EXPECT_EQ(o.ordering, Ordering::Auto);
  EXPECT_EQ(o.solver, Solver::Auto);
  EXPECT_EQ(o.memory_limit_bytes, 4.0 * 1073741824.0);  // 4 GiB
}

TEST(FitOptions, PolynomialAndSolverNamesRoundTrip) {
  const std::vector<std::pair<Polynomial, std::string>> polynomials{
      {Polynomial::None, "none"}, {Polynomial::Constant, "constant"}, {Polynomial::Linear, "linear"}};
  for (const auto& [p, name] : polynomials) {
    EXPECT_EQ(polynomial_name(p), name);
    EXPECT_EQ(parse_polynomial(name), p) << name;
  }
  EXPECT_EQ(parse_polynomial("LINEAR"), Polynomial::Linear);  // any case
  EXPECT_FALSE(parse_polynomial("quadratic").has_value());
  EXPECT_FALSE(parse_polynomial("").has_value());
  const std::vector<std::pair<Solver, std::string>> solvers{{Solver::Envelope, "envelope"},
                                                            {Solver::Eigen, "eigen"},
                                                            {Solver::Cholmod, "cholmod"},
                                                            {Solver::Auto, "auto"},
                                                            {Solver::Cg, "cg"}};
  for (const auto& [s, name] : solvers) {
    EXPECT_EQ(solver_name(s), name);
    EXPECT_EQ(parse_solver(name), s) << name;
  }
  EXPECT_EQ(parse_solver("Envelope"), Solver::Envelope);
  EXPECT_FALSE(parse_solver("lu").has_value());
}

TEST(FitOptions, AutoWeighsTheEnvelopeAgainstConjugateGradients) {
  // An explicit choice is kept, whatever the work.
  for (const Solver s : {Solver::Envelope, Solver::Eigen, Solver::Cholmod, Solver::Cg})
    EXPECT_EQ(resolve_solver(s, 1e30, 10, 20), s) << solver_name(s);
  // Without counts, the envelope solver up to its work limit.
  EXPECT_EQ(resolve_solver(Solver::Auto, 0.0), Solver::Envelope);
  EXPECT_EQ(resolve_solver(Solver::Auto, 1.01 * kEnvelopeWorkLimit), Solver::Cg);
  // 100 controls and 450 neighbour pairs: kCgStepsEstimate CG steps on 3 right-hand sides cost
  // 100 * 3 * (2 * 450 + 100) = 3e5 multiply-adds, as many as 5e5 of the envelope's at 0.6 each.
  EXPECT_EQ(kCgStepsEstimate * 3.0 * (2.0 * 450 + 100), 3e5);
  EXPECT_EQ(resolve_solver(Solver::Auto, 4.99e5, 100, 450), Solver::Envelope);
  EXPECT_EQ(resolve_solver(Solver::Auto, 5.01e5, 100, 450), Solver::Cg);
}

TEST(FitOptions, MemoryEstimateCountsEveryNeighbourUpTo256Sources) {
  // A 5 x 5 x 5 grid of spacing 1 (125 sources: every one counted), R = 1.5: the 6 face and 12
  // edge neighbours of an inner point are within R, the corners (sqrt 3) are not.
  std::vector<Vec3> grid;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j)
      for (int k = 0; k < 5; ++k) grid.emplace_back(i, j, k);
  std::size_t pairs = 0;
  for (const Vec3& a : grid)
    for (const Vec3& b : grid) pairs += &a != &b && (a - b).norm() < 1.5;
  const FitMemoryEstimate e = estimate_fit_memory(grid, 1.5);
  EXPECT_DOUBLE_EQ(e.mean_neighbors, double(pairs) / 125.0);
  EXPECT_EQ(e.max_neighbors, 18.0);
  EXPECT_GT(e.bytes, 0.0);
  // A radius past the grid's diagonal: every source is every other's neighbour, and more memory.
  const FitMemoryEstimate all = estimate_fit_memory(grid, 10.0);
  EXPECT_EQ(all.mean_neighbors, 124.0);
  EXPECT_EQ(all.max_neighbors, 124.0);
  EXPECT_GT(all.bytes, e.bytes);
  // Fewer than two sources have no neighbours and need nothing.
  const FitMemoryEstimate one = estimate_fit_memory(std::vector<Vec3>{Vec3(0, 0, 0)}, 1.0);
  EXPECT_EQ(one.mean_neighbors, 0.0);
  EXPECT_EQ(one.bytes, 0.0);
}
