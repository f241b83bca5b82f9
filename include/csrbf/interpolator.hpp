// Scattered-data interpolation by compactly supported radial basis functions, in the shape of
// scipy.interpolate.RBFInterpolator: P points in D = 1, 2 or 3 dimensions, each with V values (a
// scalar, a vector, a tensor flattened), fitted once and evaluated anywhere:
//   s(x) = sum_i alpha_i phi(||x - x_i|| / R) + p(x),   s(x_i) + lambda_i alpha_i = f_i,
// phi a Wendland function (kernels.hpp), p a polynomial of degree -1 (none: strictly local), 0 or 1
// with P^T alpha = 0, lambda_i >= 0 the smoothing (0: interpolation). Each level is a kernel system
// (kernel_system.hpp), as a SpaceMap's fit is: one neighbour graph and factorisation for all V values.
//
// Multiscale (Floater & Iske 1996; Wendland, "Multiscale analysis in Sobolev spaces on bounded
// domains", 2010): a single radius either leaves a large error (few neighbours) or a dense system
// (many). With L levels, nested subsets X_1 c X_2 c ... c X_L = all points are thinned from the
// points (one a cell, cells halving each level, the point nearest the cell's centre, or its side on
// the points' boundary); level 1 fits the values on X_1 with a large radius, each next level fits
// what is left (the residual on X_l) with a radius half the one before (the finest, every point, a
// quarter), and s = s_1 + ... + s_L. The thinned levels have the same mean number of neighbours,
// the finest a quarter of it in 2-D, so every system is as sparse as a single-scale one.
//
// The Wendland functions phi_{3,k} are positive definite on R^d for d <= 3 (Wendland 1995,
// theorem 9.13 of "Scattered Data Approximation": phi_{d,k} is positive definite on R^d and so on
// every lower dimension), so the system is solvable for any distinct points in 1-D to 3-D. In R^4
// and above they are not positive definite in general, and D > 3 is refused.
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/units.hpp"

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace csrbf {

/// The mean number of neighbours within R that the automatic radius aims at: single scale, and
/// (kMultiscaleNeighbors) the thinned levels of a multiscale fit.
inline constexpr double kDefaultNeighbors = 40.0;
inline constexpr double kMultiscaleNeighbors = 50.0;
/// The most levels of a multiscale fit.
inline constexpr int kMaxLevels = 12;

struct InterpolatorOptions {
  /// The radius of support R in the points' units: of the only level, or of the finest level of a
  /// multiscale fit (the thinned levels have 4 R, 8 R, ...). 0: chosen so that a point has
  /// `neighbors` other points within R on average; with several levels, the finest has half that
  /// radius (about neighbors / 2^D), each thinned level about `neighbors`.
  double radius = 0.0;
  /// 0: kDefaultNeighbors single scale, kMultiscaleNeighbors with several levels.
  double neighbors = 0.0;
  Kernel kernel = Kernel::C2;
  int degree = -1;  ///< -1: no polynomial (strictly local); 0: a constant; 1: linear
  /// lambda: empty (0, interpolation), one value for every point, or one a point; each >= 0.
  std::vector<double> smoothing;
  /// 1: single scale; > 1: that many levels; 0: automatic (levels until the coarsest has about
  /// kCoarsestPoints points, at most kAutoLevels).
  int levels = 1;
  Solver solver = Solver::Auto;
  double memory_limit_bytes = 4.0 * kGiB;
};
/// The automatic multiscale choice: levels until the coarsest has at most this many points...
inline constexpr double kCoarsestPoints = 250.0;
/// ...and at most this many levels.
inline constexpr int kAutoLevels = 8;

/// One level of a fit: its points, radius and coefficients, and what its fit did.
struct InterpolatorLevel {
  double radius = 0;
  std::vector<double> points;  ///< n x D, row-major
  std::vector<double> alpha;   ///< n x V, row-major
  std::vector<double> beta;    ///< terms x V (terms = 0, 1 or 1 + D), in u = (x - center) / scale
  Vec3 center = Vec3::Zero();
  double scale = 1.0;
  // What the fit did (zero for a level rebuilt from its coefficients):
  double mean_neighbors = 0;
  Solver solver = Solver::Auto;
  std::size_t iterations = 0;    ///< CG's steps (the slowest block of right-hand sides)
  double residual_relative = 0;  ///< max |(A + Lambda) alpha + P beta - f| / max |f| on this level
  double rms_before = 0;         ///< RMS of the values this level fitted (the residual of those before)
  double seconds = 0;            ///< its fit, and the residual it passes on
};

/// A fitted interpolant. Immutable; copies share the fit; every const member is thread-safe.
class Interpolator {
 public:
  static constexpr int kMaxDimension = 3;
  Interpolator() = default;

  /// points: P x D row-major (D = dimension, 1..3); values: P x V row-major. Throws InvalidInput
  /// (naming the argument and the first bad element), DuplicateSource, DegeneratePolynomial,
  /// IllConditioned, NotPositiveDefinite or ResourceLimit.
  static Interpolator fit(std::span<const double> points, int dimension, std::span<const double> values,
                          std::size_t value_count, const InterpolatorOptions& options);
  /// An interpolant from its levels' coefficients (a fit stored and read back: pickling).
  static Interpolator from_levels(int dimension, std::size_t value_count, Kernel kernel, int degree,
                                  std::vector<InterpolatorLevel> levels, double seconds_fit = 0);

  /// s(x) for q points (q x D) into out (q x V). Float points and results are evaluated in float
  /// where each level's map trusts it (SpaceMap::float_trusted), else in double.
  void evaluate(const double* x, std::size_t q, double* out) const;
  void evaluate(const float* x, std::size_t q, float* out) const;
  /// ds/dx for q points into out (q x V x D: out[(i * V + v) * D + d] = d s_v / d x_d).
  void gradient(const double* x, std::size_t q, double* out) const;

  int dimension() const noexcept { return dim_; }
  std::size_t value_count() const noexcept { return values_; }
  std::size_t size() const noexcept;  ///< P, the points fitted
  Kernel kernel() const noexcept { return kernel_; }
  int degree() const noexcept { return degree_; }
  const std::vector<InterpolatorLevel>& levels() const noexcept { return *levels_; }
  double seconds_fit() const noexcept { return seconds_fit_; }

 private:
  int dim_ = 0;
  std::size_t values_ = 0;
  Kernel kernel_ = Kernel::C2;
  int degree_ = -1;
  double seconds_fit_ = 0;
  std::shared_ptr<const std::vector<InterpolatorLevel>> levels_;
  std::shared_ptr<const std::vector<std::vector<SpaceMap>>> maps_;  // [level][chunk of 3 values]
  template <class T>
  void evaluate_impl(const T* x, std::size_t q, T* out) const;
};

}  // namespace csrbf
