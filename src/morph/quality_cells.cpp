#include "csrbf/morph/quality.hpp"

#include "quality_buffers.hpp"

#include <vtkCellType.h>
#include <vtkHexahedron.h>
#include <vtkMeshQuality.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkTetra.h>

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>  // parallel_deterministic_reduce: the same sums in every run

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace csrbf::morph {

namespace {

/// The smallest normalised corner Jacobian of a prism or a pyramid (VTK corner order), scaled so
/// that the ideal cell (equilateral triangles, square base with equilateral sides) has 1.
double corner_jacobian(int type, const std::uint32_t* v, std::span<const Vec3> p) {
  // For each corner, three neighbours in the order whose determinant is positive for a valid cell.
  static constexpr int wedge[6][4] = {{0, 2, 1, 3}, {1, 0, 2, 4}, {2, 1, 0, 5},
                                      {3, 4, 5, 0}, {4, 5, 3, 1}, {5, 3, 4, 2}};
  static constexpr int pyramid[4][4] = {{0, 1, 3, 4}, {1, 2, 0, 4}, {2, 3, 1, 4}, {3, 0, 2, 4}};
  const bool is_wedge = type == VTK_WEDGE;
  const int corners = is_wedge ? 6 : 4;
  const double ideal = is_wedge ? std::sqrt(3.0) / 2 : std::sqrt(2.0) / 2;
  double worst = 1;
  for (int c = 0; c < corners; ++c) {
    const int* k = is_wedge ? wedge[c] : pyramid[c];
    const Vec3 a = p[v[k[1]]] - p[v[k[0]]], b = p[v[k[2]]] - p[v[k[0]]], e = p[v[k[3]]] - p[v[k[0]]];
    const double len = a.norm() * b.norm() * e.norm();
    const double j = len > 0 ? a.dot(b.cross(e)) / len / ideal : -1.0;
    worst = std::min(worst, std::min(j, 1.0));
  }
  return worst;
}

/// A 2-D cell's smallest corner sine, signed by the cell's normal before the morph.
double planar_jacobian(std::size_t n, const std::uint32_t* v, std::span<const Vec3> p, std::span<const Vec3> ref) {
  Vec3 normal = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) normal += ref[v[i]].cross(ref[v[(i + 1) % n]]);
  if (!(normal.norm() > 0)) return -1.0;
  normal.normalize();
  double worst = 1;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 a = p[v[(i + 1) % n]] - p[v[i]], b = p[v[(i + n - 1) % n]] - p[v[i]];
    const double len = a.norm() * b.norm();
    worst = std::min(worst, len > 0 ? a.cross(b).dot(normal) / len : -1.0);
  }
  return worst;
}

struct Cells {
  vtkNew<vtkTetra> tet;
  vtkNew<vtkHexahedron> hex;
};

/// A cell's size as a sum of its tetrahedra's signed volumes (a 2-D cell: its triangles' area
/// vectors projected on the reference's), over points p; the same split before and after a morph,
/// so that after / before is the cell's volume ratio whatever the corner order's orientation.
double cell_size(std::uint8_t type, const std::uint32_t* v, std::span<const Vec3> p, std::span<const Vec3> ref) {
  static constexpr int hex[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
  static constexpr int wedge[3][4] = {{0, 1, 2, 5}, {0, 1, 5, 4}, {0, 4, 5, 3}};
  static constexpr int pyramid[2][4] = {{0, 1, 2, 4}, {0, 2, 3, 4}};
  static constexpr int tet[1][4] = {{0, 1, 2, 3}};
  const auto sum = [&](const auto& tets) {
    double s = 0;
    for (const auto& k : tets) {
      const Vec3& a = p[v[k[0]]];
      s += (p[v[k[1]]] - a).cross(p[v[k[2]]] - a).dot(p[v[k[3]]] - a);
    }
    return s / 6;
  };
  switch (type) {
    case VTK_TETRA:
      return sum(tet);
    case VTK_HEXAHEDRON:
      return sum(hex);
    case VTK_WEDGE:
      return sum(wedge);
    case VTK_PYRAMID:
      return sum(pyramid);
    default: {  // a triangle or a quadrilateral (fans from corner 0)
      const int n = type == VTK_TRIANGLE ? 3 : 4;
      Vec3 now = Vec3::Zero(), before = Vec3::Zero();
      for (int k = 1; k + 1 < n; ++k) {
        now += (p[v[k]] - p[v[0]]).cross(p[v[k + 1]] - p[v[0]]);
        before += (ref[v[k]] - ref[v[0]]).cross(ref[v[k + 1]] - ref[v[0]]);
      }
      return now.dot(before.normalized()) / 2;
    }
  }
}

}  // namespace

