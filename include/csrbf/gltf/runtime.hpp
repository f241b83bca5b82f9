// A glb's meshes played on the CPU as a client of CSRBF_deformation plays them
// (docs/gltf/CSRBF_deformation.md): the extension's deformations evaluated at each vertex with their
// Jacobians (normals J^-T n), and the morph targets it does not replace added as glTF adds them.
// For engines that load `csrbf export --compact` files, and the tests that check them.
#pragma once

#include "csrbf/types.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace csrbf::gltf {

class GltfRuntime {
 public:
  /// Reads a .glb's bytes. Throws InvalidInput naming the field (and value) that is malformed: a
  /// chunk, an accessor out of its buffer view, a deformation's kernel or radius, a term's weight.
  explicit GltfRuntime(const std::vector<unsigned char>& glb);
  ~GltfRuntime();
  GltfRuntime(GltfRuntime&&) noexcept;
  GltfRuntime& operator=(GltfRuntime&&) noexcept;

  std::size_t meshes() const noexcept;
  /// The index of the mesh named name; throws InvalidInput where none is.
  std::size_t mesh_named(const std::string& name) const;
  /// Whether the mesh carries CSRBF_deformation.
  bool compact(std::size_t mesh) const;
  const std::string& name(std::size_t mesh) const;
  std::span<const Vec3> rest(std::size_t mesh) const;
  /// Every primitive's triangles (mode 4), three vertex indices each (0, 1, 2, ... where a
  /// primitive has no indices).
  std::span<const std::uint32_t> triangles(std::size_t mesh) const;
  /// The last key time of the mesh's weights channel (0 where none is animated).
  double duration(std::size_t mesh) const;
  /// The mesh's weights at time t: the animations' `weights` channel of a node holding the mesh
  /// (LINEAR or STEP), else its default `weights`.
  std::vector<double> weights(std::size_t mesh, double t) const;
  /// The mesh's vertices and normals (unit) at these weights. With use_extension, its deformations
  /// stage by stage, and the morph targets that no term names; without, every morph target (what a
  /// client without the extension draws).
  void deform(std::size_t mesh, std::span<const double> weights, std::vector<Vec3>& positions,
              std::vector<Vec3>& normals, bool use_extension = true) const;
  /// The same into an engine's float buffers: weights one a morph target; positions and normals xyz
  /// a vertex (3 * rest(mesh).size() floats each), filled in place. Throws InvalidInput naming the
  /// buffer whose size is wrong, and where a value is beyond float (nothing is written then).
  void deform(std::size_t mesh, std::span<const float> weights, std::span<float> positions, std::span<float> normals,
              bool use_extension = true) const;

 private:
  struct Data;
  std::unique_ptr<Data> d_;
};

}  // namespace csrbf::gltf
