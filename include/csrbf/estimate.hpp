// What a fit will cost before it runs, and the radius that gives a wanted number of neighbours
// (`csrbf info --estimate`, csrbf.estimate and csrbf.suggest_radius in Python).
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/types.hpp"

#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace csrbf {

/// One solver's predicted peak memory and time for the fit, in the terms Auto weighs them
/// (fit_options.hpp): seconds are its multiply-adds at kSecondsPerCgMultiplyAdd (measured on this
/// project's 2-core machine: a step of CG over 1e6 controls on the sphere) plus the phases every
/// solver shares (the neighbour graph, A, the ordering) at kSecondsPerEntry a non-zero.
struct SolverEstimate {
  Solver solver = Solver::Cg;
  double bytes = 0;  ///< the fit's peak: graph or A, and the factor or CG's vectors
  /// The factor's entries below the diagonal (the envelope's; the nested-dissection factor's) and
  /// its multiply-adds or flops; for CG, A's off-diagonal entries and the work of kCgStepsEstimate
  /// steps. NaN where the graph was not built.
  double factor_entries = 0, work = 0;
  double seconds = 0;        ///< predicted wall time on 2 cores (scales about with 1 / cores)
  bool within_limit = true;  ///< bytes <= FitOptions::memory_limit_bytes
  std::string note;          ///< how the figure was come by, or why it is unknown
};

struct FitEstimate {
  std::size_t controls = 0;
  double radius = 0;
  double mean_neighbors = 0;  ///< other controls within R of a control
  double max_neighbors = 0;   ///< of the controls counted (every one where `exact`)
  double nonzeros = 0;        ///< of the N x N matrix A: N + N * mean_neighbors
  bool exact = false;         ///< the neighbour graph was built (else: a seeded sample of 256 controls)
  bool counted = false;       ///< mean and max counted over every control (where the graph was too large to build, too)
  std::vector<SolverEstimate> solvers;  ///< envelope, the general direct solver, CG (incomplete Cholesky)
  Solver chosen = Solver::Cg;           ///< what Solver::Auto starts with
};

/// The fit's size and each solver's cost for these sources at radius R. The neighbour graph, the
/// reverse Cuthill-McKee envelope and the nested-dissection factor count are computed exactly (about a
/// third of a fit's time) where the graph is predicted within options.memory_limit_bytes and
/// kEstimateExactEntries non-zeros (4e5 controls on a sphere at 23 neighbours: 1.4 s on 2 cores; at 1e6
/// the exact count took 4.7 s, most of a fit, and the sample takes 0.12 s, 20.7 neighbours against
/// 22.7); beyond that neighbours come from a sample and the direct solvers' figures are bounds. Throws InvalidInput for
/// a radius that is not positive and finite, or non-finite sources.
inline constexpr double kEstimateExactEntries = 1e7;
inline constexpr double kSecondsPerCgMultiplyAdd = 5.3e-10;
inline constexpr double kSecondsPerEntry = 1.5e-7;
FitEstimate estimate(std::span<const Vec3> sources, double radius, const FitOptions& options = {});

/// The radius R at which a control has `neighbours` other controls within R on average (> 0),
/// measured on a seeded sample of the controls (at most 4096; every one below): the distances to
/// their neighbours found once with the neighbour grid, R the one that many fall within (the
/// interpolator's radius="auto" measure; src/core/radius.cpp).
/// Throws InvalidInput where `neighbours` is not within (0, N - 1) or there are fewer than 2 sources.
double suggest_radius(std::span<const Vec3> sources, double neighbours);

}  // namespace csrbf
