// The fitted state behind a SpaceMap (private to csrbf::core): what depends on the sources only
// (Structure: the matrix, its factorisation, the polynomial block), shared by every map made with
// with_destinations(), and what depends on the destinations too (State: the coefficients and the
// evaluation data). fit.cpp fills them phase by phase; space_map.cpp evaluates them.
#pragma once

#include "csrbf/space_map.hpp"

#include "evaluator.hpp"
#include "sparse_solver.hpp"

#include <Eigen/Cholesky>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <type_traits>
#include <vector>

namespace csrbf {

// The most memory the evaluation lists of one fit may take (evaluator.hpp), and never more than
// what the fit's own predicted memory leaves of FitOptions::memory_limit_bytes; past it, evaluation
// goes through NeighborIndex.
inline constexpr std::size_t kEvalListBytes = std::size_t(512) << 20;

namespace detail {
/// Coordinates (and so distances) stay below this, so that their squares are finite.
inline constexpr double kMaxCoordinate = 1e150;
/// InvalidInput naming `what` and its index where a point is not finite or beyond kMaxCoordinate:
/// the fit's check of its sources and destinations, and estimate()'s of the sources.
void check_points(std::span<const Vec3> pts, const char* what);
}  // namespace detail

// Everything that depends on the sources only: shared by every map made with with_destinations().
struct SpaceMap::Structure {
  FitOptions options;
  std::vector<Vec3> sources;  // input order
  // Over the sources: built on first use (the simple path, the Jacobian) unless the fit needs it
  // (when the evaluation grid is unusable).
  mutable std::once_flag index_once;
  mutable NeighborIndex index_;
  const NeighborIndex& index() const {
    std::call_once(index_once, [this] { index_ = NeighborIndex(sources, options.radius); });
    return index_;
  }
  // The evaluation grid (evaluator.hpp): built by the fit when its lists give the neighbour graph
  // (N > kBruteForceGraph), else on first evaluation.
  mutable std::once_flag grid_once;
  mutable detail::EvalGrid grid_;
  int max_subdivision = detail::EvalGrid::kMaxSubdivision;  // from_solution: 1 for a map evaluated over few points
  /// csrbf::Interpolator's points of 1 or 2 dimensions: the axes from `dims` on are 0 for every source
  /// and every point evaluated (EvalGrid::build).
  int dims = 3;
  /// The most the evaluation lists may take: kEvalListBytes for a SpaceMap; csrbf::Interpolator's
  /// levels, whose lists are their evaluation, take up to what the memory limit leaves (1e6 2-D
  /// points: 650 MB, which 512 MB sent through NeighborIndex at 40x the time).
  std::size_t eval_list_bytes = kEvalListBytes;
  double fit_bytes = 0;  // the fit's predicted memory (graph, matrix, factor), set before the grid is built
  /// CG's preconditioner, where a solve needs one: additive Schwarz over patches of the sources
  /// (csrbf::Interpolator's scattered points, schwarz.hpp), else the incomplete Cholesky.
  bool cg_schwarz = false;
  /// The sources are already in the Schwarz patches' order (schwarz_order: the interpolator sorts a
  /// level's points so before its graph is built). Where CG takes the Schwarz path, its order is
  /// then the identity and it reads A in place (cg_in_place) instead of copying A's rows.
  bool schwarz_sorted = false;
  bool cg_in_place = false;
  double schwarz_bytes = 0;  // what CG with the Schwarz patches would hold, where they apply (0: they do not)
  /// A and what CG holds beside it (its rows where it copies them, vectors and preconditioner;
  /// Schwarz's copy of the sources): what a fit by CG holds.
  double cg_total_bytes() const {
    return detail::kernel_matrix_bytes(a) +
           detail::cg_bytes(a.values().size(), sources.size(), cg_schwarz, !cg_in_place);
  }
  const detail::EvalGrid& grid() const {
    std::call_once(grid_once, [this] {
      const double left = options.memory_limit_bytes - fit_bytes;
      const std::size_t budget = left >= double(eval_list_bytes) ? eval_list_bytes : left > 0 ? std::size_t(left) : 0;
      grid_ = detail::EvalGrid::build(sources, options.radius, budget, max_subdivision, dims);
    });
    return grid_;
  }
  KernelMatrix a;                                // A, input order: its pattern is the neighbour graph
  std::vector<std::uint32_t> order;              // order[k] = input index of the source at row k
  std::vector<std::size_t> first_columns;        // of the envelope in `order`, until it is assembled
  EnvelopeMatrix factor;                         // L, in `order` (Solver::Envelope)
  std::unique_ptr<detail::SparseFactor> sparse;  // the other solvers (then `order` is the identity)
  std::vector<std::uint32_t> cg_rows;            // CG's row order (RCM), for the solver that may take over
  int terms = 0;                                 // columns of P
  Vec3 center = Vec3::Zero();                    // polynomial coordinates u = (x - center) / scale
  double scale = 1.0;
  double poly_condition = 1.0;        // linear polynomial: the sources' largest over smallest singular value in u
  RowMatrix p;                        // N x terms, in `order`
  RowMatrix y;                        // A^{-1} P, in `order`
  Eigen::LLT<Eigen::MatrixXd> schur;  // P^T A^{-1} P
  FitStats stats;                     // the structural part and its times
  bool solved_elsewhere = false;      // SpaceMap::from_solution: no matrix, no factor
  /// csrbf::Interpolator's smoothing: A + diag(shift) (one value, or one a source; empty: none).
  /// Sources at one position are allowed where both are shifted (> 0).
  std::vector<double> diagonal_shift;

