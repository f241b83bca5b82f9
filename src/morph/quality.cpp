#include "csrbf/morph/quality.hpp"

#include "quality_buffers.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/volume_file.hpp"

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>  // parallel_deterministic_reduce: the same sums in every run

#include <algorithm>
#include <functional>
#include <limits>
#include <cmath>
#include <numbers>
#include <vector>

namespace csrbf::morph {

namespace {

constexpr double kVSmall = 1e-300;
constexpr double kRootVSmall = 1e-150;

/// OpenFOAM's face centre and area vector (primitiveMeshFaceCentresAndAreas): a triangle is exact;
/// a polygon is split into triangles about its points' mean, the centre weighted by their areas.
void face_geometry(const PolyTopology& t, std::span<const Vec3> p, std::size_t f, Vec3& centre, Vec3& area) {
  const std::uint64_t b = t.face_start[f], e = t.face_start[f + 1];
  const std::size_t n = std::size_t(e - b);
  const std::uint32_t* v = t.face_points.data() + b;
  if (n == 3) {
    centre = (p[v[0]] + p[v[1]] + p[v[2]]) / 3.0;
    area = 0.5 * (p[v[1]] - p[v[0]]).cross(p[v[2]] - p[v[0]]);
    return;
  }
  Vec3 mean = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) mean += p[v[i]];
  mean /= double(n);
  Vec3 sum_n = Vec3::Zero(), sum_ac = Vec3::Zero();
  double sum_a = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& a = p[v[i]];
    const Vec3& next = p[v[i + 1 < n ? i + 1 : 0]];
    const Vec3 c = a + next + mean;
    const Vec3 nn = (next - a).cross(mean - a);
    const double mag = nn.norm();
    sum_n += nn;
    sum_a += mag;
    sum_ac += mag * c;
  }
  if (sum_a < kRootVSmall) {
    centre = mean;
    area = Vec3::Zero();
  } else {
    centre = sum_ac / (3.0 * sum_a);
    area = 0.5 * sum_n;
  }
}

}  // namespace

namespace detail {

namespace {

// What the phases of a measure share: the mesh, the buffers they fill, and what they recompute.
// Each face's and cell's figures are kept (b.cosine, b.skew, b.vol, b.det, b.bad): a later
// measure recomputes only what its dirty flags name, and the reductions run over the whole
// arrays in one fixed order, so that its result equals a whole measure's bit for bit.
struct QualityPass {
  const PolyTopology& t;
  std::span<const Vec3> points;
  PolyBuffers& b;
  const Dirty* dirty;
  std::size_t nf, ni, nc;

  bool face_dirty(std::size_t f) const { return !dirty || dirty->face[f]; }
  bool cell_dirty(std::size_t c) const { return !dirty || dirty->cell[c]; }
  bool face_measured(std::size_t f) const {
    return !dirty || dirty->cell[t.owner[f]] || (f < ni && dirty->cell[t.neighbour[f]]);
  }
};

void face_centres_and_areas(const QualityPass& pass) {
  auto& fc = pass.b.fc;
  auto& fa = pass.b.fa;
  fc.resize(pass.nf);
  fa.resize(pass.nf);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pass.nf, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t f = r.begin(); f < r.end(); ++f)
      if (pass.face_dirty(f)) face_geometry(pass.t, pass.points, f, fc[f], fa[f]);
  });
}

// Each cell's faces by a counting sort, so that the cells are computed in parallel.
void index_cell_faces(const QualityPass& pass) {
  const PolyTopology& t = pass.t;
  const std::size_t nf = pass.nf, ni = pass.ni, nc = pass.nc;
  auto& first = pass.b.first;
  auto& faces_of = pass.b.faces_of;  // a face, with its top bit set where the cell is its neighbour
  if (first.size() != nc + 1) {      // the topology's index, once
    first.assign(nc + 1, 0);
    for (std::size_t f = 0; f < nf; ++f) ++first[t.owner[f] + 1];
    for (std::size_t f = 0; f < ni; ++f) ++first[t.neighbour[f] + 1];
    for (std::size_t c = 0; c < nc; ++c) first[c + 1] += first[c];
    faces_of.resize(first[nc]);
    std::vector<std::uint64_t> next(first.begin(), first.end() - 1);
    for (std::size_t f = 0; f < nf; ++f) faces_of[next[t.owner[f]]++] = std::uint32_t(f);
    for (std::size_t f = 0; f < ni; ++f) faces_of[next[t.neighbour[f]]++] = std::uint32_t(f) | 0x80000000u;
  }
}

