#include "csrbf/anim/tracks.hpp"

#include <gtest/gtest.h>
#include <vtkKochanekSpline.h>
#include <vtkNew.h>

#include <cmath>
#include <numbers>
#include <random>

using csrbf::InvalidInput;
using csrbf::Vec3;
using namespace csrbf::anim;

namespace {

std::vector<PositionKey> wavy_keys(bool uneven) {
  std::vector<PositionKey> k;
  double t = 0;
  for (int i = 0; i < 7; ++i) {
    k.push_back({t, Vec3(std::cos(i * 0.9), std::sin(i * 1.3) + 0.2 * i, 0.5 * i - 0.1 * i * i)});
    t += uneven ? 0.5 + 0.35 * (i % 3) : 1.0;
  }
  return k;
}

}  // namespace

TEST(PositionTrack, PassesThroughItsKeys) {
  for (bool uneven : {false, true})
    for (TrackEnds ends : {TrackEnds::Natural, TrackEnds::Still}) {
      auto keys = wavy_keys(uneven);
      for (std::size_t i = 0; i < keys.size(); ++i) {
        keys[i].tension = 0.3 * std::sin(double(i));
        keys[i].continuity = 0.4 * std::cos(double(i));
        keys[i].bias = -0.2 + 0.1 * double(i % 4);
      }
      const PositionTrack track(keys, ends);
      for (const auto& k : keys) EXPECT_LT((track.position(k.time) - k.position).norm(), 1e-12) << k.time;
      // Holds still outside the keys.
      EXPECT_EQ(track.position(-5.0), keys.front().position);
      EXPECT_EQ(track.position(keys.back().time + 3), keys.back().position);
    }
}

TEST(PositionTrack, ZeroTensionContinuityBiasIsCatmullRom) {
  // Uniform spacing: Catmull-Rom's tangent at key i is (P[i+1] - P[i-1]) / 2 per unit of time, and
  // each segment is the cubic Hermite between its keys.
  const auto keys = wavy_keys(false);
  const PositionTrack track(keys);
  for (std::size_t i = 1; i + 2 < keys.size(); ++i) {
    const Vec3 p0 = keys[i - 1].position, p1 = keys[i].position, p2 = keys[i + 1].position, p3 = keys[i + 2].position;
    for (double s : {0.1, 0.25, 0.5, 0.8}) {
      // The closed form of the uniform Catmull-Rom segment.
      const Vec3 expect = 0.5 * ((2 * p1) + (-p0 + p2) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s * s +
                                 (-p0 + 3 * p1 - 3 * p2 + p3) * s * s * s);
      EXPECT_LT((track.position(keys[i].time + s) - expect).norm(), 1e-12) << i << " " << s;
    }
    EXPECT_LT((track.velocity(keys[i].time) - (p2 - p0) / 2).norm(), 1e-12);
  }
}

TEST(PositionTrack, VelocityIsContinuousAtKeysWhenContinuityIsZero) {
  auto keys = wavy_keys(true);  // unequal spacing: the tangent adjustment is what keeps C1
  for (std::size_t i = 0; i < keys.size(); ++i) {
    keys[i].tension = 0.5 * std::sin(3.0 * double(i));
    keys[i].bias = 0.3 * std::cos(2.0 * double(i));
  }
  const PositionTrack track(keys);
  const double h = 1e-7;
  for (std::size_t i = 1; i + 1 < keys.size(); ++i) {
    const Vec3 before = track.velocity(keys[i].time - h), after = track.velocity(keys[i].time + h);
    EXPECT_LT((before - after).norm(), 1e-5 * (1 + before.norm())) << "key " << i;
    // And the velocity is the derivative of the position.
    const Vec3 fd = (track.position(keys[i].time + 0.5 + h) - track.position(keys[i].time + 0.5 - h)) / (2 * h);
    EXPECT_LT((fd - track.velocity(keys[i].time + 0.5)).norm(), 1e-5);
  }
  // continuity != 0 breaks the velocity at that key.
  keys[3].continuity = -0.8;
  const PositionTrack corner(keys);
  const double t = keys[3].time;
  EXPECT_GT((corner.velocity(t - h) - corner.velocity(t + h)).norm(), 0.1);
}

TEST(PositionTrack, TensionOneStopsAtTheKey) {
  auto keys = wavy_keys(false);
  keys[2].tension = 1.0;
  const PositionTrack track(keys);
  EXPECT_LT(track.velocity(keys[2].time - 1e-9).norm(), 1e-6);
  EXPECT_LT(track.velocity(keys[2].time + 1e-9).norm(), 1e-6);
}

