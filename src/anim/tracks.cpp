#include "csrbf/anim/tracks.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

namespace csrbf::anim {
namespace {

[[noreturn]] void fail(const std::string& what, std::size_t key, const std::string& detail) {
  std::ostringstream m;
  m << what << " key " << key << ": " << detail;
  throw InvalidInput(m.str());
}

template <class Key>
void check_times(const std::vector<Key>& keys, const char* what) {
  if (keys.empty()) throw InvalidInput(std::string(what) + ": at least one key is needed");
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (!std::isfinite(keys[i].time)) fail(what, i, "time is not finite (" + std::to_string(keys[i].time) + ")");
    if (i > 0 && !(keys[i].time > keys[i - 1].time)) {
      std::ostringstream m;
      m << "time " << keys[i].time << " is not after the previous key's " << keys[i - 1].time;
      fail(what, i, m.str());
    }
  }
}

/// Index i of the segment [t_i, t_{i+1}) holding t, for keys sorted by time (size >= 2).
template <class Key>
std::size_t find_segment(const std::vector<Key>& keys, double t) {
  const auto it = std::upper_bound(keys.begin(), keys.end(), t, [](double v, const Key& k) { return v < k.time; });
  const auto i = static_cast<std::size_t>(it - keys.begin());
  return std::clamp<std::size_t>(i == 0 ? 0 : i - 1, 0, keys.size() - 2);
}

// Hermite basis on s in [0, 1] and its derivative.
struct Hermite {
  double h00, h10, h01, h11;
};
Hermite hermite(double s) {
  const double s2 = s * s, s3 = s2 * s;
  return {2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2};
}
Hermite hermite_derivative(double s) {
  const double s2 = s * s;
  return {6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s};
}

Eigen::Quaterniond quat_log(const Eigen::Quaterniond& q) {  // unit q -> (0, axis * half angle)
  const Vec3 v = q.vec();
  const double s = v.norm();
  const double angle = std::atan2(s, q.w());
  const Vec3 r = s > 1e-15 ? Vec3(v * (angle / s)) : v;
  return Eigen::Quaterniond(0.0, r.x(), r.y(), r.z());
}
Eigen::Quaterniond quat_exp(const Eigen::Quaterniond& q) {  // pure q -> unit
  const Vec3 v = q.vec();
  const double a = v.norm();
  const Vec3 r = a > 1e-15 ? Vec3(v * (std::sin(a) / a)) : v;
  return Eigen::Quaterniond(std::cos(a), r.x(), r.y(), r.z());
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// Kochanek & Bartels, "Interpolating splines with local tension, continuity, and bias control",
// SIGGRAPH 1984: the tangents of eq. 8-9 with the adjustment of eq. 11-12 for unequal key spacing.

PositionTrack::PositionTrack(std::vector<PositionKey> keys, TrackEnds ends) : keys_(std::move(keys)), ends_(ends) {
  check_times(keys_, "position track");
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const auto& k = keys_[i];
    if (!k.position.allFinite()) fail("position track", i, "position is not finite");
    for (const double v : {k.tension, k.continuity, k.bias})
      if (!std::isfinite(v)) fail("position track", i, "tension, continuity and bias must be finite");
  }
  const std::size_t n = keys_.size();
  out_.assign(n, Vec3::Zero());
  in_.assign(n, Vec3::Zero());
  if (n < 2) return;
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const auto& k = keys_[i];
    const Vec3 cs = k.position - keys_[i - 1].position, cd = keys_[i + 1].position - k.position;
    const double t = 1 - k.tension, c = k.continuity, b = k.bias;
    Vec3 in = cs * (t * (1 - c) * (1 + b) / 2) + cd * (t * (1 + c) * (1 - b) / 2);
    Vec3 out = cs * (t * (1 + c) * (1 + b) / 2) + cd * (t * (1 - c) * (1 - b) / 2);
    const double n0 = k.time - keys_[i - 1].time, n1 = keys_[i + 1].time - k.time;
    in *= 2 * n0 / (n0 + n1);
    out *= 2 * n1 / (n0 + n1);
    in_[i] = in;
    out_[i] = out;
  }
  const Vec3 first = keys_[1].position - keys_[0].position, last = keys_[n - 1].position - keys_[n - 2].position;
  if (ends_ == TrackEnds::Natural) {
    if (n == 2) {
      // Both ends natural on one segment: the straight line at constant speed.
      out_[0] = first;
      in_[1] = first;
    } else {
      // p''(0) = 6 (P1 - P0) - 4 m0 - 2 m1 = 0, and the same at the far end.
      out_[0] = (3 * first - in_[1]) / 2;
      in_[n - 1] = (3 * last - out_[n - 2]) / 2;
    }
  }
}

std::size_t PositionTrack::segment(double t) const { return find_segment(keys_, t); }