// Cell centres and volumes (primitiveMeshCellCentresAndVols): an estimated centre, the mean of
// the cell's face centres, then pyramids from it to each face.
void cell_centres_and_volumes(const QualityPass& pass) {
  PolyBuffers& b = pass.b;
  const std::size_t nf = pass.nf, nc = pass.nc;
  const auto& first = b.first;
  const auto& faces_of = b.faces_of;
  const auto& fc = b.fc;
  const auto& fa = b.fa;
  auto& cc = b.cc;
  auto& vol = b.vol;
  cc.resize(nc);
  vol.resize(nc);
  b.cosine.resize(nf);
  b.skew.resize(nf);
  b.det.resize(nc);
  b.bad.resize(nc);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nc, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t c = r.begin(); c < r.end(); ++c) {
      if (!pass.cell_dirty(c)) continue;
      const std::uint64_t b = first[c], e = first[c + 1];
      Vec3 est = Vec3::Zero();
      for (std::uint64_t k = b; k < e; ++k) est += fc[faces_of[k] & 0x7fffffffu];
      if (e > b) est /= double(e - b);
      Vec3 centre = Vec3::Zero();
      double v = 0;
      for (std::uint64_t k = b; k < e; ++k) {
        const std::uint32_t f = faces_of[k] & 0x7fffffffu;
        const double pyr = (faces_of[k] & 0x80000000u) ? fa[f].dot(est - fc[f]) : fa[f].dot(fc[f] - est);
        centre += pyr * (0.75 * fc[f] + 0.25 * est);
        v += pyr;
      }
      cc[c] = std::abs(v) > kVSmall ? Vec3(centre / v) : est;
      vol[c] = v / 3.0;
    }
  });
}

// Non-orthogonality: the angle between the face's area vector and the line between the centres
// of its cells (internal faces). Skewness: how far the face centre lies from where that line
// crosses the face, over the distance from the face centre to its edge in that direction.
void orthogonality_and_skewness(const QualityPass& pass) {
  const PolyTopology& t = pass.t;
  PolyBuffers& b = pass.b;
  const std::size_t ni = pass.ni;
  const auto& fc = b.fc;
  const auto& fa = b.fa;
  const auto& cc = b.cc;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pass.nf, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t f = r.begin(); f < r.end(); ++f) {
      if (!pass.face_measured(f)) continue;
      const Vec3& own = cc[t.owner[f]];
      const Vec3 cpf = fc[f] - own;
      Vec3 d;
      double fd0;
      if (f < ni) {
        d = cc[t.neighbour[f]] - own;
        b.cosine[f] = d.dot(fa[f]) / (d.norm() * fa[f].norm() + kVSmall);
        fd0 = 0.2 * d.norm();
      } else {
        const Vec3 normal = fa[f] / (fa[f].norm() + kRootVSmall);
        d = normal * normal.dot(cpf);
        fd0 = 0.4 * d.norm();
      }
      const Vec3 sv = cpf - (fa[f].dot(cpf) / (fa[f].dot(d) + kRootVSmall)) * d;
      const Vec3 sv_hat = sv / (sv.norm() + kRootVSmall);
      double fd = fd0 + kRootVSmall;
      for (std::uint64_t k = t.face_start[f]; k < t.face_start[f + 1]; ++k)
        fd = std::max(fd, std::abs(sv_hat.dot(pass.points[t.face_points[k]] - fc[f])));
      b.skew[f] = sv.norm() / fd;
    }
  });
}

// Face pyramids (checkFacePyramids): the pyramid from each face to its owner's centre, and to
// its neighbour's, must not have negative volume (below -1e-15, checkMesh's threshold), the
// face's normal pointing away from the cell. Each bad pyramid counts, as in checkMesh; a cell
// with one is inverted. Cell determinant (primitiveMeshTools::cellDeterminant): how well a
// cell's faces span space.
void pyramids_and_determinants(const QualityPass& pass) {
  PolyBuffers& b = pass.b;
  const std::size_t ni = pass.ni;
  const auto& first = b.first;
  const auto& faces_of = b.faces_of;
  const auto& fc = b.fc;
  const auto& fa = b.fa;
  const auto& cc = b.cc;
  constexpr double kMinPyramid = -1e-15;
  const auto counted = [&](std::uint32_t f) {
    if (f < ni) return true;
    for (const auto& [begin, end] : b.coupled)
      if (f >= begin && f < end) return true;
    return false;
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pass.nc, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t c = r.begin(); c < r.end(); ++c) {
      if (!pass.cell_dirty(c)) continue;
      std::uint32_t bad = 0;
      double mean_area = 0;
      int n = 0;
      for (std::uint64_t k = first[c]; k < first[c + 1]; ++k) {
        const std::uint32_t f = faces_of[k] & 0x7fffffffu;
        const double pyr =
            (faces_of[k] & 0x80000000u) ? fa[f].dot(cc[c] - fc[f]) / 3.0 : fa[f].dot(fc[f] - cc[c]) / 3.0;
        if (pyr < kMinPyramid) ++bad;
        if (!counted(f)) continue;
        mean_area += fa[f].norm();
        ++n;
      }
      b.bad[c] = bad;
      double value = 0;
      if (n > 0 && mean_area >= kVSmall) {
        mean_area /= n;
        Eigen::Matrix3d tensor = Eigen::Matrix3d::Zero();
        for (std::uint64_t k = first[c]; k < first[c + 1]; ++k) {
          const std::uint32_t f = faces_of[k] & 0x7fffffffu;
          if (!counted(f)) continue;
          const Vec3 s = fa[f] / mean_area;
          tensor += s * s.transpose();
        }
        if (b.empty_axis >= 0) tensor(b.empty_axis, b.empty_axis) = 1;
        value = std::abs(tensor.determinant()) / 8;  // a cube inside the mesh: 1
      }
      b.det[c] = value;
    }
  });
}

