// Cell quality of a volume mesh, before and after a morph. For polyhedra (OpenFOAM), the measures
// OpenFOAM's checkMesh computes, with its formulas (primitiveMeshTools: face centres and areas by
// triangles about the face's mean point, cell centres and volumes by pyramids about an estimated
// centre, non-orthogonality, skewness, face pyramids).
#pragma once

#include "csrbf/morph/volume_mesh.hpp"

#include <cstddef>
#include <span>

namespace csrbf::morph {

struct PolyQuality {
  std::size_t cells = 0, faces = 0, internal_faces = 0;
  double max_non_orthogonality = 0;   ///< degrees, over internal faces (checkMesh's "Mesh non-orthogonality Max")
  double mean_non_orthogonality = 0;  ///< degrees ("average": the angle of the mean cosine)
  double max_skewness = 0;            ///< checkMesh's "Max skewness" (internal and boundary faces)
  std::size_t negative_volumes = 0;   ///< cells of volume <= 1e-300 ("Zero or negative cell volume")
  std::size_t bad_pyramids = 0;       ///< face pyramids of negative volume ("faces incorrectly oriented")
  std::size_t inverted_cells = 0;     ///< cells with a non-positive volume or a bad pyramid
  double min_volume = 0, total_volume = 0;
};

/// The checkMesh measures of t over points. Parallel over faces; deterministic.
PolyQuality poly_quality(const PolyTopology& t, std::span<const Vec3> points);

}  // namespace csrbf::morph