  /// b = A^-1 b (input order); CG starts from `initial` where it is given.
  void solve_in_place(RowMatrix& b, const RowMatrix* initial = nullptr) const {
    if (!sparse) {
      factor.solve_in_place(b);
      return;
    }
    if (!fell_back.load()) {
      double predicted = 0;
      std::size_t taken = 0;
      bool gave_way = false;
      std::string why;
      try {
        sparse->solve_in_place(b, initial);  // CG writes b only when it converged
        return;
      } catch (const detail::CgStagnated& e) {
        predicted = e.predicted_steps();
        taken = e.steps_taken();
        gave_way = e.gave_way();
        why = e.what();
      }
      // CG stagnated, or Auto's probe found it slower than a direct solve: another solver takes
      // over, once, for this fit and every later solve with these sources.
      std::call_once(fallback_once, [&] {
        // CG that stagnated never runs again: its copy of A makes room for the solver that takes
        // over (face.obj, 6158 controls, R = 1.5: the envelope was refused beside it under 1 GiB).
        // Where it gave way, it is kept until another solver has taken over (else it goes on).
        // Outside take_over's lock: a solve still in CG may wait for that lock in its probe.
        if (!gave_way) sparse->release();
        take_over(predicted, taken, gave_way, why);
        if (fallback) sparse->release();
      });
    }
    after().solve_in_place(b, initial);
  }
  /// The solver after CG gave way: the one that took over, or CG itself without its probe.
  const detail::SparseFactor& after() const { return fallback ? *fallback : *sparse; }
  /// Whether solves start from an initial guess (CG, or CG again after a direct solver was refused).
  bool warm_starts() const { return fell_back.load() ? after().iterative() : sparse && sparse->iterative(); }
  /// Multiply-adds of one CG step over all the solves of a fit: 3 right-hand sides, and the
  /// polynomial block's.
  double cg_step_work() const {
    return (2.0 * double(stats.neighbor_pairs) + double(sources.size())) * double(3 + terms);
  }
  /// Auto's direct solver (CHOLMOD, else Eigen), weighed while CG runs: its factorisation's cost in
  /// CG multiply-adds (kDirectFlopCost a flop), from the factor's column counts in csrbf's nested
  /// dissection order, or infinity where the factor would pass the memory limit. The count's time
  /// stays in the solve that made it.
  double direct_cost() const {
    std::lock_guard lock(direct_mutex);  // CG's probe in one solve, take_over after another's
    return tbb::this_task_arena::isolate([&] { return direct_cost_locked(); });
  }
  mutable std::mutex direct_mutex;
  mutable double direct_cost_ = -1;  // < 0: not counted yet
  double direct_cost_locked() const {
    if (direct_cost_ < 0) {
      // Values and row indices of L (12 bytes an entry), as the solvers' own analyses check them, beside
      // A, CG's copy of it (which lives on while the direct solver takes over) and the direct solver's
      // two copies of A's lower triangle: the count stops where the factor passes the memory limit
      // (infinite cost).
      const std::size_t lower = a.values().size() / 2 + sources.size();
      const double beside = cg_total_bytes() + 2 * 12.0 * double(lower);
      if (beside >= options.memory_limit_bytes)
        direct_cost_ = std::numeric_limits<double>::infinity();
      else
        direct_cost_ = kDirectFlopCost *
                       cholesky_factor_count(a.pattern(), nested_dissection_order(a.pattern(), sources, options.radius),
                                             (options.memory_limit_bytes - beside) / 12.0)
                           .flops;
    }
    return direct_cost_;
  }