// The reductions, over every face and cell.
void reduce_figures(const QualityPass& pass, PolyQuality& q) {
  const PolyBuffers& b = pass.b;
  const std::size_t ni = pass.ni, nc = pass.nc;
  const auto& vol = b.vol;
  q.min_volume = nc ? std::numeric_limits<double>::infinity() : 0.0;
  for (std::size_t c = 0; c < nc; ++c) {
    q.min_volume = std::min(q.min_volume, vol[c]);
    q.total_volume += vol[c];
    if (vol[c] <= kVSmall) ++q.negative_volumes;
    q.bad_pyramids += b.bad[c];
    if (vol[c] <= kVSmall || b.bad[c]) ++q.inverted_cells;
  }
  struct Acc {
    double min_cos = 1, sum_cos = 0, max_skew = 0;
  };
  const Acc acc = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, pass.nf, 4096), Acc{},
      [&](const tbb::blocked_range<std::size_t>& r, Acc a) {
        for (std::size_t f = r.begin(); f < r.end(); ++f) {
          if (f < ni) {
            a.min_cos = std::min(a.min_cos, b.cosine[f]);
            a.sum_cos += b.cosine[f];
          }
          a.max_skew = std::max(a.max_skew, b.skew[f]);
        }
        return a;
      },
      [](Acc x, const Acc& y) {
        x.min_cos = std::min(x.min_cos, y.min_cos);
        x.sum_cos += y.sum_cos;
        x.max_skew = std::max(x.max_skew, y.max_skew);
        return x;
      });
  // checkMesh's "average" is the angle of the mean cosine.
  const auto degrees = [](double c) { return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / std::numbers::pi; };
  q.max_non_orthogonality = ni ? degrees(acc.min_cos) : 0.0;
  q.mean_non_orthogonality = ni ? degrees(acc.sum_cos / double(ni)) : 0.0;
  q.max_skewness = acc.max_skew;
  struct Det {
    double min = std::numeric_limits<double>::infinity(), sum = 0;
  };
  const Det det = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, nc, 4096), Det{},
      [&](const tbb::blocked_range<std::size_t>& r, Det d) {
        for (std::size_t c = r.begin(); c < r.end(); ++c) {
          d.min = std::min(d.min, b.det[c]);
          d.sum += b.det[c];
        }
        return d;
      },
      [](Det x, const Det& y) {
        x.min = std::min(x.min, y.min);
        x.sum += y.sum;
        return x;
      });
  q.min_determinant = nc ? det.min : 0.0;
  q.mean_determinant = nc ? det.sum / double(nc) : 0.0;
}

}  // namespace

PolyQuality poly_quality(const PolyTopology& t, std::span<const Vec3> points, PolyBuffers& b, const Dirty* dirty) {
  PolyQuality q;
  const QualityPass pass{t, points, b, dirty, t.faces(), t.internal_faces(), t.cells};
  q.cells = pass.nc;
  q.faces = pass.nf;
  q.internal_faces = pass.ni;
  face_centres_and_areas(pass);
  index_cell_faces(pass);
  cell_centres_and_volumes(pass);
  orthogonality_and_skewness(pass);
  pyramids_and_determinants(pass);
  reduce_figures(pass, q);
  return q;
}

}  // namespace detail

PolyQuality poly_quality(const PolyTopology& t, std::span<const Vec3> points) {
  detail::PolyBuffers b;
  return detail::poly_quality(t, points, b);
}

MeshQuality mesh_quality(const VolumeMesh& mesh, std::span<const Vec3> points) {
  return QualityMeter(mesh).measure(points);
}

