#include "csrbf/ordering.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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
    for (Ordering o : {Ordering::Identity, Ordering::BreadthFirst, Ordering::ReverseBreadthFirst, Ordering::ReverseCuthillMcKee})
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

TEST(Ordering, Names) {
  for (Ordering o : {Ordering::Identity, Ordering::BreadthFirst, Ordering::ReverseBreadthFirst,
                     Ordering::ReverseCuthillMcKee, Ordering::Auto})
    EXPECT_EQ(parse_ordering(ordering_name(o)), o);
  EXPECT_FALSE(parse_ordering("sideways"));
}
