// The CSRBF space mapping T: R^3 -> R^3 of the paper (Kojekine et al., sections 3-4):
//   T(x) = x + t * d(x),   d(x) = sum_i alpha_i phi(||x - s_i|| / R) + p(x),
// each coordinate of the displacement d an interpolant of g_i = destination_i - source_i at the
// sources s_i (eq. 1-3), phi a Wendland function (kernels.hpp) and p a polynomial: none (the plain
// CSRBF sum, strictly local: points farther than R from every source do not move), a constant, or a
// linear polynomial (the paper's choice: T reproduces any affine map the controls admit).
//
// Fit (paper section 4): neighbour index, breadth-first ordering, Jennings envelope Cholesky of A,
// then George & Liu's block elimination for the polynomial part:
//   A Y = P, A z = g, (P^T Y) beta = P^T z, alpha = z - Y beta.
#pragma once

#include "csrbf/envelope_cholesky.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/ordering.hpp"

#include <Eigen/Core>

#include <memory>
#include <optional>
#include <span>
#include <string_view>

namespace csrbf {

enum class Polynomial { None, Constant, Linear };
std::string_view polynomial_name(Polynomial p) noexcept;
std::optional<Polynomial> parse_polynomial(std::string_view name) noexcept;

/// The factorisation of the N x N CSRBF matrix A.
enum class Solver {
  Envelope,  ///< the paper's: ordering + Jennings envelope Cholesky (envelope_cholesky.hpp)
  Eigen,     ///< Eigen's SimplicialLLT with AMD ordering
  Cholmod,   ///< SuiteSparse CHOLMOD, supernodal, in nested_dissection_order (only when csrbf was built with it)
  Auto,      ///< Envelope while its estimated work is small, then CG, CHOLMOD where CG stagnates
  Cg,        ///< conjugate gradients, the right-hand sides together, parallel products; no factor
};
std::string_view solver_name(Solver s) noexcept;
std::optional<Solver> parse_solver(std::string_view name) noexcept;
/// Whether this build of csrbf can use CHOLMOD.
bool cholmod_available() noexcept;
/// The largest relative residual at the controls a fit accepts (FitStats::residual_relative).
inline constexpr double kResidualLimit = 1e-6;
/// Float (single-precision) evaluation is used only where it agrees with double evaluation to this
/// fraction of the largest control displacement, measured once per map on (up to 4096 of) its
/// sources; otherwise float inputs are evaluated in double and rounded once.
inline constexpr double kFloatTolerance = 1e-4;
/// Solver::Cg stops at this relative residual ||b - A x|| / ||b|| for each right-hand side, and
/// gives up (a direct solver takes over) after kCgMaxIterations steps.
inline constexpr double kCgTolerance = 1e-12;
inline constexpr std::size_t kCgMaxIterations = 3000;
/// Auto's rule, by estimated cost: the envelope solver while the multiply-adds of its factorisation
/// (sum over rows of (row length)^2 / 2) stay below those of kCgStepsEstimate conjugate-gradient
/// steps on 3 right-hand sides (each step a product with A: 2 * neighbour pairs + N entries) and at
/// most kEnvelopeWorkLimit; else CG, with CHOLMOD (or Eigen) taking over where CG stagnates or, under
/// Auto, once CG has spent a tenth of the envelope's work (at least 50 steps). CG took 28 to 230
/// steps on the sphere sweep; the crossover measured between N = 300 and 600 (docs/PERFORMANCE.md).
inline constexpr double kEnvelopeWorkLimit = 1.0e8;
inline constexpr double kCgStepsEstimate = 50.0;
/// The solver a fit uses: `requested`, or for Solver::Auto the rule above.
Solver resolve_solver(Solver requested, double envelope_work, std::size_t controls = 0,
                      std::size_t neighbor_pairs = 0) noexcept;

/// The inner loop of SpaceMap::apply(): the portable one, compiled for x86-64-v3 (AVX2 + FMA) and for
/// baseline x86-64 and picked at load time, or hand-written AVX-512 where the CPU and the build have
/// it (the default there). Both are held to the simple path by tests.
enum class EvaluationLoop { Auto, Portable, Avx512 };
/// Selects the loop for the whole process (for benchmarks and comparisons). Avx512 where it is not
/// available throws InvalidInput.
void set_evaluation_loop(EvaluationLoop loop);
/// The loop apply() runs now: "avx512", "avx2" (the portable loop's AVX2 + FMA clone) or "baseline".
std::string_view evaluation_loop_name() noexcept;

struct FitOptions {
  double radius = 0.0;  ///< support radius R in the points' units (not squared), > 0
  Kernel kernel = Kernel::C2;
  Polynomial polynomial = Polynomial::None;
  Ordering ordering = Ordering::Auto;  ///< of the envelope solver (the sparse solvers order themselves)
  Solver solver = Solver::Auto;
  /// The fit refuses (throws ResourceLimit) when it would need more memory than this: first from an
  /// estimate of the neighbour graph, matrix and factor (a sample of the sources) before anything
  /// large is built, then from the exact envelope of the chosen ordering or the factor size the
  /// sparse solver's symbolic analysis predicts, before the factorisation. A radius near the
  /// model's size makes the matrix dense, N^2 entries. Must be > 0 (NaN is refused).
  double memory_limit_bytes = 4.0 * (1ull << 30);
};

/// Estimated memory (bytes) of a fit's neighbour graph and factor, and the mean number of other
/// sources within R, from a seeded sample of at most 256 sources (exact up to 256 sources).
struct FitMemoryEstimate {
  double bytes = 0;
  double mean_neighbors = 0;
};
FitMemoryEstimate estimate_fit_memory(std::span<const Vec3> sources, double radius);

/// What a fit did and what it cost. Times are wall-clock seconds of each phase.
struct FitStats {
  std::size_t controls = 0;
  std::size_t neighbor_pairs = 0;        ///< unordered pairs of sources closer than R
  double mean_neighbors = 0.0;           ///< mean number of other sources within R of a source
  Ordering ordering = Ordering::Auto;    ///< the ordering used
  Profile identity, breadth_first, reverse_breadth_first, reverse_cuthill_mckee;
  std::size_t bandwidth = 0;             ///< of the ordered matrix
  std::size_t envelope_entries = 0;      ///< off-diagonal entries stored
  std::size_t envelope_bytes = 0;        ///< paper's accounting: 4-byte floats + 4-byte indices
  std::size_t dense_bytes = 0;           ///< N^2 * 4, the paper's dense float storage
  double envelope_work = 0.0;            ///< multiply-adds of the envelope factorisation (estimate)
  Solver solver = Solver::Envelope;      ///< the solver used
  std::size_t factor_nonzeros = 0;       ///< entries of the factor L actually stored (CG: of A)
  std::size_t iterations = 0;            ///< CG: steps of the last solve (the slowest right-hand side)
  double solver_residual = 0.0;          ///< CG: its final relative residual ||b - A x|| / ||b||
  bool fell_back = false;                ///< CG stagnated; `solver` is the direct solver that took over
  double residual_max = 0.0;             ///< max_i ||s(x_i) - g_i|| at the controls
  double residual_relative = 0.0;        ///< residual_max / max_i ||g_i|| (or residual_max if g = 0);
                                         ///< at most kResidualLimit, or the fit throws IllConditioned
  double seconds_index = 0, seconds_graph = 0, seconds_ordering = 0, seconds_assembly = 0,
         seconds_factorization = 0, seconds_solve = 0, seconds_residual = 0;
  double seconds_total() const noexcept {
    return seconds_index + seconds_graph + seconds_ordering + seconds_assembly + seconds_factorization +
           seconds_solve + seconds_residual;
  }
};

/// An immutable fitted mapping. Copies share the fitted state (cheap); every const member is
/// thread-safe. Buffers passed to apply() are borrowed for the call only.
class SpaceMap {
 public:
  /// sources and destinations: N points each, N >= 1, finite, sources pairwise distinct.
  /// Throws InvalidInput, DuplicateSource, DegeneratePolynomial or NotPositiveDefinite.
  static SpaceMap fit(std::span<const Vec3> sources, std::span<const Vec3> destinations,
                      const FitOptions& options);

