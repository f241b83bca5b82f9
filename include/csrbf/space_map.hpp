// The CSRBF space mapping T: R^3 -> R^3 of the paper (Kojekine et al., sections 3-4):
//   T(x) = x + t * d(x),   d(x) = sum_i alpha_i phi(||x - s_i|| / R) + p(x),
// each coordinate of the displacement d an interpolant of g_i = destination_i - source_i at the
// sources s_i (eq. 1-3), phi a Wendland function (kernels.hpp) and p a polynomial (fit_options.hpp).
//
// SpaceMap::fit (fit.cpp) is three values in 3-D over the kernel system (kernel_system.hpp), which
// runs the paper's phases (section 4): neighbour graph (neighbor_index, evaluator: the grid's cell
// lists) -> ordering (ordering.cpp) -> the matrix A (kernel_matrix.cpp) -> factorisation
// (envelope_cholesky, sparse_solver: CHOLMOD, Eigen, or CG with no factor) -> polynomial block ->
// solve -> residual check. The polynomial block is George & Liu's block elimination:
//   A Y = P, A z = g, (P^T Y) beta = P^T z, alpha = z - Y beta.
// The fit adds its own checks: the sources and the polynomial before any work, the linear part's
// amplification, and the residual through the evaluation where the coefficients are large.
// Evaluation (space_map.cpp, evaluator*.cpp) runs through the neighbour grid.
#pragma once

#include "csrbf/errors.hpp"
#include "csrbf/fit_options.hpp"
#include "csrbf/fit_stats.hpp"
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/types.hpp"

#include <Eigen/Core>

#include <memory>
#include <span>
#include <string_view>

namespace csrbf {

/// The inner loop of SpaceMap::apply(): the portable one, compiled for x86-64-v3 (AVX2 + FMA) and for
/// baseline x86-64 and picked at load time, or hand-written AVX-512 where the CPU and the build have
/// it (the default there). Both are held to the simple path by tests.
enum class EvaluationLoop { Auto, Portable, Avx512 };
/// Selects the loop for the whole process (for benchmarks and comparisons). Avx512 where it is not
/// available throws InvalidInput.
void set_evaluation_loop(EvaluationLoop loop);
/// The loop apply() runs now: "avx512", "avx2" (the portable loop's AVX2 + FMA clone) or "baseline".
std::string_view evaluation_loop_name() noexcept;

/// An immutable fitted mapping. Copies share the fitted state (cheap); every const member is
/// thread-safe. Buffers passed to apply() are borrowed for the call only.
class SpaceMap {
 public:
  /// sources and destinations: N points each, N >= 1, finite, sources pairwise distinct.
  /// Throws InvalidInput, DuplicateSource, DegeneratePolynomial or NotPositiveDefinite.
  static SpaceMap fit(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options);

  /// A mapping whose coefficients were solved elsewhere (csrbf::mpi's distributed fit): sources and
  /// their alpha (N x 3), and the polynomial's beta in the coordinates u = (x - center) / scale (row 0
  /// constant, rows 1-3 linear, zero where absent). Evaluation only, through the same grid and loops
  /// as a fitted map: it has no matrix, so with_destinations() and condition_estimate() throw
  /// InvalidInput; destinations() is empty. N may be 0 (the polynomial alone).
  ///
  /// points: how many points the map will evaluate in all, where the caller knows (0: unknown, as
  /// for a map played over many frames). Fewer than kFineGridPointsPerSource a source, and the
  /// evaluation builds cells of side R instead of R/2: a quarter of the memory and 5-10x less time to
  /// build (about 15 us a source less), for 10-50 ns more a point, which that many points do not win
  /// back (measured at N = 1e4 and 5e4, one thread).
  static SpaceMap from_solution(std::span<const Vec3> sources, const Eigen::Matrix<double, Eigen::Dynamic, 3>& alpha,
                                const Eigen::Matrix<double, 4, 3>& beta, const Vec3& center, double scale,
                                const FitOptions& options, std::size_t points = 0);
  static constexpr std::size_t kFineGridPointsPerSource = 1000;
  /// The same sources, radius, kernel and polynomial with new destinations: reuses the neighbour
  /// index, the matrix, its ordering and factorisation, so only the solve is redone (by CG, started
  /// from this map's solution: an animation frame that moves the destinations a little converges in
  /// fewer steps).
  SpaceMap with_destinations(std::span<const Vec3> destinations) const;

