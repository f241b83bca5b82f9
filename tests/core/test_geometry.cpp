// The closest point of a triangle (csrbf/geometry.hpp) in each of its seven Voronoi regions, and
// against the obvious slow answer (the projection onto the plane where it falls inside, else the
// nearest of the three edges) on seeded random triangles and points.
#include "csrbf/geometry.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace csrbf;

namespace {

Vec3 closest_on_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return a + t * (b - a);
}

/// The slow answer: the plane's foot where its barycentric coordinates are all >= 0, else the
/// nearest point of the edges.
Vec3 brute_force(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a);
  const Vec3 foot = p - n * (p - a).dot(n) / n.squaredNorm();
  const double area = n.squaredNorm();
  const double u = (c - b).cross(foot - b).dot(n) / area, v = (a - c).cross(foot - c).dot(n) / area;
  if (u >= 0 && v >= 0 && 1 - u - v >= 0) return foot;
  Vec3 best = closest_on_segment(p, a, b);
  for (const Vec3& q : {closest_on_segment(p, b, c), closest_on_segment(p, c, a)})
    if ((q - p).squaredNorm() < (best - p).squaredNorm()) best = q;
  return best;
}

}  // namespace

TEST(Geometry, EachVoronoiRegionOfTheTriangle) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const auto closest = [&](double x, double y, double z) { return closest_point_on_triangle(Vec3(x, y, z), a, b, c); };
  EXPECT_EQ(closest(-1, -1, 0.5), a);
  EXPECT_EQ(closest(2, -0.5, 1), b);
  EXPECT_EQ(closest(-0.5, 2, -1), c);
  EXPECT_EQ(closest(0.5, -1, 3), Vec3(0.5, 0, 0));    // edge ab
  EXPECT_EQ(closest(-1, 0.25, 0), Vec3(0, 0.25, 0));  // edge ac
  EXPECT_EQ(closest(1, 1, 0), Vec3(0.5, 0.5, 0));     // edge bc
  EXPECT_EQ(closest(0.25, 0.5, 5), Vec3(0.25, 0.5, 0));
  EXPECT_EQ(closest(0.25, 0.5, -5), Vec3(0.25, 0.5, 0));
  // A point of the triangle is its own closest point.
  EXPECT_EQ(closest(0.5, 0.25, 0), Vec3(0.5, 0.25, 0));
  EXPECT_EQ(closest(1, 0, 0), b);
}

TEST(Geometry, AgreesWithTheSlowAnswerOnRandomTriangles) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto random_point = [&] { return Vec3(u(rng), u(rng), u(rng)); };
  for (int t = 0; t < 200; ++t) {
    const Vec3 a = random_point(), b = random_point(), c = random_point();
    for (int i = 0; i < 50; ++i) {
      const Vec3 p = 2 * random_point();
      const Vec3 q = closest_point_on_triangle(p, a, b, c);
      const Vec3 want = brute_force(p, a, b, c);
      ASSERT_LT((q - want).norm(), 1e-9) << "triangle " << t << " point " << i;
    }
  }
}
