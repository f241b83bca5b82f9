#include "auto_solver.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/names.hpp"

#include "cholmod_loader.hpp"
#include "sparse_solver.hpp"

#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace csrbf::detail {

AutoSolver::AutoSolver(const KernelMatrix& a, std::span<const Vec3> points, std::vector<std::uint32_t> cg_rows,
                       const AutoInputs& inputs, CgPreconditioner preconditioner)
    : a_(a), points_(points), cg_rows_(cg_rows), in_(inputs) {
  // Chosen by Auto, CG checks every kCgProbeSteps steps how many it will need, and gives way where a
  // direct solver is predicted to be faster (fit_options.hpp). Asked for by name, it runs until it
  // converges or stagnates (kCgMaxIterations): its early predictions can be far too high as well as
  // too low (900 points in a cube: more than 3000 predicted after 10 steps, of fewer than 3000).
  CgProbe probe;
  if (in_.asked == Solver::Auto) {
    probe.steps = kCgProbeSteps;
    probe.worth_it = [this](double steps, double done) { return worth_it(steps, done); };
  }
  cg_ = conjugate_gradients(a_, std::move(cg_rows), kCgTolerance, kCgMaxIterations, std::move(probe), preconditioner);
}

std::unique_ptr<KernelSolver> AutoSolver::after_breakdown(const KernelMatrix& a, std::span<const Vec3> points,
                                                          double memory_limit_bytes,
                                                          const std::exception_ptr& breakdown) {
  // Auto's envelope solver refuses a pivot below 64 eps of its diagonal entry: 5e4 random points on
  // a line, whose close pairs make A that nearly singular, were refused where the general direct
  // solver (or CG) solves them to 1e-10 at the points; the residual check judges its solution. Where
  // it fails too, the first refusal is the one reported.
  try {
    return factor_sparse(a, points, cholmod_available() ? Solver::Cholmod : Solver::Eigen, memory_limit_bytes);
  } catch (const Error&) {
    std::rethrow_exception(breakdown);
  }
}

SolveStatus AutoSolver::solve(RowMatrix& b, const RowMatrix* initial) {
  // One solve at a time (CG's and the direct solvers' are serialised anyway), isolated: a thread
  // waiting in a parallel loop below must not take another task that would lock mutex_ again.
  std::lock_guard lock(mutex_);
  return tbb::this_task_arena::isolate([&] {
    if (!stage_.handed_over) {
      SolveStatus s = cg_->solve(b, initial);  // CG writes b only where it converged
      if (s.ok()) return s;
      // CG stagnated, or Auto's probe found it slower than a direct solve: another solver takes
      // over, once, for this solve and every later one with these points. CG that stagnated never
      // runs again: its copy of A makes room for the solver that takes over (face.obj, 6158
      // controls, R = 1.5: the envelope was refused beside it under 1 GiB). Where it gave way, it
      // is kept until another solver has taken over (else it goes on).
      if (s.info != SystemInfo::GaveWay) cg_->release();
      take_over(s);
      if (taken_) cg_->release();
    }
    return taken_ ? taken_->solve(b, initial) : cg_->solve(b, initial);
  });
}

bool AutoSolver::iterative() const {
  std::lock_guard lock(mutex_);
  return taken_ ? taken_->iterative() : true;
}

std::size_t AutoSolver::iterations() const {
  std::lock_guard lock(mutex_);
  return taken_ ? taken_->iterations() : cg_->iterations();
}

double AutoSolver::residual() const {
  std::lock_guard lock(mutex_);
  return taken_ ? taken_->residual() : cg_->residual();
}

double AutoSolver::held_bytes() const {
  std::lock_guard lock(mutex_);
  return cg_->held_bytes() + (taken_ ? taken_->held_bytes() : 0.0);
}

AutoSolver::Stage AutoSolver::stage() const {
  std::lock_guard lock(mutex_);
  return stage_;
}

double AutoSolver::cg_step_work() const {
  return (2.0 * double(in_.neighbor_pairs) + double(points_.size())) * in_.work_columns;
}

double AutoSolver::direct_cost() {
  if (direct_cost_ < 0) {
    // Values and row indices of L (12 bytes an entry), as the solvers' own analyses check them, beside
    // A, CG's copy of it (which lives on while the direct solver takes over) and the direct solver's
    // two copies of A's lower triangle: the count stops where the factor passes the memory limit
    // (infinite cost).
    const std::size_t lower = a_.values().size() / 2 + points_.size();
    const double beside = in_.cg_total_bytes + 2 * 12.0 * double(lower);
    if (beside >= in_.memory_limit_bytes)
      direct_cost_ = std::numeric_limits<double>::infinity();
    else
      direct_cost_ = kDirectFlopCost *
                     cholesky_factor_count(a_.pattern(), nested_dissection_order(a_.pattern(), points_, a_.radius()),
                                           (in_.memory_limit_bytes - beside) / 12.0)
                         .flops;
  }
  return direct_cost_;
}

