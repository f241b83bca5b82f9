// Keyframe tracks of the animation model (paper section 5): positions along Kochanek-Bartels
// splines, orientations by quaternion interpolation, and deformation phases. Every track is
// immutable after construction and thread-safe to query; times are seconds.
#pragma once

#include "csrbf/errors.hpp"
#include "csrbf/neighbor_index.hpp"

#include <Eigen/Geometry>

#include <span>
#include <vector>

namespace csrbf::anim {

/// A key of a position track. tension, continuity and bias are those of Kochanek & Bartels
/// (1984); all 0 gives a Catmull-Rom spline. tension 1 stops at the key; continuity != 0 breaks the
/// velocity there (a corner for continuity = -1); bias > 0 overshoots, < 0 undershoots.
struct PositionKey {
  double time = 0.0;
  Vec3 position = Vec3::Zero();
  double tension = 0.0, continuity = 0.0, bias = 0.0;
};

/// How a position track behaves at its first and last keys.
enum class TrackEnds {
  Natural,  ///< second derivative zero (VTK's vtkSpline constraint 2 with value 0)
  Still,    ///< zero velocity: the object eases in and out (VTK's default constraint 1, value 0)
};

/// Kochanek-Bartels interpolating spline through position keys, piecewise cubic Hermite in time.
/// The tangents are adjusted for unequal key spacing as in the paper of Kochanek & Bartels (and in
/// vtkKochanekSpline), so with continuity 0 the velocity is continuous in time at every key.
/// Before the first key and after the last the track holds still.
class PositionTrack {
 public:
  /// keys: at least one, times finite and strictly increasing, parameters finite. Throws
  /// InvalidInput naming the key's index and the value.
  explicit PositionTrack(std::vector<PositionKey> keys, TrackEnds ends = TrackEnds::Natural);
  PositionTrack() : PositionTrack({PositionKey{}}) {}

  Vec3 position(double t) const;
  /// d position / dt.
  Vec3 velocity(double t) const;
  const std::vector<PositionKey>& keys() const noexcept { return keys_; }
  TrackEnds ends() const noexcept { return ends_; }
  /// Per key, the Hermite tangents leaving it and arriving at it, per unit of the segment's
  /// parameter (divide by the segment's duration for d position / dt): glTF's CUBICSPLINE keys.
  const std::vector<Vec3>& out_tangents() const noexcept { return out_; }
  const std::vector<Vec3>& in_tangents() const noexcept { return in_; }

 private:
  std::size_t segment(double t) const;  // i with keys_[i].time <= t < keys_[i + 1].time (clamped)
  std::vector<PositionKey> keys_;
  TrackEnds ends_;
  std::vector<Vec3> out_, in_;  // per key: tangent leaving it and arriving at it, per unit segment parameter
};

/// How an orientation track interpolates between keys.
enum class Rotation {
  Slerp,  ///< spherical linear, constant angular speed in each segment (Shoemake 1985)
  Squad,  ///< spherical cubic through the keys, smooth across keys (Shoemake 1987)
};

struct OrientationKey {
  double time = 0.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< normalised on construction
};

/// Orientation keys interpolated on the unit quaternion sphere. Each key is replaced by its
/// antipode where that is closer to the previous key, so every segment turns the short way (less
/// than 180 degrees). Holds still outside the keys. Results are unit quaternions.
class OrientationTrack {
 public:
  /// keys: at least one; times strictly increasing; quaternions finite and non-zero.
  explicit OrientationTrack(std::vector<OrientationKey> keys, Rotation rotation = Rotation::Squad);
  OrientationTrack() : OrientationTrack({OrientationKey{}}) {}

  Eigen::Quaterniond rotation(double t) const;
  const std::vector<OrientationKey>& keys() const noexcept { return keys_; }
  Rotation interpolation() const noexcept { return mode_; }

 private:
  std::vector<OrientationKey> keys_;       // hemisphere-aligned
  std::vector<Eigen::Quaterniond> inner_;  // squad's control quaternions s_i
  Rotation mode_;
};

/// Slerp without the shortest-path flip (the tracks align the keys once instead); t in [0, 1].
Eigen::Quaterniond slerp(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double t);

struct PhaseKey {
  double time = 0.0;
  double phase = 0.0;  ///< the deformation's phase: 0 at rest, 1 fully deformed (finite; any value extrapolates)
};

/// How a phase track goes from one key to the next.
enum class PhaseEasing {
  Linear,  ///< straight lines: constant speed, a kink at each key
  Smooth,  ///< smoothstep 3s^2 - 2s^3 in each segment: C1, at rest at every key, never past a key's value
};

/// The schedule of one deformation: its phase at any time. Holds the first and last values
/// outside the keys.
class PhaseTrack {
 public:
  /// keys: at least one; times strictly increasing; phases finite.
  explicit PhaseTrack(std::vector<PhaseKey> keys, PhaseEasing easing = PhaseEasing::Smooth);
  PhaseTrack() : PhaseTrack({PhaseKey{0.0, 1.0}}) {}

  double phase(double t) const;
  const std::vector<PhaseKey>& keys() const noexcept { return keys_; }
  PhaseEasing easing() const noexcept { return easing_; }

 private:
  std::vector<PhaseKey> keys_;
  PhaseEasing easing_;
};

}  // namespace csrbf::anim
