// Auto's solver (fit_options.hpp states the rule), behind the kernel system's solver interface
// (csrbf/detail/kernel_solver.hpp): conjugate gradients with Auto's probe, and every hand-over to
// another solver. CG's failure is a status (SolveStatus): where CG stagnates, or its probe finds
// another solver cheaper, this solver turns to that one, once, for this solve and every later one.
// Solver::Cg asked for by name is this solver without the probe: a direct solver takes over where CG
// stagnates. Private to csrbf::core.
#pragma once

#include "csrbf/detail/kernel_solver.hpp"
#include "csrbf/fit_options.hpp"
#include "csrbf/ordering.hpp"

#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace csrbf::detail {

/// What Auto weighs CG against: the kernel system's analysis.
struct AutoInputs {
  Solver asked = Solver::Auto;  ///< Auto: CG with the probe; Cg: CG until it stagnates
  double memory_limit_bytes = 0;
  Ordering ordering = Ordering::ReverseCuthillMcKee;  ///< of CG's rows, the envelope's where it takes over
  double envelope_work = 0;                           ///< the envelope factorisation's multiply-adds (infinity: never)
  std::size_t envelope_entries = 0;
  std::size_t neighbor_pairs = 0;
  double work_columns = 3;    ///< the right-hand sides a CG step counts for (KernelSystemOptions::cg_work_columns)
  double cg_total_bytes = 0;  ///< A and what CG holds beside it
};

class AutoSolver final : public KernelSolver {
 public:
  /// CG over `a` (input order; it must outlive this solver, as `points` must), its rows in `cg_rows`.
  AutoSolver(const KernelMatrix& a, std::span<const Vec3> points, std::vector<std::uint32_t> cg_rows,
             const AutoInputs& inputs, CgPreconditioner preconditioner);
  /// The general direct solver (CHOLMOD, else Eigen) where Auto's envelope Cholesky broke down
  /// (KernelSystemOptions::direct_after_breakdown); where it fails too, `breakdown` is rethrown.
  static std::unique_ptr<KernelSolver> after_breakdown(const KernelMatrix& a, std::span<const Vec3> points,
                                                       double memory_limit_bytes, const std::exception_ptr& breakdown);

  /// CG, or the solver that took over. A status other than Success only where CG went on without its
  /// probe (every direct solver refused by the memory limit) and failed again; ResourceLimit or
  /// NotPositiveDefinite where no solver can take over.
  SolveStatus solve(RowMatrix& b, const RowMatrix* initial = nullptr) override;
  bool iterative() const override;
  std::size_t nonzeros() const override { return cg_->nonzeros(); }  ///< CG's (A's entries)
  std::size_t iterations() const override;                           ///< the answering solver's
  double residual() const override;                                  ///< the answering solver's
  double held_bytes() const override;

  /// Auto's stage, read at once: whether another solver has taken over, which (Solver::Cg: CG went on
  /// without its probe, every other refused by the memory limit), why (CG's status), the taking over
  /// solver's factorisation in seconds, and that solver (null: none, or CG went on).
  struct Stage {
    bool handed_over = false;
    Solver solver = Solver::Cg;
    SolveStatus cause;
    double seconds = 0;
    const KernelSolver* taken = nullptr;
  };
  Stage stage() const;
  /// CG's steps and residual in its last solve (also after another solver took over).
  std::size_t cg_iterations() const { return cg_->iterations(); }
  double cg_residual() const { return cg_->residual(); }

 private:
  /// Multiply-adds of one CG step over all the solves of a fit (AutoInputs::work_columns).
  double cg_step_work() const;
  /// The direct solver's factorisation in CG multiply-adds (kDirectFlopCost a flop), from its
  /// factor's column counts in csrbf's nested dissection order, or infinity where the factor would
  /// pass the memory limit; counted once. Under mutex_ (CG's probe runs inside solve()).
  double direct_cost();
  /// CG's probe: whether the steps CG predicts are worth it against the other solvers.
  bool worth_it(double steps, double done);
  /// After CG failed with `cause`: the solver that takes over (or CG without its probe).
  void take_over(const SolveStatus& cause);
  void take_over_after_probe(double left, const std::function<void()>& envelope, const std::function<void()>& direct,
                             const std::function<void()>& go_on);

  const KernelMatrix& a_;
  std::span<const Vec3> points_;
  std::vector<std::uint32_t> cg_rows_;  // CG's row order, for the envelope that may take over
  AutoInputs in_;
  std::unique_ptr<KernelSolver> cg_;
  // Auto's stage, written under mutex_ (solve() holds it throughout).
  mutable std::mutex mutex_;
  Stage stage_;
  std::unique_ptr<KernelSolver> taken_;  // stage_.taken
  double direct_cost_ = -1;              // < 0: not counted yet
};

}  // namespace csrbf::detail
