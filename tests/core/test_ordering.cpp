#include "csrbf/ordering.hpp"
#include "csrbf/errors.hpp"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

using namespace csrbf;

namespace {

std::vector<Vec3> grid_points(int nx, int ny, int nz, double h) {
  std::vector<Vec3> p;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) p.emplace_back(i * h, j * h, k * h);
  return p;
}

AdjacencyGraph graph_of(const std::vector<Vec3>& p, double r) {
  const NeighborIndex index(p, r);
  return AdjacencyGraph::from_index(index, p);
}

bool is_permutation_of_n(std::vector<std::uint32_t> o) {
  std::sort(o.begin(), o.end());
  for (std::size_t i = 0; i < o.size(); ++i)
    if (o[i] != i) return false;
  return true;
}

}  // namespace

TEST(Ordering, GraphIsSymmetricWithoutSelf) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> p(400);
  for (auto& x : p) x = Vec3(u(rng), u(rng), u(rng));
  const auto g = graph_of(p, 0.15);
  for (std::size_t i = 0; i < g.size(); ++i)
    for (auto j : g.neighbors_of(i)) {
      EXPECT_NE(j, i);
      const auto nj = g.neighbors_of(j);
      EXPECT_TRUE(std::binary_search(nj.begin(), nj.end(), std::uint32_t(i)));
      EXPECT_LT((p[i] - p[j]).norm(), 0.15);
    }
}

TEST(Ordering, BreadthFirstFollowsFigure3OnAChain) {
  // Points on a line, given shuffled: the paper's sort starts at input point 0 and walks outwards.
  std::vector<Vec3> p;
  const std::vector<int> xs{3, 0, 4, 1, 2};
  for (int x : xs) p.emplace_back(x, 0, 0);
  const auto g = graph_of(p, 1.5);
  const auto bf = breadth_first_order(g);
  // input 0 is x=3; its neighbours x=4 (input 2) and x=2 (input 4), ascending input index; then x=1, x=0.
  EXPECT_EQ(bf, (std::vector<std::uint32_t>{0, 2, 4, 3, 1}));
  EXPECT_EQ(reversed_order(bf), (std::vector<std::uint32_t>{1, 3, 4, 2, 0}));
  EXPECT_EQ(profile(g, bf).bandwidth, 2u);
  EXPECT_EQ(profile(g, identity_order(5)).bandwidth, 4u);
}

TEST(Ordering, RcmStartsAtAnEndOfAChain) {
  std::vector<Vec3> p;
  const std::vector<int> xs{3, 0, 4, 1, 2};
  for (int x : xs) p.emplace_back(x, 0, 0);
  const auto g = graph_of(p, 1.5);
  const auto rcm = reverse_cuthill_mckee_order(g);
  EXPECT_EQ(profile(g, rcm).bandwidth, 1u);
  EXPECT_EQ(profile(g, rcm).envelope, 4u);
}

TEST(Ordering, HandlesSeveralComponents) {
  std::vector<Vec3> p{Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(0.5, 0, 0), Vec3(10.5, 0, 0), Vec3(20, 0, 0)};
  const auto g = graph_of(p, 1.0);
  const auto bf = breadth_first_order(g);
  EXPECT_EQ(bf, (std::vector<std::uint32_t>{0, 2, 1, 3, 4}));
  EXPECT_EQ(profile(g, bf).envelope, 2u);
}

TEST(Ordering, EnvelopeNeverLargerThanShuffledInput) {
  for (unsigned seed = 1; seed <= 8; ++seed) {
    auto p = grid_points(12, 9, 5, 0.1);
    std::mt19937 rng(seed);
    std::shuffle(p.begin(), p.end(), rng);
    const auto g = graph_of(p, 0.25);
    const OrderingChoice c = choose_ordering(g, Ordering::Auto);
    ASSERT_TRUE(is_permutation_of_n(c.order));
    const Profile chosen = profile(g, c.order);
    EXPECT_LE(chosen.envelope, c.identity.envelope);
    EXPECT_LE(chosen.envelope, c.breadth_first.envelope);
    EXPECT_LE(chosen.envelope, c.reverse_breadth_first.envelope);
    EXPECT_LE(chosen.envelope, c.reverse_cuthill_mckee.envelope);
    // On a shuffled grid every sort beats the input order; RCM from a pseudo-peripheral node by far.
    EXPECT_LT(c.breadth_first.envelope, c.identity.envelope);
    EXPECT_LT(c.reverse_breadth_first.envelope, c.identity.envelope);
    EXPECT_LT(c.reverse_cuthill_mckee.envelope * 5, c.identity.envelope * 2);  // near a slab-wide band
    EXPECT_LT(c.reverse_cuthill_mckee.envelope, c.breadth_first.envelope);
    EXPECT_LT(c.reverse_cuthill_mckee.bandwidth * 3, c.identity.bandwidth);
    EXPECT_TRUE(is_permutation_of_n(reverse_cuthill_mckee_order(g)));
    for (Ordering o :
         {Ordering::Identity, Ordering::BreadthFirst, Ordering::ReverseBreadthFirst, Ordering::ReverseCuthillMcKee})
      EXPECT_TRUE(is_permutation_of_n(choose_ordering(g, o).order));
  }
}

