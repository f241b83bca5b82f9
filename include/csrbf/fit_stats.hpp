// What a fit did and what each of its phases cost (SpaceMap::stats(), `csrbf info`).
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/ordering.hpp"

#include <cstddef>

namespace csrbf {

struct FitStats {
  std::size_t controls = 0;
  std::size_t neighbor_pairs = 0;      ///< unordered pairs of sources closer than R
  double mean_neighbors = 0.0;         ///< mean number of other sources within R of a source
  Ordering ordering = Ordering::Auto;  ///< the ordering of the envelope solver, or of CG's rows
  /// The profiles of the four orderings: set when they were compared (the envelope solver with
  /// Ordering::Auto); otherwise only the one that was computed is set.
  Profile identity, breadth_first, reverse_breadth_first, reverse_cuthill_mckee;
  bool orderings_compared = false;
  std::size_t bandwidth = 0;         ///< of the ordered matrix
  std::size_t envelope_entries = 0;  ///< off-diagonal entries stored
  std::size_t envelope_bytes = 0;    ///< paper's accounting: 4-byte floats + 4-byte indices
  std::size_t dense_bytes = 0;       ///< N^2 * 4, the paper's dense float storage
  double envelope_work = 0.0;        ///< multiply-adds of the envelope factorisation (estimate)
  Solver solver = Solver::Envelope;  ///< the solver used
  std::size_t factor_nonzeros = 0;   ///< entries of the factor L actually stored (CG: of A)
  std::size_t iterations = 0;        ///< CG: steps of the last solve (the slowest right-hand side)
  double solver_residual = 0.0;      ///< CG: its final relative residual ||b - A x|| / ||b||
  bool warm_start = false;           ///< CG started from the previous solution (with_destinations)
  bool fell_back = false;            ///< CG stagnated; `solver` is the direct solver that took over
  double residual_max = 0.0;         ///< max_i ||s(x_i) - g_i|| at the controls
  double residual_relative = 0.0;    ///< residual_max / max_i ||g_i|| (or residual_max if g = 0);
                                     ///< at most kResidualLimit, or the fit throws IllConditioned
  /// Wall-clock seconds of each phase: the neighbour index, the graph, the ordering, the assembly of
  /// A, its factorisation, the solves (polynomial block and displacements), the residual check.
  double seconds_index = 0, seconds_graph = 0, seconds_ordering = 0, seconds_assembly = 0, seconds_factorization = 0,
         seconds_solve = 0, seconds_residual = 0;
  double seconds_total() const noexcept {
    return seconds_index + seconds_graph + seconds_ordering + seconds_assembly + seconds_factorization + seconds_solve +
           seconds_residual;
  }
};

}  // namespace csrbf
