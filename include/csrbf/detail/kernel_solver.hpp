// The solvers of a kernel system (csrbf/kernel_system.hpp) behind one interface: the envelope
// Cholesky, Eigen's and CHOLMOD's sparse Cholesky, conjugate gradients, and Auto's solver over them
// (src/core/auto_solver.hpp). Installed for csrbf::mpi, whose one-rank CG is the core's own; internal
// to csrbf, not a stable API.
#pragma once

#include "csrbf/kernel_matrix.hpp"
#include "csrbf/kernel_system.hpp"
#include "csrbf/types.hpp"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace csrbf::detail {

/// One solver of A X = B. A failed solve is a status (SolveStatus), not an exception: CG that
/// stagnates, or that Auto's probe stops, says so and leaves B as it was. Solves are thread-safe; they
/// are not const, as a solve may change the solver (CG's record of its last solve, Auto's hand-over).
class KernelSolver {
 public:
  virtual ~KernelSolver() = default;
  /// Solves A X = B in place; B is N x m in the row order the solver was made for (a sparse
  /// solver's: the input order of the points). An iterative solver starts from `initial` (N x m, the
  /// same order) where one is given; a direct one ignores it. B is written only on success.
  virtual SolveStatus solve(RowMatrix& b, const RowMatrix* initial = nullptr) = 0;
  /// solve(), for a caller with no other solver to turn to: a status other than Success throws
  /// CgStagnated (src/core/sparse_solver.hpp), which carries it.
  void solve_in_place(RowMatrix& b, const RowMatrix* initial = nullptr);
  /// Whether an initial guess helps (iterative solvers).
  virtual bool iterative() const { return false; }
  /// Entries of the factor L (CG: of A).
  virtual std::size_t nonzeros() const = 0;
  /// Iterative solvers: steps and final relative residual of the last solve (0 for direct ones).
  virtual std::size_t iterations() const { return 0; }
  virtual double residual() const { return 0.0; }
  /// Bytes the solver holds beside A (its copy of A's rows, its factor), counted against the memory
  /// limit when another solver is built while this one lives (Auto's hand-over after CG).
  virtual double held_bytes() const = 0;
  /// CG: Auto's probe stops, so that later solves run until they converge or stagnate (Auto keeps CG
  /// where the direct solvers are refused by the memory limit). Nothing for the direct solvers.
  virtual void stop_probing() const {}
  /// CG, once another solver has taken over for good: frees its copy of A's rows (after a solve in
  /// progress ends); a later solve fails (SystemInfo::NoConvergence), so that its caller turns to the
  /// one that took over. Nothing for the direct solvers.
  virtual void release() {}
};
/// CG gives up (SystemInfo::NoConvergence) when its residual has not fallen 10x over this many steps
/// (docs/RELIABILITY.md).
inline constexpr std::size_t kCgStagnationWindow = 1000;
/// At its step limit, CG keeps a solution whose relative residual is at most this (the fit then
/// checks the residual at the controls against 1e-6 itself).
inline constexpr double kCgGoodEnough = 1e-8;

/// Auto's check on CG: every `steps` steps of a solve, CG predicts the steps it needs in all from the
/// residual's decrease over its last two thirds of steps (geometric, for the slowest right-hand side)
/// and stops with SystemInfo::GaveWay unless worth_it(predicted, done) holds (done: the steps taken,
/// a sunk cost).
struct CgProbe {
  std::size_t steps = 0;  ///< 0: no probe
  std::function<bool(double predicted_steps, double done)> worth_it;
};

/// CG's preconditioner where a solve needs one: the incomplete Cholesky (no points), or additive
/// Schwarz over patches of `points` (the sources, input order; src/core/schwarz.hpp), which the
/// incomplete Cholesky replaces where the patches would take more than their share. The points are
/// borrowed: they must outlive the solver.
struct CgPreconditioner {
  std::span<const Vec3> points;
};

/// Conjugate gradients on A, the right-hand sides of a solve together: one parallel pass over A a
/// step serves all of them (a block of independent recurrences, not a block-Krylov method). A's
/// diagonal is phi(0) everywhere, so Jacobi preconditioning would change nothing. Rows are stored in
/// `order` (a bandwidth-reducing ordering of the sources) for locality: a copy of A's rows, or A's
/// own where `order` is the identity (A must then outlive the solver). Stops at a relative residual
/// of `tolerance` per column; fails (SystemInfo::NoConvergence) after `max_iterations`, or as soon as
/// the worst column's smallest relative residual has not fallen 10x in the last kCgStagnationWindow
/// steps.
std::unique_ptr<KernelSolver> conjugate_gradients(const KernelMatrix& a, std::vector<std::uint32_t> order,
                                                  double tolerance, std::size_t max_iterations, CgProbe probe = {},
                                                  CgPreconditioner preconditioner = {});

}  // namespace csrbf::detail
