#include "csrbf/anim/scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

using csrbf::FitOptions;
using csrbf::Kernel;
using csrbf::SpaceMap;
using csrbf::Vec3;
using namespace csrbf::anim;

namespace {

/// A unit box surface sampled on a grid (n points a side), with no faces.
std::vector<Vec3> box_points(int n) {
  std::vector<Vec3> v;
  for (int z = 0; z <= n; ++z)
    for (int y = 0; y <= n; ++y)
      for (int x = 0; x <= n; ++x)
        if (x == 0 || y == 0 || z == 0 || x == n || y == n || z == n)
          v.emplace_back(double(x) / n, double(y) / n, double(z) / n);
  return v;
}

Object cloud_object(std::vector<Vec3> pts) {
  Object o;
  o.rest = std::move(pts);
  Part all;
  for (std::uint32_t i = 0; i < o.rest.size(); ++i) all.vertices.push_back(i);
  o.parts.push_back(all);
  o.finalize();
  return o;
}

SpaceMap bump(const Vec3& at, const Vec3& by, double radius) {
  const std::vector<Vec3> s{at}, d{at + by};
  return SpaceMap::fit(s, d, FitOptions{radius, Kernel::C2});
}

}  // namespace

TEST(Scene, CentreOfGravityIsTheAreaCentroid) {
  Object o;
  // A unit square made of one big and four small triangles' worth of vertices: the centroid is the
  // square's centre whatever the vertex density.
  o.rest = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0), Vec3(0.9, 0.9, 0), Vec3(0.95, 0.9, 0)};
  o.faces = {{0, 1, 2, 3}};
  o.finalize();
  EXPECT_LT((o.centre - Vec3(0.5, 0.5, 0)).norm(), 1e-15);
}

TEST(Scene, ObjectFollowsItsTrajectoryAndTurnsAboutItsCentre) {
  Scene scene;
  Object o = cloud_object(box_points(4));
  o.parts.clear();
  o.trajectory = PositionTrack({{0.0, Vec3(2, 0, 0)}, {1.0, Vec3(3, 1, 0)}, {2.0, Vec3(5, 0, 1)}});
  o.orientation = OrientationTrack({{0.0, Eigen::Quaterniond::Identity()},
                                    {2.0, Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()))}});
  scene.objects.push_back(o);
  Player player(scene);
  for (const auto& key : scene.objects[0].trajectory->keys()) {
    player.evaluate(key.time);
    const auto& p = player.positions(0);
    Vec3 mean = Vec3::Zero();
    for (const auto& x : p) mean += x;
    mean /= double(p.size());
    // The box's vertices are symmetric about its centre: their mean is the centre of gravity.
    EXPECT_LT((mean - key.position).norm(), 1e-12) << key.time;
  }
  // At t = 2 the box has turned 90 degrees about z through its centre.
  player.evaluate(2.0);
  const Vec3 c = scene.objects[0].centre;
  for (std::size_t i = 0; i < o.rest.size(); ++i) {
    const Vec3 r = o.rest[i] - c;
    EXPECT_LT((player.positions(0)[i] - (Vec3(-r.y(), r.x(), r.z()) + Vec3(5, 0, 1))).norm(), 1e-12);
  }
}

TEST(Scene, ComposeAppliesDeformationsInOrderWithTheirPhases) {
  Scene scene;
  Object o = cloud_object(box_points(6));
  const SpaceMap a = bump(Vec3(0.5, 0.5, 1.0), Vec3(0, 0, 0.2), 0.5),
                 b = bump(Vec3(0.5, 0.5, 1.1), Vec3(0.1, 0, 0), 0.3);
  o.parts[0].deformations.push_back(
      {"a", a, std::nullopt, {}, PhaseTrack({{0.0, 0.0}, {1.0, 1.0}}, PhaseEasing::Linear), {}});
  o.parts[0].deformations.push_back(
      {"b", b, std::nullopt, {}, PhaseTrack({{0.0, 1.0}, {1.0, 0.5}}, PhaseEasing::Linear), {}});
  o.parts[0].combine = Combine::Compose;
  scene.objects.push_back(o);
  Player player(scene);
  player.evaluate(0.5);  // phases 0.5 and 0.75
  for (std::size_t i = 0; i < o.rest.size(); ++i) {
    const Vec3 x1 = a.map(o.rest[i], 0.5);
    const Vec3 x2 = b.map(x1, 0.75);
    EXPECT_LT((player.deformed(0)[i] - x2).norm(), 1e-13) << i;
    // No trajectory or orientation: world = model.
    EXPECT_LT((player.positions(0)[i] - x2).norm(), 1e-13);
  }
  // Sum: each displacement at the rest shape.
  scene.objects[0].parts[0].combine = Combine::Sum;
  Player summed(scene);
  summed.evaluate(0.5);
  for (std::size_t i = 0; i < o.rest.size(); ++i) {
    const Vec3 x = o.rest[i] + 0.5 * a.displacement(o.rest[i]) + 0.75 * b.displacement(o.rest[i]);
    EXPECT_LT((summed.deformed(0)[i] - x).norm(), 1e-13) << i;
  }
}

