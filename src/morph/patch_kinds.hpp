// What each patch of a volume mesh does in a morph: the motion file's entries resolved against the
// mesh (names, OpenFOAM's group names and regular expressions), the defaults of the patches it
// leaves unlisted, and the surfaces that slip keeps points on.
#pragma once

#include "csrbf/morph/backend.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/morph/motion.hpp"
#include "csrbf/morph/volume_mesh.hpp"
#include "csrbf/neighbor_index.hpp"

#include <optional>
#include <string>
#include <vector>

namespace csrbf::morph::detail {

/// A patch's best plane (through the centroid of its points, normal to their least spread) and its
/// points' largest distance from it, over every part of a decomposed mesh.
struct PatchPlane {
  Vec3 centre = Vec3::Zero(), normal = Vec3::UnitZ();
  double deviation = 0;
  bool every_point = false;  ///< the patch holds every point of the mesh
};

/// Patches closer to their plane than this fraction of the mesh's size are planar.
constexpr double kPlanarTolerance = 1e-9;

/// The plane of every boundary patch (Patch::boundary; collective over the backend's processes:
/// every process calls it, and every part lists the same boundaries in the same order).
std::vector<PatchPlane> patch_planes(const VolumeMesh& mesh, MorphBackend& b);

/// The motion with one entry a patch of the mesh: the file's entries matched (exactly, then by
/// group, then by a regular expression matching the whole name, each entry in the file's order), and
/// each unlisted boundary patch given its default (symmetryPlane, symmetry, wedge: slip; empty in a
/// 2-D mesh: free, as the 2-D morph keeps its planes; cyclic ones: fixed; others slip where planar,
/// fixed otherwise). reports: each patch of the mesh, its kind and why. An entry that matches no
/// patch is an error naming it and the mesh's patches; a displacements file names one patch.
Motion resolve_patches(const VolumeMesh& mesh, const Motion& motion, std::span<const PatchPlane> planes,
                       double mesh_size, bool two_d, std::vector<PatchReport>& reports);

/// Projects points onto a patch's faces (OpenFOAM's polygons, as fans of triangles): the closest
/// point of the surface. Throws io::FileError where the patch has no faces.
class SurfaceProjector {
 public:
  SurfaceProjector(const VolumeMesh& mesh, const Patch& patch, const std::string& where);
  Vec3 project(const Vec3& y) const;

 private:
  std::vector<std::array<Vec3, 3>> triangles_;
  std::vector<Vec3> centres_;
  NeighborIndex index_;
  double reach_ = 0;
};

}  // namespace csrbf::morph::detail