bool AutoSolver::worth_it(double steps, double done) {
  // Costs in CG multiply-adds; the steps taken are spent either way.
  const std::size_t n = points_.size();
  const double left = (steps - done) * cg_step_work();
  const double envelope = kEnvelopeCostRatio * in_.envelope_work;
  if (in_.envelope_work <= kEnvelopeWorkLimit && envelope < left) return false;
  // The general direct solver is weighed (its ordering and its factor's column counts, no numbers)
  // once CG looks long enough for it to win: its flops are then known.
  if (steps - done > kCgAnalyseSteps * std::sqrt(double(n))) {
    const double direct = direct_cost();
    // CG's prediction is least sure after its first steps: the direct solver must win by a margin
    // that shrinks as CG goes on (2x after 10 steps, 1.25x after 40).
    const double margin = 1 + kCgProbeSteps / done;
    if (direct * margin < left) return false;
    // Where the memory limit refuses the direct factor, the envelope whatever its work, where it fits
    // beside A and CG (face.obj, 6158 controls at 5263 neighbours each: CG ran 1000 steps and 78 s
    // before it gave way; the envelope takes 22 s).
    const double envelope_bytes = envelope_factor_bytes(double(in_.envelope_entries), n) + in_.cg_total_bytes;
    if (!std::isfinite(direct) && envelope * margin < left && envelope_bytes <= in_.memory_limit_bytes) return false;
  }
  return true;
}

// After CG took cause.steps steps. Where Auto's probe made it give way: the envelope solver where its
// work (at kEnvelopeCostRatio) is below what CG was predicted to need, within kEnvelopeWorkLimit and
// below the direct solver's as weighed; else the direct solver (CHOLMOD, or Eigen); and where the
// memory limit refuses them, CG goes on without the probe. Where CG stagnated (or a CG asked for by
// name), the direct solver, then the envelope solver whatever its work: CG again would stagnate again.
// Each counts what CG still holds beside it: nothing where CG stagnated (its copy of A was freed
// first), its copy where it gave way (it goes on if every other is refused).
void AutoSolver::take_over(const SolveStatus& cause) {
  const auto t0 = std::chrono::steady_clock::now();
  const bool automatic = in_.asked == Solver::Auto;
  const bool gave_way = cause.info == SystemInfo::GaveWay;
  const double left = (cause.predicted_steps - double(cause.steps)) * cg_step_work();
  const double beside = cg_->held_bytes();
  const Solver general = cholmod_available() ? Solver::Cholmod : Solver::Eigen;
  Solver next = Solver::Cg;
  const auto envelope = [&] {
    taken_ = envelope_factor(a_, cg_rows_, in_.memory_limit_bytes, ordering_name(in_.ordering), beside);
    next = Solver::Envelope;
  };
  const auto direct = [&] {
    taken_ = factor_sparse(a_, points_, general, in_.memory_limit_bytes, beside);
    next = general;
  };
  const auto go_on = [&] {  // CG without the probe: taken_ stays empty
    cg_->stop_probing();
    next = Solver::Cg;
  };
  try {
    if (gave_way) {
      take_over_after_probe(left, envelope, direct, go_on);
    } else {
      try {
        direct();
      } catch (const ResourceLimit& first) {
        if (!automatic)
          throw ResourceLimit(cause.message + "; and the direct solver that can solve it passes the memory limit: " +
                              first.what() + " (--solver envelope, or auto, may fit within it)");
        try {
          envelope();
        } catch (const ResourceLimit& second) {
          throw ResourceLimit(cause.message + "; and the direct solvers that can solve it pass the memory limit: " +
                              first.what() + "; " + second.what());
        }
      }
    }
  } catch (const NotPositiveDefinite& e) {
    throw NotPositiveDefinite(std::string("conjugate gradients ") + (gave_way ? "gave way" : "did not converge") +
                              " after " + std::to_string(cause.steps) + " steps, and then " + e.what());
  }
  stage_ = {true, next, cause, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
            taken_.get()};
}

void AutoSolver::take_over_after_probe(double left, const std::function<void()>& envelope,
                                       const std::function<void()>& direct, const std::function<void()>& go_on) {
  // The solvers cheaper than CG's remaining steps, the cheaper first, each tried while the memory
  // limit refuses the one before; else CG goes on. The envelope is held to kEnvelopeWorkLimit only
  // where the direct solver can take over instead. The direct solver's cost is counted only where
  // the envelope's does not settle it.
  const double envelope_cost = kEnvelopeCostRatio * in_.envelope_work;
  const bool envelope_cheap = envelope_cost < left;
  std::vector<std::function<void()>> tries;
  if (envelope_cheap && in_.envelope_work <= kEnvelopeWorkLimit &&
      !(direct_cost_ >= 0 && direct_cost_ < envelope_cost)) {
    tries.emplace_back(envelope);
    if (std::isfinite(direct_cost())) tries.emplace_back(direct);
  } else {
    if (std::isfinite(direct_cost())) tries.emplace_back(direct);
    if (envelope_cheap) tries.emplace_back(envelope);
  }
  for (const auto& t : tries) {
    try {
      t();
      return;
    } catch (const ResourceLimit&) {
    }
  }
  go_on();
}

}  // namespace csrbf::detail