CellQuality cell_quality(const CellTopology& t, std::span<const Vec3> points, std::span<const Vec3> reference) {
  CellQuality q;
  bool solid = false;
  for (const auto type : t.type)
    solid |= type == VTK_TETRA || type == VTK_HEXAHEDRON || type == VTK_WEDGE || type == VTK_PYRAMID;
  tbb::enumerable_thread_specific<Cells> cells;
  struct Acc {
    std::size_t measured = 0, inverted = 0, tet = 0, hex = 0, prism = 0, pyramid = 0, tri = 0, quad = 0;
    double min = 1, sum = 0, ratio = std::numeric_limits<double>::infinity();
  };
  const Acc acc = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, t.size(), 2048), Acc{},
      [&](const tbb::blocked_range<std::size_t>& r, Acc a) {
        Cells& c = cells.local();
        for (std::size_t i = r.begin(); i < r.end(); ++i) {
          const std::uint32_t* v = t.points.data() + t.start[i];
          double j;
          switch (t.type[i]) {
            case VTK_TETRA:
              for (int k = 0; k < 4; ++k) c.tet->GetPoints()->SetPoint(k, points[v[k]].data());
              j = vtkMeshQuality::TetScaledJacobian(c.tet);
              ++a.tet;
              break;
            case VTK_HEXAHEDRON:
              for (int k = 0; k < 8; ++k) c.hex->GetPoints()->SetPoint(k, points[v[k]].data());
              j = vtkMeshQuality::HexScaledJacobian(c.hex);
              ++a.hex;
              break;
            case VTK_WEDGE:
              j = corner_jacobian(VTK_WEDGE, v, points);
              ++a.prism;
              break;
            case VTK_PYRAMID:
              j = corner_jacobian(VTK_PYRAMID, v, points);
              ++a.pyramid;
              break;
            case VTK_TRIANGLE:
            case VTK_QUAD:
              if (solid) continue;  // faces of a volume mesh: its cells are measured
              j = planar_jacobian(t.type[i] == VTK_TRIANGLE ? 3 : 4, v, points, reference);
              ++(t.type[i] == VTK_TRIANGLE ? a.tri : a.quad);
              break;
            default:
              continue;
          }
          if (!std::isfinite(j)) j = -1.0;
          // The volume ratio, after / before, of cells that had a volume (a degenerate cell of the
          // input has none to compare with).
          const double before = cell_size(t.type[i], v, reference, reference);
          if (std::abs(before) > 1e-300) {
            const double ratio = cell_size(t.type[i], v, points, reference) / before;
            a.ratio = std::min(a.ratio, std::isfinite(ratio) ? ratio : -1.0);
          }
          ++a.measured;
          a.inverted += j <= 0;
          a.min = std::min(a.min, j);
          a.sum += j;
        }
        return a;
      },
      [](Acc x, const Acc& y) {
        x.measured += y.measured;
        x.inverted += y.inverted;
        x.tet += y.tet;
        x.hex += y.hex;
        x.prism += y.prism;
        x.pyramid += y.pyramid;
        x.tri += y.tri;
        x.quad += y.quad;
        x.min = std::min(x.min, y.min);
        x.sum += y.sum;
        x.ratio = std::min(x.ratio, y.ratio);
        return x;
      });
  q.cells = acc.measured;
  q.min_volume_ratio = std::isfinite(acc.ratio) ? acc.ratio : 1.0;
  q.inverted_cells = acc.inverted;
  q.tetrahedra = acc.tet;
  q.hexahedra = acc.hex;
  q.prisms = acc.prism;
  q.pyramids = acc.pyramid;
  q.triangles = acc.tri;
  q.quads = acc.quad;
  q.min_scaled_jacobian = acc.measured ? acc.min : 1.0;
  q.mean_scaled_jacobian = acc.measured ? acc.sum / double(acc.measured) : 1.0;
  return q;
}

void orient_cells(CellTopology& t, std::span<const Vec3> points) {
  // One corner's determinant, positive in VTK's order; and the mirror that reverses it.
  struct Rule {
    std::uint8_t type;
    int a, b, c, o;           // det[p_a - p_o, p_b - p_o, p_c - p_o] > 0
    std::vector<int> mirror;  // new corner k = old corner mirror[k]
  };
  static const Rule rules[] = {{VTK_TETRA, 1, 2, 3, 0, {0, 2, 1, 3}},
                               {VTK_HEXAHEDRON, 1, 3, 4, 0, {4, 5, 6, 7, 0, 1, 2, 3}},
                               {VTK_WEDGE, 2, 1, 3, 0, {0, 2, 1, 3, 5, 4}},
                               {VTK_PYRAMID, 1, 3, 4, 0, {0, 3, 2, 1, 4}}};
  for (const Rule& r : rules) {
    std::size_t positive = 0, negative = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (t.type[i] != r.type) continue;
      const std::uint32_t* v = t.points.data() + t.start[i];
      const Vec3& o = points[v[r.o]];
      const double d = (points[v[r.a]] - o).dot((points[v[r.b]] - o).cross(points[v[r.c]] - o));
      positive += d > 0;
      negative += d < 0;
    }
    if (negative <= positive) continue;
    std::vector<std::uint32_t> old;
    for (std::size_t i = 0; i < t.size(); ++i) {
      if (t.type[i] != r.type) continue;
      std::uint32_t* v = t.points.data() + t.start[i];
      old.assign(v, v + r.mirror.size());
      for (std::size_t k = 0; k < r.mirror.size(); ++k) v[k] = old[std::size_t(r.mirror[k])];
    }
  }
}

}  // namespace csrbf::morph