TEST(PositionTrack, EndConditions) {
  const auto keys = wavy_keys(true);
  const PositionTrack still(keys, TrackEnds::Still);
  EXPECT_LT(still.velocity(keys.front().time).norm(), 1e-12);
  EXPECT_LT(still.velocity(keys.back().time).norm(), 1e-12);
  // Natural: zero second derivative at both ends.
  const PositionTrack natural(keys, TrackEnds::Natural);
  const double h = 1e-4;
  for (double t : {keys.front().time + h, keys.back().time - h}) {
    const Vec3 acc = (natural.velocity(t + h / 2) - natural.velocity(t - h / 2)) / h;
    EXPECT_LT(acc.norm(), 1e-2) << t;
  }
  // Two keys, natural ends: the straight line at constant speed.
  const PositionTrack line({{1.0, Vec3(0, 0, 0)}, {3.0, Vec3(2, 4, 6)}});
  EXPECT_LT((line.position(1.5) - Vec3(0.5, 1, 1.5)).norm(), 1e-12);
  EXPECT_LT((line.velocity(2.7) - Vec3(1, 2, 3)).norm(), 1e-12);
}

TEST(PositionTrack, MatchesVtkKochanekSpline) {
  // vtkKochanekSpline has one tension, continuity and bias for all keys, fits each coordinate on
  // its own, adjusts tangents for unequal spacing as we do, and offers both our end conditions:
  // constraint 2 with value 0 (natural) and 1 with value 0 (still).
  for (bool uneven : {false, true})
    for (const auto& [t, c, b] : std::vector<std::array<double, 3>>{
             {0, 0, 0}, {0.5, 0, 0}, {0, 0.5, 0}, {0, 0, 0.5}, {-0.3, -0.4, 0.6}, {0.2, 0.7, -0.5}})
      for (TrackEnds ends : {TrackEnds::Natural, TrackEnds::Still}) {
        auto keys = wavy_keys(uneven);
        for (auto& k : keys) k.tension = t, k.continuity = c, k.bias = b;
        const PositionTrack track(keys, ends);
        vtkNew<vtkKochanekSpline> spline[3];
        for (int a = 0; a < 3; ++a) {
          spline[a]->SetDefaultTension(t);
          spline[a]->SetDefaultContinuity(c);
          spline[a]->SetDefaultBias(b);
          const int constraint = ends == TrackEnds::Natural ? 2 : 1;
          spline[a]->SetLeftConstraint(constraint);
          spline[a]->SetRightConstraint(constraint);
          spline[a]->SetLeftValue(0.0);
          spline[a]->SetRightValue(0.0);
          for (const auto& k : keys) spline[a]->AddPoint(k.time, k.position[a]);
        }
        double worst = 0;
        const double t0 = keys.front().time, t1 = keys.back().time;
        for (int s = 0; s <= 400; ++s) {
          const double tt = t0 + (t1 - t0) * s / 400.0;
          const Vec3 v(spline[0]->Evaluate(tt), spline[1]->Evaluate(tt), spline[2]->Evaluate(tt));
          worst = std::max(worst, (v - track.position(tt)).norm());
        }
        EXPECT_LT(worst, 1e-12) << "t=" << t << " c=" << c << " b=" << b << " uneven=" << uneven
                                << " natural=" << (ends == TrackEnds::Natural);
      }
}

TEST(PositionTrack, RejectsBadKeys) {
  EXPECT_THROW(PositionTrack(std::vector<PositionKey>{}), InvalidInput);
  EXPECT_THROW(PositionTrack({{0.0, Vec3::Zero()}, {0.0, Vec3::Ones()}}), InvalidInput);
  EXPECT_THROW(PositionTrack({{1.0, Vec3::Zero()}, {0.5, Vec3::Ones()}}), InvalidInput);
  EXPECT_THROW(PositionTrack({{0.0, Vec3(NAN, 0, 0)}}), InvalidInput);
  try {
    PositionTrack({{0.0, Vec3::Zero()}, {2.0, Vec3::Ones()}, {1.0, Vec3::Ones()}});
    FAIL();
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("key 2"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------------

namespace {

Eigen::Quaterniond axis_angle(double degrees, const Vec3& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * std::numbers::pi / 180, axis.normalized()));
}

double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return 2 * std::acos(std::min(1.0, std::abs(a.dot(b))));
}

std::vector<OrientationKey> turning_keys() {
  return {{0.0, axis_angle(0, Vec3::UnitY())},
          {1.0, axis_angle(80, Vec3(0, 1, 0.3))},
          {1.5, axis_angle(150, Vec3(0.2, 1, 0))},
          {3.0, axis_angle(40, Vec3(1, 0.5, 0.2))},
          {4.0, axis_angle(-60, Vec3(0, 0, 1))}};
}

}  // namespace

TEST(OrientationTrack, HitsKeysStaysUnit) {
  for (Rotation mode : {Rotation::Slerp, Rotation::Squad}) {
    const auto keys = turning_keys();
    const OrientationTrack track(keys, mode);
    for (const auto& k : keys) EXPECT_LT(angle_between(track.rotation(k.time), k.rotation), 1e-9);
    for (double t = -1; t < 5; t += 0.01) EXPECT_NEAR(track.rotation(t).norm(), 1.0, 1e-12) << t;
  }
}