Vec3 PositionTrack::position(double t) const {
  if (keys_.size() == 1 || t <= keys_.front().time) return keys_.front().position;
  if (t >= keys_.back().time) return keys_.back().position;
  const std::size_t i = segment(t);
  const double len = keys_[i + 1].time - keys_[i].time;
  const Hermite h = hermite((t - keys_[i].time) / len);
  return h.h00 * keys_[i].position + h.h10 * out_[i] + h.h01 * keys_[i + 1].position + h.h11 * in_[i + 1];
}

Vec3 PositionTrack::velocity(double t) const {
  if (keys_.size() == 1 || t < keys_.front().time || t > keys_.back().time) return Vec3::Zero();
  const std::size_t i = segment(t);
  const double len = keys_[i + 1].time - keys_[i].time;
  const Hermite h = hermite_derivative((t - keys_[i].time) / len);
  return (h.h00 * keys_[i].position + h.h10 * out_[i] + h.h01 * keys_[i + 1].position + h.h11 * in_[i + 1]) / len;
}

// ---------------------------------------------------------------------------------------------------
// Shoemake, "Animating rotation with quaternion curves" (SIGGRAPH 1985) and "Quaternion calculus
// and fast animation" (SIGGRAPH course notes 1987): slerp and squad.

Eigen::Quaterniond slerp(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double t) {
  const double d = std::clamp(a.dot(b), -1.0, 1.0);
  double wa, wb;
  if (std::abs(d) > 1.0 - 1e-12) {  // (nearly) the same rotation: linear, then normalised
    wa = 1 - t;
    wb = t;
  } else {
    const double omega = std::acos(d), s = std::sin(omega);
    wa = std::sin((1 - t) * omega) / s;
    wb = std::sin(t * omega) / s;
  }
  Eigen::Quaterniond q(wa * a.coeffs() + wb * b.coeffs());
  q.normalize();
  return q;
}

OrientationTrack::OrientationTrack(std::vector<OrientationKey> keys, Rotation rotation)
    : keys_(std::move(keys)), mode_(rotation) {
  check_times(keys_, "orientation track");
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    auto& q = keys_[i].rotation;
    if (!q.coeffs().allFinite() || q.norm() < 1e-12)
      fail("orientation track", i, "quaternion is not finite or is zero");
    q.normalize();
    if (i > 0 && q.dot(keys_[i - 1].rotation) < 0) q.coeffs() = -q.coeffs();  // the short way
  }
  const std::size_t n = keys_.size();
  inner_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& q = keys_[i].rotation;
    if (i == 0 || i + 1 == n) {
      inner_[i] = q;
      continue;
    }
    const Eigen::Quaterniond qi = q.conjugate();
    const Eigen::Quaterniond a = quat_log(qi * keys_[i + 1].rotation), b = quat_log(qi * keys_[i - 1].rotation);
    const Eigen::Quaterniond e(0.0, -(a.x() + b.x()) / 4, -(a.y() + b.y()) / 4, -(a.z() + b.z()) / 4);
    inner_[i] = (q * quat_exp(e)).normalized();
  }
}

Eigen::Quaterniond OrientationTrack::rotation(double t) const {
  if (keys_.size() == 1 || t <= keys_.front().time) return keys_.front().rotation;
  if (t >= keys_.back().time) return keys_.back().rotation;
  const std::size_t i = find_segment(keys_, t);
  const double h = (t - keys_[i].time) / (keys_[i + 1].time - keys_[i].time);
  const auto& a = keys_[i].rotation;
  const auto& b = keys_[i + 1].rotation;
  if (mode_ == Rotation::Slerp) return slerp(a, b, h);
  return slerp(slerp(a, b, h), slerp(inner_[i], inner_[i + 1], h), 2 * h * (1 - h));
}

// ---------------------------------------------------------------------------------------------------

PhaseTrack::PhaseTrack(std::vector<PhaseKey> keys, PhaseEasing easing) : keys_(std::move(keys)), easing_(easing) {
  check_times(keys_, "phase track");
  for (std::size_t i = 0; i < keys_.size(); ++i)
    if (!std::isfinite(keys_[i].phase)) fail("phase track", i, "phase is not finite");
}

double PhaseTrack::phase(double t) const {
  if (keys_.size() == 1 || t <= keys_.front().time) return keys_.front().phase;
  if (t >= keys_.back().time) return keys_.back().phase;
  const std::size_t i = find_segment(keys_, t);
  double s = (t - keys_[i].time) / (keys_[i + 1].time - keys_[i].time);
  if (easing_ == PhaseEasing::Smooth) s = s * s * (3 - 2 * s);
  return keys_[i].phase + s * (keys_[i + 1].phase - keys_[i].phase);
}

}  // namespace csrbf::anim