TEST(Scene, PartsDeformOnlyTheirVertices) {
  Scene scene;
  Object o = cloud_object(box_points(6));
  Part left;
  for (std::uint32_t i = 0; i < o.rest.size(); ++i)
    if (o.rest[i].x() < 0.5) left.vertices.push_back(i);
  // Reaches every vertex: a wide support about the centre.
  left.deformations.push_back(
      {"up", bump(Vec3(0.5, 0.5, 0.5), Vec3(0, 0.3, 0), 3.0), std::nullopt, {}, PhaseTrack(), {}});
  o.parts = {left};
  scene.objects.push_back(o);
  Player player(scene);
  player.evaluate(0.0);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < o.rest.size(); ++i) {
    const bool in_left = o.rest[i].x() < 0.5;
    if (!in_left) {
      EXPECT_EQ(player.deformed(0)[i], o.rest[i]);
    }
    moved += player.deformed(0)[i] != o.rest[i];
  }
  EXPECT_EQ(moved, left.vertices.size());
}

TEST(Scene, ContactDentsTheWallTheBallPresses) {
  // The controls: 8 pinned corners, and 5 per touched wall, the middle one pushed by the penetration.
  std::vector<Vec3> s, d;
  contact_controls(Vec3::Zero(), Vec3::Ones(), Vec3(0.5, 0.5, 0.5), 0.2, 0.6, s, d);
  EXPECT_EQ(s.size(), 8u);  // not touching
  contact_controls(Vec3::Zero(), Vec3::Ones(), Vec3(0.5, 0.15, 0.5), 0.2, 0.6, s, d);
  ASSERT_EQ(s.size(), 13u);
  EXPECT_LT((s[8] - Vec3(0.5, 0, 0.5)).norm(), 1e-15);
  EXPECT_LT((d[8] - Vec3(0.5, -0.05, 0.5)).norm(), 1e-15);
  for (int k = 9; k < 13; ++k) EXPECT_NEAR(d[k].y(), -0.03, 1e-15);
  // Near a corner the side controls are clamped to the box and never duplicate a source.
  contact_controls(Vec3::Zero(), Vec3::Ones(), Vec3(0.05, 0.05, 0.05), 0.2, 0.6, s, d);
  for (std::size_t i = 0; i < s.size(); ++i)
    for (std::size_t j = 0; j < i; ++j) EXPECT_NE(s[i], s[j]);

  Scene scene;
  Object box = cloud_object(box_points(8));
  Deformation dent;
  dent.contact = Contact{1, 0.2, 0.6};
  dent.options = FitOptions{0.4, Kernel::C2};
  box.parts[0].deformations.push_back(dent);
  Object ball = cloud_object({Vec3(0, 0, 0)});
  ball.parts.clear();
  ball.trajectory = PositionTrack({{0.0, Vec3(0.5, 0.5, 0.5)}, {1.0, Vec3(0.5, 0.15, 0.5)}});
  scene.objects = {box, ball};
  Player player(scene);
  player.evaluate(0.0);  // the ball in the middle: the box at rest
  for (std::size_t i = 0; i < box.rest.size(); ++i) EXPECT_EQ(player.deformed(0)[i], box.rest[i]);
  player.evaluate(1.0);  // on the floor: the floor's middle goes down by the penetration
  const auto& p = player.deformed(0);
  for (std::size_t i = 0; i < box.rest.size(); ++i) {
    const Vec3& r = box.rest[i];
    if (r == Vec3(0.5, 0, 0.5)) {
      EXPECT_NEAR(p[i].y(), -0.05, 1e-9);
    }
    if (r.y() == 1.0) {
      EXPECT_EQ(p[i], r);  // the ceiling is farther than R from every control
    }
  }
}

TEST(Scene, FrameCount) {
  Scene s;
  s.fps = 25;
  EXPECT_EQ(s.frame_count(0, 1), 26u);
  EXPECT_EQ(s.frame_count(0, 0.2), 6u);
  EXPECT_EQ(s.frame_count(1, 1), 1u);
  EXPECT_EQ(s.frame_count(1, 0.5), 0u);
}

TEST(Scene, AFrameThatOverflowsIsAnErrorNotNaN) {
  // Keys at +-1.7e308 are finite, but the trajectory between them overflows: evaluate refuses the
  // frame, naming the object and the time, instead of handing NaN to the renderer or a writer.
  Scene scene;
  Object o = cloud_object(box_points(2));
  o.name = "far";
  o.trajectory = PositionTrack({{0.0, Vec3(1.7e308, 0, 0)}, {1.0, Vec3(-1.7e308, 0, 0)}, {2.0, Vec3(1.7e308, 0, 0)}});
  scene.objects.push_back(std::move(o));
  scene.duration = 2;
  Player player(scene);
  player.evaluate(0.0);  // at a key: finite
  EXPECT_TRUE(player.positions(0)[0].allFinite());
  try {
    player.evaluate(0.5);
    FAIL() << "a non-finite frame was accepted";
  } catch (const csrbf::InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("objects[0] ('far') at t = 0.5 s"), std::string::npos) << e.what();
  }
}