  /// The same sources, radius, kernel and polynomial with new destinations: reuses the neighbour
  /// index, ordering and factorisation, so only the substitutions are redone.
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
  /// evaluation to kFloatTolerance of the largest displacement on the sources (measured once, on
  /// first use); false sends float inputs through double evaluation. Thread-safe.
  bool float_trusted() const;
  /// An estimate of the 2-norm condition number of the N x N CSRBF matrix A, lambda_max / lambda_min
  /// (power iteration and inverse iteration through the factorisation, 30 steps each). Computed on
  /// first call and kept; thread-safe.
  double condition_estimate() const;
  const NeighborIndex& index() const;

 private:
  struct Structure;
  struct State;
  explicit SpaceMap(std::shared_ptr<const State> s) : s_(std::move(s)) {}
  SpaceMap solve_destinations(std::span<const Vec3> destinations) const;  // sizes and values already checked
  template <class T> void apply_impl(const T* in, T* out, std::size_t n, double phase, bool add_point) const;
  template <class T> void apply_direct(const T* in, T* out, std::size_t n, double phase, bool add_point) const;
  std::shared_ptr<const State> s_;
};

/// The CSRBF matrix A = [phi(||s_i - s_j|| / R)] of a neighbour graph in Jennings envelope form,
/// row k being the source order[k] (unfactorised).
EnvelopeMatrix kernel_matrix(const AdjacencyGraph& g, std::span<const std::uint32_t> order, Kernel kernel,
                             double radius);
/// The same with the envelope's first columns already known (envelope_first_columns(g, order)).
EnvelopeMatrix kernel_matrix(const AdjacencyGraph& g, std::span<const std::uint32_t> order,
                             std::vector<std::size_t> first_columns, Kernel kernel, double radius);

/// One-off use: fit and apply in one call (points interleaved n x 3, in place).
void deform(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options,
            double* points, std::size_t n, double phase = 1.0);

}  // namespace csrbf
