// The animation model of the paper (section 5): a scene of animation objects, each made of parts
// with their own colours, textures and CSRBF deformations on a schedule, moving along a
// Kochanek-Bartels trajectory and turning about its centre of gravity. No rendering here: a Player
// gives every vertex position of every object at any time t; csrbf::render draws them.
#pragma once

#include "csrbf/anim/tracks.hpp"
#include "csrbf/space_map.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::anim {

enum class TextureMapping { Sphere, Plane, Cylinder };

/// How a part looks. Colours are RGB in [0, 1].
struct Material {
  Vec3 color = Vec3(0.8, 0.8, 0.8);
  double opacity = 1.0;
  double specular = 0.2;
  std::string texture;                              ///< image file (PNG or JPEG), or empty
  TextureMapping mapping = TextureMapping::Sphere;  ///< texture coordinates, projected from the rest shape
};

/// A built-in dynamic deformation: the part is an axis-aligned box in its model coordinates (its
/// rest vertices' bounding box), and where another object's bounding sphere comes within its radius
/// of a wall, five control vectors push a patch of that wall outwards by the penetration depth; the
/// box's 8 corners are pinned. The controls change every frame, so every frame is a full recompute
/// (neighbour search, ordering, factorisation, solve, evaluation): the paper's 386-vertex box.
struct Contact {
  std::size_t collider = 0;      ///< index of the pushing object in Scene::objects
  double collider_radius = 0.0;  ///< > 0, world units
  double spread = 0.6;           ///< distance of the four side controls, in collider radii
};

/// One CSRBF deformation of a part, in the object's model coordinates.
struct Deformation {
  std::string name;
  std::optional<SpaceMap> map;     ///< a fixed deformation (fitted once), or
  std::optional<Contact> contact;  ///< a dynamic one, fitted every frame with `options`
  FitOptions options;              ///< radius, kernel and polynomial of a contact deformation
  PhaseTrack schedule;             ///< phase against time (default: 1 throughout)
  /// The active area: sorted object vertex indices it moves (the Picker's); empty: the whole part.
  std::vector<std::uint32_t> area;
};

/// How the deformations of a part combine.
enum class Combine {
  Compose,  ///< in order, each on the result of the previous (the paper's pipeline of transforms)
  Sum,      ///< displacements of all, each at the rest shape, added with their phases (blending)
};

/// A vertex group with its own look and deformations.
struct Part {
  std::string name;
  std::vector<std::uint32_t> vertices;  ///< sorted, unique indices into Object::rest
  std::vector<std::uint32_t> faces;     ///< faces drawn with this part's material
  Material material;
  std::vector<Deformation> deformations;
  Combine combine = Combine::Compose;
};

struct Object {
  std::string name;
  std::vector<Vec3> rest;   ///< model coordinates
  PolygonList faces;        ///< polygons, 0-based
  std::vector<Part> parts;  ///< a vertex in several parts takes the last one's deformation
  Material material;        ///< faces in no part
  /// World position of the centre of gravity against time; empty: it stays at centre.
  std::optional<PositionTrack> trajectory;
  OrientationTrack orientation;  ///< about the centre of gravity (identity by default)
  Vec3 centre = Vec3::Zero();    ///< centre of gravity of the rest surface (set by finalize())
  /// Computes centre (area-weighted centroid of the faces; mean vertex without area). Call after
  /// filling rest and faces.
  void finalize();
};

struct Camera {
  Vec3 position = Vec3(0.5, 0.5, 3.0);
  Vec3 focal_point = Vec3(0.5, 0.5, 0.5);
  Vec3 view_up = Vec3(0.0, 1.0, 0.0);
  double view_angle = 30.0;  ///< degrees, vertical
};

struct Light {
  Vec3 position = Vec3(1.0, 1.0, 1.0);  ///< a light at infinity shining from position to the focal point
  Vec3 color = Vec3(1.0, 1.0, 1.0);
  double intensity = 1.0;
  bool headlight = false;  ///< follows the camera (position is then ignored)
};

struct Scene {
  std::vector<Object> objects;
  Camera camera;
  std::vector<Light> lights;  ///< empty: one headlight
  Vec3 background = Vec3(0.1, 0.1, 0.15);
  double duration = 1.0;  ///< seconds, > 0
  double fps = 25.0;      ///< frames per second, > 0
  /// Number of frames from t = from to t = to inclusive of from, at fps: frame k is at from + k / fps.
  std::size_t frame_count(double from, double to) const;
};

/// The rigid part of an object's motion at time t: world = rotation (model - centre) + position.
struct Pose {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Vec3 position = Vec3::Zero();
};
Pose pose_at(const Object& object, double t);

/// Evaluates a scene at any time: deformations by schedule, then the rigid motion. Fixed
/// deformations are fitted when the scene is built; their per-vertex displacements over each part's
/// rest shape are kept here (DisplacementField), so the first deformation of a part costs one pass
/// over memory per frame. The scene must outlive the player. Not thread-safe (it owns buffers).
class Player {
 public:
  explicit Player(const Scene& scene);
  ~Player();
  /// What a Player of `scene` holds, in bytes, before it is made (for memory limits): each object's
  /// model and world vertices, each part's rest and work buffers, and each kept DisplacementField.
  static double bytes(const Scene& scene);
  Player(Player&&) noexcept;
  Player(const Player&) = delete;
  Player& operator=(const Player&) = delete;

  /// Computes every object's vertices at time t (world coordinates).
  void evaluate(double t);
  /// Vertices of object i after the last evaluate(), world coordinates, in the mesh's order.
  const std::vector<Vec3>& positions(std::size_t object) const;
  /// Vertices of object i in model coordinates (deformed, before the rigid motion).
  const std::vector<Vec3>& deformed(std::size_t object) const;
  const Scene& scene() const noexcept { return *scene_; }
  /// The map that contact deformation `deformation` of part `part` of object `object` is refitted
  /// to at time t (what evaluate(t) applies with its phase), or none where no wall is touched.
  /// Throws InvalidInput naming the deformation and t where the fit fails.
  std::optional<SpaceMap> contact_map(std::size_t object, std::size_t part, std::size_t deformation, double t) const;

 private:
  std::optional<SpaceMap> contact_fit(std::size_t object, std::size_t part, std::size_t deformation, double t,
                                      std::vector<Vec3>& sources, std::vector<Vec3>& destinations) const;
  struct Impl;
  const Scene* scene_;
  std::unique_ptr<Impl> impl_;
};

/// Controls of a Contact deformation for a box [lo, hi] and a sphere (model coordinates).
void contact_controls(const Vec3& lo, const Vec3& hi, const Vec3& centre, double sphere_radius, double spread,
                      std::vector<Vec3>& sources, std::vector<Vec3>& destinations);

}  // namespace csrbf::anim
