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

FoldReport check_folds(const SpaceMap& map, std::span<const Vec3> vertices,
                       const std::vector<std::vector<std::uint32_t>>& faces, double phase) {
  check_phase(phase);
  std::vector<Vec3> points(vertices.begin(), vertices.end());
  for (const auto& f : faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      if (f[0] >= vertices.size() || f[k] >= vertices.size() || f[k + 1] >= vertices.size())
        throw InvalidInput("a face refers to vertex " +
                           std::to_string(std::max({f[0], f[k], f[k + 1]})) + " of " + std::to_string(vertices.size()));
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
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 256), [&](const tbb::blocked_range<std::size_t>& range) {
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

}  // namespace csrbf
