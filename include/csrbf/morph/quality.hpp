// Cell quality of a volume mesh, before and after a morph.
// - Polyhedra (OpenFOAM): the measures OpenFOAM's checkMesh computes, with its formulas
//   (primitiveMeshTools: face centres and areas by triangles about the face's mean point, cell
//   centres and volumes by pyramids about an estimated centre, non-orthogonality, skewness, face
//   pyramids).
// - Standard cells (VTK, Gmsh, CGNS): the scaled Jacobian, by Verdict through vtkMeshQuality for
//   tetrahedra and hexahedra; for prisms and pyramids (which VTK 9.1's vtkMeshQuality does not
//   measure) the same quantity computed here: the smallest corner Jacobian, each corner's three
//   edges normalised. A cell with any corner Jacobian <= 0 is inverted. A mesh with no 3-D cells
//   (a 2-D mesh) is measured by its triangles and quadrilaterals, signed against their normals
//   before the morph.
#pragma once

#include "csrbf/morph/volume_mesh.hpp"

#include <cstddef>
#include <memory>
#include <optional>
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
  /// The smallest cell volume after / before (QualityMeter: against its first measure; 1 for that
  /// one and for poly_quality alone). Below 0: a cell turned inside out; near 0: one crushed.
  double min_volume_ratio = 1;
  /// checkMesh -allGeometry's "Cell determinant (wellposedness)": per cell, det of the sum of its
  /// internal and coupled faces' outer products S S^T, each S scaled by the cell's mean face area
  /// (in a 2-D mesh the empty direction's diagonal set to 1), over 8: 1 for a cube whose six
  /// faces are internal, 0 for a cell without such faces. checkMesh warns below 0.001. Smallest
  /// and mean over the cells.
  double min_determinant = 0, mean_determinant = 0;
};

/// The checkMesh measures of t over points. Parallel over faces; deterministic. The cell
/// determinant counts internal faces alone and takes the mesh as 3-D (QualityMeter knows the
/// patches: coupled ones count, and an empty patch's direction is the 2-D mesh's missing one).
PolyQuality poly_quality(const PolyTopology& t, std::span<const Vec3> points);

struct CellQuality {
  std::size_t cells = 0;  ///< cells measured (3-D ones; 2-D ones in a 2-D mesh)
  std::size_t tetrahedra = 0, hexahedra = 0, prisms = 0, pyramids = 0, triangles = 0, quads = 0;
  double min_scaled_jacobian = 1;  ///< in [-1, 1]; 1 for a perfect cell
  double mean_scaled_jacobian = 1;
  std::size_t inverted_cells = 0;  ///< cells with a corner Jacobian <= 0
  /// The smallest cell volume (2-D cells: area) over points / over reference, by the same split
  /// into tetrahedra (triangles): 1 when nothing moved.
  double min_volume_ratio = 1;
};

/// reference: the points before the morph, which give 2-D cells their normals (may be points).
/// VTK's Verdict measures them: in csrbf::morph_formats.
CellQuality cell_quality(const CellTopology& t, std::span<const Vec3> points, std::span<const Vec3> reference);

/// Puts each standard cell's corners in VTK's orientation where a file's convention differs (CGNS
/// and Gmsh order a prism's corners the other way round): for each cell type, if most cells are
/// mirrored in VTK's convention, all of that type are reordered. A mesh's own inverted cells stay
/// inverted.
void orient_cells(CellTopology& t, std::span<const Vec3> points);

struct MeshQuality {
  std::optional<PolyQuality> poly;
  std::optional<CellQuality> cells;
  std::size_t inverted_cells() const { return (poly ? poly->inverted_cells : 0) + (cells ? cells->inverted_cells : 0); }
};

/// The measures that apply to mesh's topology, over points.
MeshQuality mesh_quality(const VolumeMesh& mesh, std::span<const Vec3> points);

namespace detail {
struct PolyBuffers;
}

/// mesh_quality for many point sets of one mesh (before, after, a bisection): keeps its buffers
/// and the cell-to-face index between calls. Borrows mesh, which must outlive it; one thread at a
/// time.
class QualityMeter {
 public:
  explicit QualityMeter(const VolumeMesh& mesh);
  ~QualityMeter();
  QualityMeter(const QualityMeter&) = delete;
  QualityMeter& operator=(const QualityMeter&) = delete;
  MeshQuality measure(std::span<const Vec3> points);

 private:
  const VolumeMesh* mesh_;
  std::unique_ptr<detail::PolyBuffers> buffers_;
};

}  // namespace csrbf::morph
