// What a fit reports of itself (csrbf/fit_stats.hpp): the neighbour counts against a brute-force
// count, the paper's storage accounting, the envelope factor's entries, the residual against the
// mapping evaluated at the controls, and the sum of the phases' seconds.
#include "csrbf/fit_stats.hpp"
#include "csrbf/space_map.hpp"

#include <gtest/gtest.h>

#include "test_points.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using namespace csrbf;

namespace {

using test::displaced;
using test::random_points;

}  // namespace

TEST(SpaceMap, StatsReportTheProfile) {
  std::mt19937 rng(18);
  auto s = random_points(1000, rng);
  const auto d = displaced(s, rng);
  const SpaceMap m = SpaceMap::fit(s, d, {0.1, Kernel::C0, Polynomial::None, Ordering::Auto});
  const FitStats& st = m.stats();
  EXPECT_EQ(st.controls, 1000u);
  EXPECT_EQ(st.dense_bytes, 4u * 1000 * 1000);
  EXPECT_EQ(st.envelope_bytes, 4 * (1000 + st.envelope_entries) + 4 * 1000);
  EXPECT_LT(st.envelope_bytes, st.dense_bytes / 4);
  EXPECT_LE(st.envelope_entries, st.identity.envelope);
  EXPECT_GT(st.mean_neighbors, 1.0);
  EXPECT_EQ(double(st.neighbor_pairs) * 2 / 1000.0, st.mean_neighbors);
  EXPECT_GT(st.seconds_total(), 0.0);
}

TEST(FitStats, SecondsTotalIsTheSumOfThePhases) {
  EXPECT_EQ(FitStats{}.seconds_total(), 0.0);
  FitStats st;
  st.seconds_index = 1;
  st.seconds_graph = 2;
  st.seconds_ordering = 4;
  st.seconds_assembly = 8;
  st.seconds_factorization = 16;
  st.seconds_solve = 32;
  st.seconds_residual = 64;
  EXPECT_EQ(st.seconds_total(), 127.0);
}

TEST(FitStats, EnvelopeFitCountsPairsFactorAndResidual) {
  std::mt19937 rng(21);
  const auto s = random_points(400, rng);
  const auto d = displaced(s, rng);
  const double r = 0.2;
  FitOptions o{r, Kernel::C2, Polynomial::Linear, Ordering::Identity};
  o.solver = Solver::Envelope;
  const SpaceMap m = SpaceMap::fit(s, d, o);
  const FitStats& st = m.stats();
  std::size_t pairs = 0;
  for (std::size_t i = 0; i < s.size(); ++i)
    for (std::size_t j = i + 1; j < s.size(); ++j) pairs += (s[i] - s[j]).norm() < r;
  EXPECT_EQ(st.controls, s.size());
  EXPECT_EQ(st.neighbor_pairs, pairs);
  EXPECT_DOUBLE_EQ(st.mean_neighbors, 2.0 * double(pairs) / double(s.size()));
  EXPECT_EQ(st.solver, Solver::Envelope);
  EXPECT_EQ(st.ordering, Ordering::Identity);
  EXPECT_FALSE(st.orderings_compared);
  EXPECT_EQ(st.envelope_entries, st.identity.envelope);
  EXPECT_EQ(st.bandwidth, st.identity.bandwidth);
  EXPECT_EQ(st.factor_nonzeros, st.envelope_entries + s.size());  // the envelope and the diagonal
  EXPECT_EQ(st.dense_bytes, 4 * s.size() * s.size());
  EXPECT_EQ(st.iterations, 0u);
  EXPECT_FALSE(st.fell_back);
  // The residual is the mapping's own at the controls, relative to the largest displacement.
  std::vector<Vec3> at(s.size());
  m.apply(s, at);
  double worst = 0, gmax = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    worst = std::max(worst, (at[i] - d[i]).norm());
    gmax = std::max(gmax, (d[i] - s[i]).norm());
  }
  EXPECT_NEAR(st.residual_max, worst, 1e-13);
  EXPECT_DOUBLE_EQ(st.residual_relative, st.residual_max / gmax);
  EXPECT_LE(st.residual_relative, kResidualLimit);
}
