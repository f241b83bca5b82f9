// The fitted state behind a SpaceMap (private to csrbf::core): what depends on the sources only
// (Structure: the points and their neighbour grid, the polynomial's frame, and the kernel system with
// its factorisation and polynomial block), shared by every map made with with_destinations(), and
// what depends on the destinations too (State: the coefficients and the evaluation data). fit.cpp
// fits them; space_map.cpp evaluates them; csrbf::Interpolator's levels are maps over a Structure
// whose system is gone once they are solved.
#pragma once

#include "csrbf/kernel_system.hpp"
#include "csrbf/space_map.hpp"

#include "evaluator.hpp"
#include "point_cloud.hpp"

#include <memory>
#include <mutex>
#include <type_traits>
#include <vector>

namespace csrbf {

// Everything that depends on the sources only: shared by every map made with with_destinations().
struct SpaceMap::Structure {
  FitOptions options;
  std::shared_ptr<detail::PointCloud> cloud;  // the sources (input order), their index and grid
  /// The fitted system (A, its solver and polynomial block); null for a map made from a solution
  /// (from_solution, an interpolator's level): evaluation only.
  std::shared_ptr<KernelSystem> system;
  int terms = 0;               // the polynomial's terms (0, 1 or 4)
  Vec3 center = Vec3::Zero();  // polynomial coordinates u = (x - center) / scale
  double scale = 1.0;
  double poly_condition = 1.0;  // linear polynomial: the sources' largest over smallest singular value in u
  FitStats stats;               // the structural part and its times

  const std::vector<Vec3>& sources() const { return cloud->points; }
  const NeighborIndex& index() const { return cloud->index(); }
  const detail::EvalGrid& grid() const { return cloud->grid(); }
  bool solved_elsewhere() const { return !system; }
};

struct SpaceMap::State {
  std::shared_ptr<const Structure> st;
  std::vector<Vec3> destinations;
  Eigen::Matrix<double, Eigen::Dynamic, 3> alpha;  // input order
  // alpha in the index's slot order, for the simple path: made on first use.
  mutable std::once_flag slot_once;
  mutable std::vector<Vec3> alpha_by_slot_;
  const std::vector<Vec3>& alpha_by_slot() const {
    std::call_once(slot_once, [this] {
      const NeighborIndex& index = st->index();
      alpha_by_slot_.resize(index.size());
      for (std::size_t slot = 0; slot < alpha_by_slot_.size(); ++slot)
        alpha_by_slot_[slot] = alpha.row(Eigen::Index(index.original_index(slot))).transpose();
    });
    return alpha_by_slot_;
  }
  // The evaluation grid's runs with coordinates and alpha, made on first use of each precision.
  mutable std::once_flag once_double, once_float, once_float_trust, once_normals_trust;
  mutable bool float_ok = true;          // float evaluation agrees with double (float_trusted())
  mutable bool float_normals_ok = true;  // and its normals too (float_normals_trusted())
  mutable double float_error = 0;        // the largest difference measured
  mutable detail::EvalData<double> data_double;
  mutable detail::EvalData<float> data_float;
  template <class T>
  const detail::EvalData<T>& eval_data() const {
    auto& flag = std::is_same_v<T, double> ? once_double : once_float;
    auto& data = [this]() -> detail::EvalData<T>& {
      if constexpr (std::is_same_v<T, double>)
        return data_double;
      else
        return data_float;
    }();
    std::call_once(flag, [&] {
      const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> rows = alpha;
      data.assign(st->grid(), st->sources(), rows.data(), st->options.kernel);
    });
    return data;
  }
  detail::PolynomialPart poly;                                             // beta for the evaluator
  Eigen::Matrix<double, 4, 3> beta = Eigen::Matrix<double, 4, 3>::Zero();  // in u coordinates
  FitStats stats;

  /// p(x); beta's absent rows are zero, so this serves constant and linear alike.
  Vec3 polynomial_at(const Vec3& x) const {
    const Vec3 u = (x - st->center) / st->scale;
    return (beta.row(0) + u.transpose() * beta.bottomRows<3>()).transpose();
  }
};

}  // namespace csrbf
