// A volume mesh as the morph sees it: its points, its named patches (sets of boundary points) and
// the topology its quality is measured on. Readers fill it (csrbf/morph/openfoam.hpp); only the
// points ever change.
#pragma once

#include "csrbf/types.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace csrbf::morph {

/// A named set of boundary points (an OpenFOAM patch, a Gmsh physical group, ...): indices into
/// VolumeMesh::points, sorted and unique.
struct Patch {
  std::string name;
  std::string type;  ///< as the format names it ("wall", "patch", "empty"), or empty
  std::vector<std::uint32_t> points;
};

/// Polyhedral cells as OpenFOAM stores them: faces (point loops), each with an owner cell and,
/// for the first internal_faces faces, a neighbour cell. A face's normal points out of its owner.
struct PolyTopology {
  std::vector<std::uint64_t> face_start;  ///< faces + 1 offsets into face_points
  std::vector<std::uint32_t> face_points;
  std::vector<std::uint32_t> owner;      ///< one per face
  std::vector<std::uint32_t> neighbour;  ///< one per internal face
  std::size_t cells = 0;

  std::size_t faces() const { return owner.size(); }
  std::size_t internal_faces() const { return neighbour.size(); }
};

struct VolumeMesh {
  std::vector<Vec3> points;
  std::vector<Patch> patches;
  PolyTopology poly;

  /// The patch named name, or nullptr.
  const Patch* patch(const std::string& name) const {
    for (const auto& p : patches)
      if (p.name == name) return &p;
    return nullptr;
  }
};

}  // namespace csrbf::morph