  /// After CG took `taken` steps. Where Auto's probe made it give way: the envelope solver where its
  /// work (at kEnvelopeCostRatio) is below what CG was predicted to need, within kEnvelopeWorkLimit
  /// and below the direct solver's as weighed; else the direct solver (CHOLMOD, or Eigen); and where
  /// the memory limit refuses them, CG goes on without the probe. Where CG stagnated (or a CG asked
  /// for by name), the direct solver, then the envelope solver whatever its work: CG again would
  /// stagnate again. Each counts what CG still holds beside it: nothing where CG stagnated (its copy
  /// of A was freed first), its copy where it gave way (it goes on if every other is refused).
  void take_over(double predicted_steps, std::size_t taken, bool gave_way, const std::string& why) const {
    std::lock_guard lock(direct_mutex);
    tbb::this_task_arena::isolate([&] { take_over_locked(predicted_steps, taken, gave_way, why); });
  }
  void take_over_locked(double predicted_steps, std::size_t taken, bool gave_way, const std::string& why) const {
    const auto t0 = std::chrono::steady_clock::now();
    const bool automatic = options.solver == Solver::Auto;
    const double left = (predicted_steps - double(taken)) * cg_step_work();
    const double beside = sparse->held_bytes();
    const Solver general = cholmod_available() ? Solver::Cholmod : Solver::Eigen;
    const auto envelope = [&] {
      fallback = detail::envelope_factor(a, cg_rows, options.memory_limit_bytes, ordering_name(stats.ordering), beside);
      fallback_solver = Solver::Envelope;
    };
    const auto direct = [&] {
      fallback = detail::factor_sparse(a, sources, general, options.memory_limit_bytes, beside);
      fallback_solver = general;
    };
    const auto go_on = [&] {  // CG without the probe: fallback stays empty, after() is CG
      sparse->stop_probing();
      fallback_solver = Solver::Cg;
    };
    try {
      if (gave_way) {
        // The solvers cheaper than CG's remaining steps, the cheaper first, each tried while the memory
        // limit refuses the one before; else CG goes on. The envelope is held to kEnvelopeWorkLimit
        // only where the direct solver can take over instead. The direct solver's cost is counted
        // only where the envelope's does not settle it.
        const double envelope_cost = kEnvelopeCostRatio * stats.envelope_work;
        const bool envelope_cheap = envelope_cost < left;
        std::vector<std::function<void()>> tries;
        if (envelope_cheap && stats.envelope_work <= kEnvelopeWorkLimit &&
            !(direct_cost_ >= 0 && direct_cost_ < envelope_cost)) {
          tries.emplace_back(envelope);
          if (std::isfinite(direct_cost_locked())) tries.emplace_back(direct);
        } else {
          if (std::isfinite(direct_cost_locked())) tries.emplace_back(direct);
          if (envelope_cheap) tries.emplace_back(envelope);
        }
        bool done = false;
        for (std::size_t k = 0; k < tries.size() && !done; ++k) {
          try {
            tries[k]();
            done = true;
          } catch (const ResourceLimit&) {
          }
        }
        if (!done) go_on();
      } else {
        try {
          direct();
        } catch (const ResourceLimit& first) {
          if (!automatic)
            throw ResourceLimit(why + "; and the direct solver that can solve it passes the memory limit: " +
                                first.what() + " (--solver envelope, or auto, may fit within it)");
          try {
            envelope();
          } catch (const ResourceLimit& second) {
            throw ResourceLimit(why + "; and the direct solvers that can solve it pass the memory limit: " +
                                first.what() + "; " + second.what());
          }
        }
      }
    } catch (const NotPositiveDefinite& e) {
      throw NotPositiveDefinite(std::string("conjugate gradients ") + (gave_way ? "gave way" : "did not converge") +
                                " after " + std::to_string(taken) + " steps, and then " + e.what());
    }
    fallback_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    fell_back = true;
  }
  mutable double fallback_seconds = 0;  // the taking over solver's factorisation
  mutable std::once_flag fallback_once;
  mutable std::unique_ptr<detail::SparseFactor> fallback;  // when CG gave way (empty: CG went on)
  mutable Solver fallback_solver = Solver::Auto;
  mutable std::atomic<bool> fell_back{false};

