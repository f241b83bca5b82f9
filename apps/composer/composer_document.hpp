// The Animation Composer's document, without any GUI: the scene file's JSON (docs/scene-format.md)
// and the edits the Composer makes to it. Every edit is a whole new JSON value, so undo is a swap
// and the file written is exactly what `csrbf animate` reads.
#pragma once

#include "csrbf/anim/scene.hpp"
#include "csrbf/errors.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

namespace csrbf::composer {

/// An edit that the scene cannot take (a key time out of order, a missing file); the message says why.
class EditError : public csrbf::Error {
 public:
  using csrbf::Error::Error;
};

class Document {
 public:
  Document();

  const nlohmann::json& json() const noexcept { return json_; }
  /// Replaces the JSON (undo, redo) whose relative paths are relative to `from_base`: they are
  /// rewritten for this document's folder, so that a state from before a Save As into another folder
  /// still names the same files.
  void set_json(nlohmann::json j, const std::filesystem::path& from_base);
  /// Takes a recovered document whole: its JSON, the folder its relative paths are for, and the
  /// file it was opened from or saved to (empty: never saved).
  void adopt(nlohmann::json j, const std::filesystem::path& base, const std::filesystem::path& path);
  /// Folder that relative paths in the JSON are relative to (the scene file's folder).
  const std::filesystem::path& base() const noexcept { return base_; }
  const std::filesystem::path& path() const noexcept { return path_; }

  /// A new empty scene (4 s at 25 fps), paths relative to `base`.
  void reset(const std::filesystem::path& base);
  /// Throws io::FileError (the scene is read whole, meshes and deformations included, to check it).
  /// A deformation file opened as a scene is named as such, with where to attach it instead.
  void open(const std::filesystem::path& file);
  /// Writes atomically; relative paths are rewritten for the new folder.
  void save(const std::filesystem::path& file);

  /// The scene this JSON describes, meshes loaded and deformations fitted. Throws io::FileError.
  anim::Scene build() const;

  // Edits (each throws EditError and leaves the JSON unchanged when it cannot be made).
  /// Adds an object for a mesh file; returns its index. Its name is the file's stem, made unique.
  std::size_t add_object(const std::filesystem::path& mesh);
  void remove_object(std::size_t object);
  /// Inserts a trajectory key at time t (error if a key is already at t); returns its index.
  std::size_t add_position_key(std::size_t object, double t, const Vec3& position);
  void set_position(std::size_t object, std::size_t key, const Vec3& position);
  void set_tcb(std::size_t object, std::size_t key, double tension, double continuity, double bias);
  void remove_position_key(std::size_t object, std::size_t key);
  /// Sets (or adds) the orientation key at time t from angles in degrees: yaw about y, then pitch
  /// about x, then roll about z. Returns its index.
  std::size_t set_orientation_key(std::size_t object, double t, double yaw, double pitch, double roll);
  void remove_orientation_key(std::size_t object, std::size_t key);
  /// Attaches a deformation file to the object's part (a new part "deformed" holding the whole mesh
  /// if the object has none), with phase 0 at t = 0 and 1 at the scene's duration; returns its index.
  std::size_t attach_deformation(std::size_t object, const std::filesystem::path& deformation_file);
  std::size_t add_phase_key(std::size_t object, std::size_t deformation, double t, double phase);

  /// The keys a timeline shows for an object: tracks "position", "orientation", and one per
  /// deformation of its first deformed part ("deformation N").
  enum class Track { Position, Orientation, Phase };
  std::vector<double> key_times(std::size_t object, Track track, std::size_t deformation = 0) const;
  std::size_t deformation_count(std::size_t object) const;
  /// Moves a key in time, keeping the track in order (error if it would pass a neighbour).
  void set_key_time(std::size_t object, Track track, std::size_t deformation, std::size_t key, double t);

  /// Deformations of the object's first deformed part: name, combine ("sum" or "compose"), phase
  /// keys (time, value) and easing ("smooth" or "linear"), removal.
  std::string deformation_name(std::size_t object, std::size_t deformation) const;
  void set_deformation_name(std::size_t object, std::size_t deformation, const std::string& name);
  void remove_deformation(std::size_t object, std::size_t deformation);
  std::string combine(std::size_t object) const;
  void set_combine(std::size_t object, const std::string& combine);
  std::string easing(std::size_t object, std::size_t deformation) const;
  void set_easing(std::size_t object, std::size_t deformation, const std::string& easing);
  double phase_value(std::size_t object, std::size_t deformation, std::size_t key) const;
  void set_phase_value(std::size_t object, std::size_t deformation, std::size_t key, double phase);
  void remove_phase_key(std::size_t object, std::size_t deformation, std::size_t key);

  /// Look: the scene camera, background, the object's colour, lights (docs/scene-format.md).
  void set_camera(const Vec3& position, const Vec3& focal_point, const Vec3& view_up, double view_angle);
  void set_background(const Vec3& rgb);
  Vec3 background() const;
  void set_object_color(std::size_t object, const Vec3& rgb);
  Vec3 object_color(std::size_t object) const;
  std::size_t light_count() const;
  /// A light at infinity shining from `position` towards the focal point (or a headlight).
  std::size_t add_light(const Vec3& position, double intensity, bool headlight);
  void set_light(std::size_t light, double intensity, const Vec3& rgb);
  void remove_light(std::size_t light);
  std::string light_label(std::size_t light) const;

  /// t rounded to the nearest frame (1 / fps): keys sit on frames.
  double snap(double t) const;

  void set_duration(double seconds);
  void set_fps(double fps);
  double duration() const;
  double fps() const;
  std::size_t object_count() const;
  std::string object_name(std::size_t object) const;

 private:
  nlohmann::json& object(std::size_t i);
  const nlohmann::json& object(std::size_t i) const;
  nlohmann::json& keys(std::size_t object, Track track, std::size_t deformation);
  std::string relative(const std::filesystem::path& file) const;
  nlohmann::json& deformation_entry(std::size_t object, std::size_t deformation);
  const nlohmann::json& deformation_entry(std::size_t object, std::size_t deformation) const;

  nlohmann::json json_;
  std::filesystem::path base_, path_;
};

/// Angles (degrees: yaw about y, pitch about x, roll about z, applied in that order) of a rotation,
/// and back.
Eigen::Quaterniond quaternion_from_angles(double yaw, double pitch, double roll);
Vec3 angles_from_quaternion(const Eigen::Quaterniond& q);

}  // namespace csrbf::composer