  /// d(x), the full displacement (phase 1).
  Vec3 displacement(const Vec3& x) const;
  /// T(x) = x + phase * d(x).
  Vec3 map(const Vec3& x, double phase = 1.0) const {
    check_phase(phase);
    return x + phase * displacement(x);
  }
  /// dT/dx at x: I + phase * dd/dx (row a, column b = d T_a / d x_b).
  Eigen::Matrix3d jacobian(const Vec3& x, double phase = 1.0) const;

  /// out = in + phase * d(in) for n points stored as interleaved xyz (n x 3, row-major). in and out
  /// may be the same buffer. Runs in parallel over points. phase is normally in [0, 1].
  void apply(const double* in, double* out, std::size_t n, double phase = 1.0) const;
  void apply(const float* in, float* out, std::size_t n, double phase = 1.0) const;
  void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase = 1.0) const;
  /// out = in + phase * d(in) for n interleaved points, with the map's Jacobian J = dT/dx at each:
  /// normals_in (n x 3, may be null) go to normals_out as J^-T n (the normal of the deformed
  /// surface, exact, not a blend; of det J's sign, so a folded surface keeps its side), scaled to
  /// the length of n, or to 1 where unit_normals; jacobians (n x 9, row-major, may be null)
  /// receives J. Any output may be its input's buffer. In parallel over points; float arrays are
  /// evaluated in float where the map's float check passes (as apply), else in double.
  void apply_with_normals(const double* in, double* out, std::size_t n, double phase, const double* normals_in,
                          double* normals_out, double* jacobians = nullptr, bool unit_normals = false) const;
  void apply_with_normals(const float* in, float* out, std::size_t n, double phase, const float* normals_in,
                          float* normals_out, float* jacobians = nullptr, bool unit_normals = false) const;
  /// d(in) for n interleaved points into out (n x 3).
  void displacements(const double* in, double* out, std::size_t n) const;
  void displacements(const float* in, float* out, std::size_t n) const;

  std::size_t size() const noexcept;
  double radius() const noexcept;
  Kernel kernel() const noexcept;
  Polynomial polynomial() const noexcept;
  std::span<const Vec3> sources() const noexcept;
  std::span<const Vec3> destinations() const noexcept;
  /// alpha, N x 3, in the input order of the sources.
  const Eigen::Matrix<double, Eigen::Dynamic, 3>& coefficients() const noexcept;
  /// The polynomial as p(x) = b0 + B x: row 0 is b0, rows 1..3 are B^T (zero where absent).
  Eigen::Matrix<double, 4, 3> polynomial_coefficients() const noexcept;
  /// order[k] = input index of the source at position k of the factorised matrix.
  std::span<const std::uint32_t> order() const noexcept;
  const FitStats& stats() const noexcept;
  /// Whether float inputs are evaluated in single precision: true when that agrees with double
  /// evaluation to a quarter of kFloatTolerance of the largest displacement on the sources and
  /// points between them (measured once, on first use); false sends float inputs through double
  /// evaluation. Thread-safe.
  bool float_trusted() const;
  /// Whether float normals (apply_with_normals on float arrays) agree with double ones within
  /// kFloatNormalRadians / 4 on the same sample as float_trusted (where float_trusted holds too).
  /// Where not, float arrays are evaluated in double.
  bool float_normals_trusted() const;
  /// An estimate of the 2-norm condition number of the N x N CSRBF matrix A, lambda_max / lambda_min
  /// (power iteration and inverse iteration through the factorisation, 30 steps each). Computed on
  /// first call and kept; thread-safe.
  double condition_estimate() const;
  const NeighborIndex& index() const;
  /// The CSRBF matrix A of the sources (input order), as the fit built it.
  const KernelMatrix& matrix() const noexcept;

  /// The fitted state (src/core/fit_state.hpp): private to csrbf's core. csrbf::Interpolator's levels
  /// are maps over states it builds from its own solutions.
  struct Structure;
  struct State;
  /// For csrbf's core: a map over a fitted state.
  explicit SpaceMap(std::shared_ptr<const State> s) : s_(std::move(s)) {}

 private:
  SpaceMap solve_destinations(std::span<const Vec3> destinations) const;  // sizes and values already checked
  template <class T>
  void apply_impl(const T* in, T* out, std::size_t n, double phase, bool add_point) const;
  template <class T>
  void apply_direct(const T* in, T* out, std::size_t n, double phase, bool add_point) const;
  template <class T>
  void normals_impl(const T* in, T* out, std::size_t n, double phase, const T* normals_in, T* normals_out, T* jacobians,
                    bool unit) const;
  std::shared_ptr<const State> s_;
};

/// One-off use: fit and apply in one call (points interleaved n x 3, in place).
void deform(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options,
            double* points, std::size_t n, double phase = 1.0);

}  // namespace csrbf
