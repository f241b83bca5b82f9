// What a fit is asked to do (FitOptions) and the rules it follows: the polynomial part, the solver of
// the CSRBF system and Auto's choice among them, the accuracy a fit must reach, and its memory limit.
#pragma once

#include "csrbf/kernels.hpp"
#include "csrbf/ordering.hpp"
#include "csrbf/types.hpp"
#include "csrbf/units.hpp"

#include <cstddef>
#include <optional>
#include <span>
#include <string_view>

namespace csrbf {

/// The polynomial part p of the displacement: none (the plain CSRBF sum, strictly local: points
/// farther than R from every source do not move), a constant, or linear (the paper's choice: T
/// reproduces any affine map the controls admit).
enum class Polynomial { None, Constant, Linear };
/// "none", "constant", "linear" (the name table in names.hpp).
std::string_view polynomial_name(Polynomial p) noexcept;
std::optional<Polynomial> parse_polynomial(std::string_view name) noexcept;

/// The solver of the N x N CSRBF system A x = b.
enum class Solver {
  Envelope,  ///< the paper's: ordering + Jennings envelope Cholesky (envelope_cholesky.hpp)
  Eigen,     ///< Eigen's SimplicialLLT with AMD ordering
  Cholmod,   ///< SuiteSparse CHOLMOD, supernodal, in nested_dissection_order (only when csrbf was built with it)
  Auto,      ///< Envelope while its estimated work is small, then CG, CHOLMOD where CG stagnates
  Cg,        ///< conjugate gradients, the right-hand sides together, parallel products; no factor
};
/// "envelope", "eigen", "cholmod", "auto", "cg" (the name table in names.hpp).
std::string_view solver_name(Solver s) noexcept;
std::optional<Solver> parse_solver(std::string_view name) noexcept;
/// Whether this build of csrbf can use CHOLMOD.
bool cholmod_available() noexcept;

/// The largest relative residual at the controls a fit accepts (FitStats::residual_relative).
inline constexpr double kResidualLimit = 1e-6;
/// Float (single-precision) evaluation is used only where it agrees with double evaluation to this
/// fraction of the largest control displacement (beyond the rounding of the result to float):
/// measured once per map on (up to 4096 of) its sources and as many points between them, where it
/// must agree to a quarter of this; otherwise float inputs are evaluated in double and rounded once.
inline constexpr double kFloatTolerance = 1e-4;
/// The angle (radians) within which normals deformed in float (SpaceMap::apply_with_normals on
/// float arrays) follow the exact ones; the map falls back to double where a sample says otherwise.
inline constexpr double kFloatNormalRadians = 1e-5;
/// Solver::Cg stops at this relative residual ||b - A x|| / ||b|| for each right-hand side, and
/// gives up (a direct solver takes over) after kCgMaxIterations steps.
inline constexpr double kCgTolerance = 1e-12;
inline constexpr std::size_t kCgMaxIterations = 3000;
/// Auto's rule, by estimated and then measured cost (docs/PERFORMANCE.md, "Solvers"). Costs are
/// counted in CG multiply-adds: a CG step on 3 right-hand sides is 3 * (2 * neighbour pairs + N).
/// - The envelope solver where its factorisation's multiply-adds (sum over rows of (row length)^2 /
///   2, in reverse Cuthill-McKee order), at kEnvelopeCostRatio each, cost less than kCgStepsEstimate
///   CG steps, and are at most kEnvelopeWorkLimit.
/// - Else CG, which every kCgProbeSteps steps predicts the steps it still needs from the rate its
///   residual fell over the last two thirds of its steps, and gives way to the envelope solver where
///   that is cheaper (and within kEnvelopeWorkLimit). Once CG predicts more than kCgAnalyseSteps * sqrt(N)
///   steps to go, the general direct solver (CHOLMOD, else Eigen) is weighed: the column counts of
///   its factor in csrbf's nested dissection order (cholesky_factor_count) give its flops, at
///   kDirectFlopCost each, and CG gives way to it where it is cheaper by a margin of
///   1 + kCgProbeSteps / steps taken (CG's early predictions are the least sure). A direct factor
///   that would pass the memory limit (counted beside A and CG's copy of it, which live on) is never
///   chosen; the envelope solver is then weighed whatever its work, where it fits.
/// - A direct solver takes over wherever CG stagnates: CHOLMOD (else Eigen), then the envelope
///   solver where the limit refuses it; never CG again, which would stagnate again. Where the limit
///   refuses both, the error names CG's residual and what each would need.
/// CG took 41 to 230 steps on the sphere and 180 to 1600 in the cube (N = 1e3 ... 1e6). The ratios
/// were measured on the solvers sweep: an envelope multiply-add costs 0.3-0.6 of a CG one, a
/// CHOLMOD flop (its ordering and analysis included) 0.18-0.26.
inline constexpr double kEnvelopeWorkLimit = 1.0e8;
inline constexpr double kCgStepsEstimate = 100.0;
inline constexpr std::size_t kCgProbeSteps = 10;
inline constexpr double kCgAnalyseSteps = 1.0;
inline constexpr double kDirectFlopCost = 0.2;
inline constexpr double kEnvelopeCostRatio = 0.6;
/// The solver a fit uses: `requested`, or for Solver::Auto the rule above.
Solver resolve_solver(Solver requested, double envelope_work, std::size_t controls = 0,
                      std::size_t neighbor_pairs = 0) noexcept;

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
  double memory_limit_bytes = 4.0 * kGiB;
};

/// Estimated memory (bytes) of a fit's neighbour graph and factor, and the mean number of other
/// sources within R, from a seeded sample of at most 256 sources (exact up to 256 sources).
struct FitMemoryEstimate {
  double bytes = 0;
  double mean_neighbors = 0;
  double max_neighbors = 0;  ///< the most of a sampled source (scaled as the mean is)
};
FitMemoryEstimate estimate_fit_memory(std::span<const Vec3> sources, double radius);

}  // namespace csrbf
