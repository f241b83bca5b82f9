#include "csrbf/folds.hpp"

#include <oneapi/tbb/parallel_for.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <mutex>

namespace csrbf {

double first_fold_phase(const Eigen::Matrix3d& j1) {
  const Eigen::Matrix3d a = j1 - Eigen::Matrix3d::Identity();
  const double c1 = a.trace();
  const double c2 = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0) + a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0) + a(1, 1) * a(2, 2) -
                    a(1, 2) * a(2, 1);
  const double c3 = a.determinant();
  // p(t) = 1 + c1 t + c2 t^2 + c3 t^3. Its real roots are the eigenvalues of the companion matrix of
  // the reversed polynomial q(s) = s^3 + c1 s^2 + c2 s + c3 (s = 1/t), which stays well defined when
  // c3 (or c2) vanishes: those roots are s = 0, i.e. t at infinity.
  Eigen::Matrix3d comp = Eigen::Matrix3d::Zero();
  comp(0, 0) = -c1;
  comp(0, 1) = -c2;
  comp(0, 2) = -c3;
  comp(1, 0) = 1;
  comp(2, 1) = 1;
  const Eigen::Vector3cd s = comp.eigenvalues();
  double best = std::numeric_limits<double>::infinity();
  const double scale = 1 + std::abs(c1) + std::sqrt(std::abs(c2)) + std::cbrt(std::abs(c3));
  for (int i = 0; i < 3; ++i) {
    if (std::abs(s[i].imag()) > 1e-9 * scale || !(s[i].real() > 0)) continue;
    best = std::min(best, 1.0 / s[i].real());
  }
  return best;
}

FoldReport check_folds(const SpaceMap& map, std::span<const Vec3> vertices, const PolygonList& faces, double phase) {
  check_phase(phase);
  std::vector<Vec3> points(vertices.begin(), vertices.end());
  for (const auto& f : faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      if (f[0] >= vertices.size() || f[k] >= vertices.size() || f[k + 1] >= vertices.size())
        throw InvalidInput("a face refers to vertex " + std::to_string(std::max({f[0], f[k], f[k + 1]})) + " of " +
                           std::to_string(vertices.size()));
      const Vec3 &a = vertices[f[0]], &b = vertices[f[k]], &c = vertices[f[k + 1]];
      const Vec3 g = (a + b + c) / 3;
      points.push_back(g);
      for (const Vec3* v : {&a, &b, &c}) points.push_back((g + *v) / 2);
    }
  FoldReport r;
  r.phase = phase;
  r.vertices = vertices.size();
  r.samples = points.size();
  std::vector<double> det(points.size()), first(points.size());
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, points.size(), 256), [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          const Eigen::Matrix3d j1 = map.jacobian(points[i], 1.0);
          det[i] = (Eigen::Matrix3d::Identity() + phase * (j1 - Eigen::Matrix3d::Identity())).determinant();
          first[i] = first_fold_phase(j1);
        }
      });
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (det[i] < r.min_det) {
      r.min_det = det[i];
      r.min_at = points[i];
    }
    if (det[i] <= 0) {
      ++r.folded;
      if (i < vertices.size()) r.folded_vertices.push_back(std::uint32_t(i));
    }
    r.fold_free_phase = std::min(r.fold_free_phase, first[i]);
  }
  return r;
}

FoldReport check_folds_in_area(const SpaceMap& map, std::span<const Vec3> vertices, const PolygonList& faces,
                               const std::vector<std::uint32_t>& area, double phase) {
  check_phase(phase);
  constexpr std::uint32_t kOut = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> local(vertices.size(), kOut);  // index in the area, or kOut
  std::vector<Vec3> part;
  part.reserve(area.size());
  for (const auto v : area) {
    local.at(v) = std::uint32_t(part.size());
    part.push_back(vertices[v]);
  }
  std::vector<Vec3> moved(part.size());
  map.apply(part, moved, 1.0);  // displacement at phase 1: moved - part
  PolygonList inside;
  std::size_t edge = 0, flipped = 0;
  double first_flip = std::numeric_limits<double>::infinity();
  const auto disp = [&](std::uint32_t v) -> Vec3 {
    return local[v] == kOut ? Vec3::Zero() : Vec3(moved[local[v]] - part[local[v]]);
  };
  for (const auto& f : faces) {
    std::size_t in = 0;
    for (const auto v : f) in += local.at(v) != kOut;
    if (in == f.size()) {
      std::vector<std::uint32_t> g;
      for (const auto v : f) g.push_back(local[v]);
      inside.push_back(std::move(g));
      continue;
    }
    if (in == 0) continue;
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      const std::uint32_t a = f[0], b = f[k], c = f[k + 1];
      if (local[a] == kOut && local[b] == kOut && local[c] == kOut) continue;
      ++edge;
      // n(t) = (e1 + t g1) x (e2 + t g2); n(t) . n(0) = |n0|^2 + t n0.(e1 x g2 + g1 x e2) + t^2 n0.(g1 x g2).
      const Vec3 e1 = vertices[b] - vertices[a], e2 = vertices[c] - vertices[a];
      const Vec3 g1 = disp(b) - disp(a), g2 = disp(c) - disp(a);
      const Vec3 n0 = e1.cross(e2);
      const double c0 = n0.squaredNorm(), c1 = n0.dot(e1.cross(g2) + g1.cross(e2)), c2 = n0.dot(g1.cross(g2));
      if (!(c0 > 0)) continue;  // a degenerate triangle has no side to turn over
      if (c0 + phase * c1 + phase * phase * c2 <= 0) ++flipped;
      // The smallest positive root of c2 t^2 + c1 t + c0: the first phase at which it turns over.
      double root = std::numeric_limits<double>::infinity();
      if (c2 == 0) {
        if (c1 < 0) root = -c0 / c1;
      } else {
        const double disc = c1 * c1 - 4 * c2 * c0;
        if (disc >= 0) {
          const double s = std::sqrt(disc);
          for (const double t : {(-c1 - s) / (2 * c2), (-c1 + s) / (2 * c2)})
            if (t > 0) root = std::min(root, t);
        }
      }
      first_flip = std::min(first_flip, root);
    }
  }
  FoldReport r = check_folds(map, part, inside, phase);
  for (auto& v : r.folded_vertices) v = area[v];
  r.edge_triangles = edge;
  r.edge_flipped = flipped;
  r.fold_free_phase = std::min(r.fold_free_phase, first_flip);
  return r;
}

}  // namespace csrbf