QualityMeter::QualityMeter(const VolumeMesh& mesh) : mesh_(&mesh), buffers_(std::make_unique<detail::PolyBuffers>()) {
  // The cell determinant's coupled faces and a 2-D mesh's missing direction, as checkMesh takes
  // them: processor and cyclic patches are coupled; the axis empty patches face is not a
  // geometric direction.
  Vec3 empty = Vec3::Zero();
  for (const Patch& p : mesh.patches) {
    if (p.face_end <= p.face_begin) continue;
    if (p.type.starts_with("processor") || p.type.starts_with("cyclic") || p.type.starts_with("nonConformalCyclic"))
      buffers_->coupled.emplace_back(p.face_begin, p.face_end);
    if (p.type != "empty") continue;
    for (std::uint64_t f = p.face_begin; f < p.face_end && f + 1 < mesh.poly.face_start.size(); ++f) {
      const std::uint32_t* v = mesh.poly.face_points.data() + mesh.poly.face_start[f];
      const std::size_t n = std::size_t(mesh.poly.face_start[f + 1] - mesh.poly.face_start[f]);
      if (n < 3) continue;
      Vec3 area = Vec3::Zero();
      for (std::size_t i = 0; i < n; ++i) area += mesh.points[v[i]].cross(mesh.points[v[(i + 1) % n]]);
      empty += area.cwiseAbs();
    }
  }
  if (empty.maxCoeff() > 0) empty.maxCoeff(&buffers_->empty_axis);
}
QualityMeter::~QualityMeter() = default;

MeshQuality QualityMeter::measure(std::span<const Vec3> points) {
  MeshQuality q;
  if (mesh_->poly.faces()) {
    // After a whole measure of the mesh's own points, a measure of moved points recomputes only
    // the faces and cells of points that differ from the mesh's, now or at the last measure: a
    // local morph's far cells keep their figures (exact locality), and a 4e5-point morph's second
    // measure takes a fraction of the first's. The result equals a whole measure's bit for bit
    // (BoxMorph.ALaterMeasureEqualsAWholeOne).
    detail::PolyBuffers& b = *buffers_;
    const PolyTopology& t = mesh_->poly;
    const std::span<const Vec3> own = mesh_->points;
    // b.touched holds a flag a point once a whole measure of as many points as the mesh's filled
    // the figures.
    if (b.touched.empty() || points.size() != own.size()) {
      q.poly = detail::poly_quality(t, points, b);
      const bool whole = points.size() == own.size();
      b.touched.assign(whole ? own.size() : 0, 0);
      if (whole)
        tbb::parallel_for(std::size_t(0), own.size(), [&](std::size_t i) { b.touched[i] = points[i] != own[i]; });
    } else {
      detail::Dirty d;
      d.face.assign(t.faces(), 0);
      d.cell.assign(t.cells, 0);
      std::vector<char> moved(own.size());
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, own.size(), 1 << 14),
                        [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i < r.end(); ++i) {
                            const bool now = points[i] != own[i];
                            moved[i] = now || b.touched[i];
                            b.touched[i] = now;
                          }
                        });
      const std::size_t ni = t.internal_faces();
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, t.faces(), 1 << 14),
                        [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t f = r.begin(); f < r.end(); ++f)
                            for (std::uint64_t k = t.face_start[f]; k < t.face_start[f + 1]; ++k)
                              if (moved[t.face_points[k]]) {
                                d.face[f] = 1;
                                break;
                              }
                        });
      for (std::size_t f = 0; f < t.faces(); ++f)
        if (d.face[f]) {
          d.cell[t.owner[f]] = 1;
          if (f < ni) d.cell[t.neighbour[f]] = 1;
        }
      q.poly = detail::poly_quality(t, points, b, &d);
    }
    // The first measure is the reference of the volume ratios of the later ones.
    auto& ref = buffers_->reference_volumes;
    const auto& vol = buffers_->vol;
    if (ref.empty()) {
      ref = vol;
    } else {
      double ratio = std::numeric_limits<double>::infinity();
      for (std::size_t c = 0; c < vol.size() && c < ref.size(); ++c)
        if (ref[c] > 1e-300) ratio = std::min(ratio, vol[c] / ref[c]);
      q.poly->min_volume_ratio = std::isfinite(ratio) ? ratio : 1.0;
    }
  }
  if (mesh_->cells.size()) {
    const auto measure_cells = detail::standard_formats().cell_quality;
    if (!measure_cells)
      throw io::FileError(
          "standard cells are measured through VTK, which this program is linked without (csrbf::morph_formats)");
    q.cells = measure_cells(mesh_->cells, points, mesh_->points);
  }
  return q;
}

}  // namespace csrbf::morph