TEST(OrientationTrack, TakesTheShortWay) {
  // 350 degrees about z is -10 degrees: the track must turn 10 degrees, not 350, whichever sign
  // the key quaternion was given with.
  for (double sign : {1.0, -1.0}) {
    Eigen::Quaterniond end = axis_angle(350, Vec3::UnitZ());
    end.coeffs() *= sign;
    for (Rotation mode : {Rotation::Slerp, Rotation::Squad}) {
      const OrientationTrack track({{0.0, Eigen::Quaterniond::Identity()}, {1.0, end}}, mode);
      double travelled = 0;
      Eigen::Quaterniond prev = track.rotation(0);
      for (int s = 1; s <= 100; ++s) {
        const Eigen::Quaterniond q = track.rotation(s / 100.0);
        travelled += angle_between(prev, q);
        prev = q;
      }
      EXPECT_NEAR(travelled, 10 * std::numbers::pi / 180, 1e-6);
    }
  }
}

TEST(OrientationTrack, SlerpTurnsAtConstantSpeed) {
  const Eigen::Quaterniond a = axis_angle(10, Vec3(1, 2, 3)), b = axis_angle(120, Vec3(-1, 0.5, 2));
  const OrientationTrack track({{0.0, a}, {2.0, b}}, Rotation::Slerp);
  const double total = angle_between(a, b);
  for (double t : {0.3, 0.9, 1.6}) EXPECT_NEAR(angle_between(a, track.rotation(t)), total * t / 2, 1e-9);
  // slerp against Eigen's on the same pair (Eigen also takes the short way; these are within 180).
  for (double h : {0.2, 0.5, 0.7}) EXPECT_LT(angle_between(slerp(a, b, h), a.slerp(h, b)), 1e-12);
}

TEST(OrientationTrack, SquadIsSmootherThanSlerpAcrossKeys) {
  // Angular velocity just before and after an interior key: slerp jumps there, squad does not
  // (with equally spaced keys squad is C1).
  std::vector<OrientationKey> keys;
  for (int i = 0; i < 5; ++i) keys.push_back({double(i), axis_angle(30.0 * i + 10.0 * (i % 2), Vec3(0.3 * i, 1, 0.1))});
  const OrientationTrack slerp_track(keys, Rotation::Slerp), squad_track(keys, Rotation::Squad);
  const double h = 1e-5;
  const auto omega = [&](const OrientationTrack& tr, double t) {  // body angular velocity vector
    const Eigen::Quaterniond d = tr.rotation(t).conjugate() * tr.rotation(t + h);
    return Vec3(d.vec() * (2 / h) * (d.w() < 0 ? -1 : 1));
  };
  for (int i = 1; i < 4; ++i) {
    const double t = double(i);
    const double jump_slerp = (omega(slerp_track, t - 2 * h) - omega(slerp_track, t + h)).norm();
    const double jump_squad = (omega(squad_track, t - 2 * h) - omega(squad_track, t + h)).norm();
    EXPECT_GT(jump_slerp, 0.05) << i;
    EXPECT_LT(jump_squad, 1e-3) << i;
  }
}

// ---------------------------------------------------------------------------------------------------

TEST(PhaseTrack, KeysEasingAndHolds) {
  const std::vector<PhaseKey> keys{{0.0, 0.0}, {0.5, 1.0}, {1.0, 0.0}, {2.0, 0.25}};
  const PhaseTrack smooth(keys, PhaseEasing::Smooth), linear(keys, PhaseEasing::Linear);
  for (const auto& k : keys) {
    EXPECT_DOUBLE_EQ(smooth.phase(k.time), k.phase);
    EXPECT_DOUBLE_EQ(linear.phase(k.time), k.phase);
  }
  EXPECT_DOUBLE_EQ(linear.phase(0.125), 0.25);
  EXPECT_DOUBLE_EQ(smooth.phase(0.125), 0.15625);  // 3 (1/4)^2 - 2 (1/4)^3
  EXPECT_DOUBLE_EQ(smooth.phase(0.25), 0.5);
  EXPECT_DOUBLE_EQ(smooth.phase(-1.0), 0.0);
  EXPECT_DOUBLE_EQ(smooth.phase(9.0), 0.25);
  // Smooth never leaves the range of its segment's keys, and is at rest at a key.
  for (double t = 0; t < 2; t += 0.001) {
    EXPECT_GE(smooth.phase(t), -1e-15);
    EXPECT_LE(smooth.phase(t), 1.0 + 1e-15);
  }
  EXPECT_NEAR((smooth.phase(0.5 + 1e-6) - smooth.phase(0.5)) / 1e-6, 0.0, 1e-4);
  EXPECT_THROW(PhaseTrack({{0.0, 0.0}, {0.0, 1.0}}), InvalidInput);
  EXPECT_THROW(PhaseTrack({{0.0, INFINITY}}), InvalidInput);
}