  mutable std::once_flag condition_once;
  mutable double condition_ = 0;
  /// lambda_max by power iteration with A, lambda_min by inverse iteration with
  /// the factorisation. A is symmetric positive definite, so both converge to the extreme eigenvalues.
  double condition() const {
    std::call_once(condition_once, [this] {
      const std::size_t n = sources.size();
      const double phi0 = a.diagonal();
      RowMatrix v = RowMatrix::Constant(Eigen::Index(n), 1, 1.0 / std::sqrt(double(n)));
      double lmax = phi0;
      for (int it = 0; it < 30; ++it) {
        const RowMatrix av = a * v;
        const double norm = av.norm();
        if (!(norm > 0)) break;
        lmax = norm;
        v = av / norm;
      }
      if (warm_starts()) {
        // No factor to reuse: each inverse step would be a whole CG solve. Lanczos on A gives both
        // extreme eigenvalues from products alone (the Ritz values of its tridiagonal matrix).
        const auto [lo, hi] = detail::lanczos_extremes(a, 20261201);
        condition_ = hi / lo;
        return;
      }
      RowMatrix x = RowMatrix::Constant(Eigen::Index(n), 1, 1.0 / std::sqrt(double(n)));
      double lmin_inv = 1.0 / phi0;
      for (int it = 0; it < 30; ++it) {
        solve_in_place(x);
        const double norm = x.norm();
        if (!(norm > 0) || !std::isfinite(norm)) break;
        lmin_inv = norm;
        x /= norm;
      }
      condition_ = lmax * lmin_inv;
    });
    return condition_;
  }
};

namespace detail {
/// The phases of SpaceMap::fit that depend on the sources only, for csrbf::Interpolator: the
/// polynomial's frame (center and scale; options.polynomial must be None, the interpolator solves its
/// own polynomial block), the neighbour graph, A + diag(diagonal_shift), the ordering and solver, the
/// factorisation. The sources must have been checked (finite, radius and limit valid).
std::shared_ptr<SpaceMap::Structure> fit_structure(std::span<const Vec3> sources, const FitOptions& options,
                                                   std::span<const double> diagonal_shift, int dims,
                                                   bool schwarz_sorted = false);
}  // namespace detail

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
      data.assign(st->grid(), st->sources, rows.data(), st->options.kernel);
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
