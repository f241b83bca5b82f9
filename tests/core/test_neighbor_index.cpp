#include "csrbf/errors.hpp"
#include "csrbf/neighbor_index.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>

using csrbf::InvalidInput;
using csrbf::NeighborIndex;
using csrbf::Vec3;

namespace {

std::vector<Vec3> random_points(std::size_t n, unsigned seed, double scale = 1.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-scale, scale);
  std::vector<Vec3> p(n);
  for (auto& x : p) x = Vec3(u(rng), u(rng), u(rng));
  return p;
}

std::vector<std::size_t> brute_force(const std::vector<Vec3>& pts, const Vec3& q, double r) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < pts.size(); ++i)
    if ((pts[i] - q).squaredNorm() < r * r) out.push_back(i);
  return out;
}

}  // namespace

TEST(NeighborIndex, MatchesBruteForceOnRandomSets) {
  for (unsigned seed : {1u, 2u, 3u}) {
    for (double r : {0.05, 0.2, 0.7, 3.0}) {
      const auto pts = random_points(800, seed);
      const NeighborIndex index(pts, r);
      const auto queries = random_points(300, seed + 100, 1.3);
      for (const auto& q : queries) ASSERT_EQ(index.query(q), brute_force(pts, q, r)) << "seed " << seed << " r " << r;
      for (std::size_t i = 0; i < pts.size(); i += 7) ASSERT_EQ(index.query(pts[i]), brute_force(pts, pts[i], r));
    }
  }
}

// The points sorted by cell (z, then y, then x), by index within a cell: by a counting sort where
// the box holds few cells for its points (r = 0.2: 1e3 cells for 800 points), by a comparison sort
// where it holds many (r = 0.05: 6.4e4), the same order either way.
TEST(NeighborIndex, PointsAreSortedByCellThenIndex) {
  const auto pts = random_points(800, 5);
  for (double r : {0.05, 0.2, 3.0}) {
    const NeighborIndex index(pts, r);
    Vec3 lo = pts[0];
    for (const Vec3& p : pts) lo = lo.cwiseMin(p);
    std::vector<std::array<long, 4>> expected;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Vec3 c = ((pts[i] - lo) / r).array().floor();
      expected.push_back({long(c.z()), long(c.y()), long(c.x()), long(i)});
    }
    std::sort(expected.begin(), expected.end());
    const auto ids = index.sorted_ids();
    ASSERT_EQ(ids.size(), pts.size());
    for (std::size_t k = 0; k < pts.size(); ++k) {
      ASSERT_EQ(long(ids[k]), expected[k][3]) << "r " << r << " slot " << k;
      ASSERT_EQ(index.point(k), pts[ids[k]]);
    }
  }
}

TEST(NeighborIndex, FloatQueriesMatchBruteForce) {
  const auto pts = random_points(500, 9);
  const NeighborIndex index(pts, 0.3);
  std::mt19937 rng(10);
  std::uniform_real_distribution<float> u(-1.2f, 1.2f);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3f qf(u(rng), u(rng), u(rng));
    const Vec3 q = qf.cast<double>();
    EXPECT_EQ(index.query(q), brute_force(pts, q, 0.3));
  }
}

TEST(NeighborIndex, DistancesAndSlotsAreConsistent) {
  const auto pts = random_points(300, 4);
  const NeighborIndex index(pts, 0.4);
  const Vec3 q(0.1, -0.2, 0.3);
  index.for_each_slot_within(q, [&](std::size_t slot, double d2) {
    const std::size_t i = index.original_index(slot);
    EXPECT_EQ(index.point(slot), pts[i]);
    EXPECT_DOUBLE_EQ(d2, (pts[i] - q).squaredNorm());
  });
}

TEST(NeighborIndex, EmptyAndFarAway) {
  const NeighborIndex empty(std::vector<Vec3>{}, 1.0);
  EXPECT_TRUE(empty.query(Vec3::Zero()).empty());
  const auto pts = random_points(100, 5);
  const NeighborIndex index(pts, 0.5);
  EXPECT_TRUE(index.query(Vec3(1e12, 0, 0)).empty());
  EXPECT_TRUE(index.query(Vec3(-1e300, 1e300, 0)).empty());
  EXPECT_TRUE(index.query(Vec3(std::nan(""), 0, 0)).empty());
}

TEST(NeighborIndex, ExactlyAtRadiusIsOutside) {
  const std::vector<Vec3> pts{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  const NeighborIndex index(pts, 1.0);
  EXPECT_EQ(index.query(Vec3(0, 0, 0)), std::vector<std::size_t>{0});
  EXPECT_EQ(index.query(Vec3(0.5, 0, 0)), (std::vector<std::size_t>{0, 1}));
}

TEST(NeighborIndex, RejectsBadInput) {
  const auto pts = random_points(10, 6);
  EXPECT_THROW(NeighborIndex(pts, 0.0), InvalidInput);
  EXPECT_THROW(NeighborIndex(pts, -1.0), InvalidInput);
  EXPECT_THROW(NeighborIndex(pts, std::nan("")), InvalidInput);
  EXPECT_THROW(NeighborIndex(pts, INFINITY), InvalidInput);
  EXPECT_THROW(NeighborIndex(pts, 1e-12), InvalidInput);
  auto bad = pts;
  bad[3].y() = INFINITY;
  EXPECT_THROW(NeighborIndex(bad, 0.5), InvalidInput);
}