TEST(Ordering, ProfileCountsTheEnvelope) {
  // Path 0-1-2 plus the edge 0-2 in a triangle: rows have first columns 0, 0, 0 -> envelope 0+1+2.
  std::vector<Vec3> p{Vec3(0, 0, 0), Vec3(0.5, 0, 0), Vec3(0.25, 0.4, 0)};
  const auto g = graph_of(p, 1.0);
  EXPECT_EQ(profile(g, identity_order(3)).envelope, 3u);
  EXPECT_EQ(profile(g, identity_order(3)).bandwidth, 2u);
}

namespace {

using Sparse = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

/// Entries of the Cholesky factor of the graph's matrix (diagonally dominant values, the graph's
/// pattern) eliminated in the given order, or with Eigen's AMD when order is empty.
long factor_entries(const AdjacencyGraph& g, const std::vector<std::uint32_t>& order) {
  const auto n = int(g.size());
  std::vector<int> position(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) position[order.empty() ? k : order[k]] = int(k);
  std::vector<Eigen::Triplet<double>> t;
  for (std::size_t i = 0; i < g.size(); ++i) {
    t.emplace_back(position[i], position[i], double(g.degree(i) + 1));
    for (std::uint32_t j : g.neighbors_of(i))
      if (position[j] > position[i]) t.emplace_back(position[j], position[i], -1.0 / double(g.degree(i) + 1));
  }
  Sparse a(n, n);
  a.setFromTriplets(t.begin(), t.end());
  if (order.empty()) {
    Eigen::SimplicialLLT<Sparse, Eigen::Lower, Eigen::AMDOrdering<int>> llt(a);
    EXPECT_EQ(llt.info(), Eigen::Success);
    return long(llt.matrixL().nestedExpression().nonZeros());
  }
  Eigen::SimplicialLLT<Sparse, Eigen::Lower, Eigen::NaturalOrdering<int>> llt(a);
  EXPECT_EQ(llt.info(), Eigen::Success);
  return long(llt.matrixL().nestedExpression().nonZeros());
}

}  // namespace

TEST(Ordering, NestedDissectionCutsTheFill) {
  // A surface (the unit sphere, ~25 neighbours each) and a volume (a cube grid): the nested
  // dissection order is a permutation, fills far less than the paper's banded orders, and about as
  // little as AMD.
  std::vector<Vec3> sphere(4000);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < sphere.size(); ++i) {
    const double y = 1.0 - 2.0 * (double(i) + 0.5) / double(sphere.size()), r = std::sqrt(1.0 - y * y);
    sphere[i] = Vec3(r * std::cos(golden * double(i)), y, r * std::sin(golden * double(i)));
  }
  struct Case {
    std::vector<Vec3> points;
    double radius;
  };
  const Case cases[] = {{sphere, std::sqrt(100.0 / double(sphere.size()))}, {grid_points(16, 16, 16, 1.0), 2.1}};
  for (const Case& c : cases) {
    const AdjacencyGraph g = graph_of(c.points, c.radius);
    const auto nd = nested_dissection_order(g, c.points, c.radius);
    ASSERT_EQ(nd.size(), c.points.size());
    ASSERT_TRUE(is_permutation_of_n(nd));
    const long fill_nd = factor_entries(g, nd), fill_amd = factor_entries(g, {});
    const long fill_rcm = factor_entries(g, reverse_cuthill_mckee_order(g));
    std::printf("[ info     ] %zu points: factor entries ND %ld, AMD %ld, RCM %ld\n", c.points.size(), fill_nd,
                fill_amd, fill_rcm);
    EXPECT_LT(double(fill_nd), 0.8 * double(fill_rcm));
    EXPECT_LT(double(fill_nd), 1.3 * double(fill_amd));
  }
  // Leaves of one point, and a set too narrow to cut (one block).
  const auto line = grid_points(50, 1, 1, 1.0);
  const AdjacencyGraph lg = graph_of(line, 1.5);
  EXPECT_TRUE(is_permutation_of_n(nested_dissection_order(lg, line, 1.5, 1)));
  const auto narrow = nested_dissection_order(lg, line, 30.0);
  EXPECT_EQ(narrow, identity_order(line.size()));
  EXPECT_THROW(nested_dissection_order(lg, sphere, 1.5), InvalidInput);
}

TEST(Ordering, Names) {
  for (Ordering o : {Ordering::Identity, Ordering::BreadthFirst, Ordering::ReverseBreadthFirst,
                     Ordering::ReverseCuthillMcKee, Ordering::Auto})
    EXPECT_EQ(parse_ordering(ordering_name(o)), o);
  EXPECT_FALSE(parse_ordering("sideways"));
}
