// A volume mesh as the morph sees it: its points, its named patches (sets of boundary points) and
// the topology its quality is measured on. Readers fill it (csrbf/morph/openfoam.hpp); only the
// points ever change.
#pragma once

#include "csrbf/types.hpp"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace csrbf::morph {

/// A named set of boundary points (an OpenFOAM patch, a Gmsh physical group, ...): indices into
/// VolumeMesh::points, sorted and unique.
struct Patch {
  std::string name;
  std::string type;  ///< as the format names it ("wall", "patch", "empty"), or empty
  std::vector<std::uint32_t> points;
  std::vector<std::string> groups;  ///< OpenFOAM's inGroups
  /// The patch's faces, [face_begin, face_end) of VolumeMesh::poly (OpenFOAM), or none: a curved
  /// patch's surface, which slip projects onto.
  std::uint64_t face_begin = 0, face_end = 0;
  /// A boundary of the mesh (an OpenFOAM patch other than processor ones, a Gmsh group of one
  /// dimension below the mesh's, a CGNS boundary condition): what a motion leaves unlisted gets a
  /// default kind (slip where planar, fixed otherwise); other patches are left free.
  bool boundary = false;
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

/// Standard cells (VTK, Gmsh, CGNS) by their corner points, in VTK's cell types and corner order
/// (VTK_TETRA 10, VTK_HEXAHEDRON 12, VTK_WEDGE 13, VTK_PYRAMID 14, and the 2-D VTK_TRIANGLE 5 and
/// VTK_QUAD 9). Higher-order cells are kept by their corners.
struct CellTopology {
  std::vector<std::uint8_t> type;
  std::vector<std::uint64_t> start{0};  ///< cells + 1 offsets into points
  std::vector<std::uint32_t> points;

  std::size_t size() const { return type.size(); }
  void add(std::uint8_t t, std::span<const std::uint32_t> corners) {
    type.push_back(t);
    points.insert(points.end(), corners.begin(), corners.end());
    start.push_back(points.size());
  }
};

struct VolumeMesh {
  std::vector<Vec3> points;
  /// The file's own number of each point, where it is not its index (Gmsh node tags): the ids a
  /// displacements file uses. Empty: point i is number i.
  std::vector<std::uint64_t> point_ids;
  std::vector<Patch> patches;
  PolyTopology poly;   ///< OpenFOAM
  CellTopology cells;  ///< the other formats

  /// The patch named name, or nullptr.
  const Patch* patch(const std::string& name) const {
    for (const auto& p : patches)
      if (p.name == name) return &p;
    return nullptr;
  }
};

}  // namespace csrbf::morph
