// The Picker's document, without any GUI: a mesh, the control vectors picked on it, the fit options
// and the active area, and the deformed mesh they give. The window edits it through whole states,
// which makes every edit undoable and lets a bad edit be refused with the last good state kept.
#pragma once

#include "csrbf/io/deformation.hpp"
#include "csrbf/folds.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/space_map.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::picker {

/// A control vector. A pinned control keeps its destination on its source (it holds a region in
/// place) and its handle cannot be dragged; a new unpinned one starts there too until dragged.
struct Control {
  Vec3 source = Vec3::Zero(), destination = Vec3::Zero();
  bool pinned = false;
  bool operator==(const Control&) const = default;
};

/// Everything an edit can change.
struct State {
  std::vector<Control> controls;
  double radius = 0.1;  ///< model units
  Kernel kernel = Kernel::C2;
  Polynomial polynomial = Polynomial::None;
  double phase = 1.0;
  std::vector<std::uint32_t> region;  ///< the active area (sorted vertex indices); empty: the whole mesh
  bool operator==(const State&) const = default;
};

/// What applying a state cost, or why it was refused.
struct Outcome {
  bool ok = true;
  std::string error;  ///< the engine's message when !ok
  double fit_ms = 0, eval_ms = 0;
};

class Document {
 public:
  /// Throws io::FileError. The state is reset: no controls, R = 5% of the bounding box diagonal.
  void load_mesh(const std::filesystem::path& path);
  bool has_mesh() const noexcept { return mesh_.has_value(); }
  const io::MeshDocument& mesh() const { return *mesh_; }
  const std::filesystem::path& mesh_path() const noexcept { return mesh_path_; }
  const std::vector<Vec3>& rest() const noexcept { return rest_; }
  double diagonal() const noexcept { return diagonal_; }

  const State& state() const noexcept { return state_; }
  /// Fits and evaluates `s`; on success it becomes the state and deformed() follows. On an engine
  /// error (a degenerate polynomial, duplicate sources, ...) nothing changes and the outcome says why.
  Outcome apply(const State& s);

  /// Rest positions moved by the current state: vertices outside the active area stay.
  const std::vector<Vec3>& deformed() const noexcept { return deformed_; }
  /// |deformed - rest| per vertex.
  std::vector<double> displacement_magnitudes() const;
  /// det(dT/dx) at the current phase over the vertices the state moves (the active area):
  /// folded_vertices are indices into rest(). Empty report without controls.
  FoldReport folds() const;

  /// The deformation file (docs/scene-format.md) of the current state, its active area included, and
  /// reading one back (as a state with the file's phase, or the current one where it has none; the
  /// file's active area, or the whole mesh). The file holds the phase shown.
  /// state_from throws io::FileError when the file's area was picked on a mesh of another vertex count.
  io::DeformationSpec deformation() const;
  State state_from(const io::DeformationSpec& spec, const std::string& where = "the deformation") const;
  /// The active area of a state as the deformation file holds it; empty for the whole mesh.
  std::optional<io::ActiveArea> area(const State& s) const;
  /// A radius for controls that come without one: three times the larger of the sources' median
  /// nearest-neighbour spacing and the longest control vector, then raised by 25% steps while the
  /// map folds the mesh (the active area of `s`) at phase 1, up to the mesh's diagonal. Throws what
  /// the fit throws.
  double propose_radius(const State& s) const;
  /// Writes the deformed mesh (the current phase) in the format of path's extension, atomically.
  void export_mesh(const std::filesystem::path& path) const;

 private:
  std::optional<io::MeshDocument> mesh_;
  std::filesystem::path mesh_path_;
  std::vector<Vec3> rest_, deformed_;
  std::optional<SpaceMap> map_;  // of the current state; empty without controls
  double diagonal_ = 1.0;
  State state_;
};

/// The point of a triangle mesh nearest to p and its distance (brute force over the polygons, fanned
/// into triangles). For tests and for snapping.
double distance_to_mesh(const std::vector<Vec3>& positions, const PolygonList& faces, const Vec3& p);

}  // namespace csrbf::picker
