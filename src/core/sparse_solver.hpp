// The solvers behind csrbf/detail/kernel_solver.hpp (private to csrbf::core): the general sparse
// Cholesky factorisations of the CSRBF matrix, Eigen's SimplicialLLT with AMD ordering and SuiteSparse
// CHOLMOD's supernodal factorisation (nested dissection, BLAS-3 on dense supernodes) when csrbf is
// built with it, the envelope Cholesky as a solver, conjugate gradients, and what they hold. They work
// in the input order of the sources (they permute internally).
#pragma once

#include "csrbf/detail/kernel_solver.hpp"
#include "csrbf/fit_options.hpp"
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/types.hpp"

#include <functional>
#include <span>
#include <string_view>
#include <memory>
#include <stdexcept>
#include <string>

namespace csrbf::detail {

/// Bytes of A as KernelMatrix holds it: a 4-byte column and an 8-byte value an off-diagonal entry,
/// and an 8-byte offset a row.
double kernel_matrix_bytes(const KernelMatrix& a);
/// What the address-space limit (RLIMIT_AS, ulimit -v) leaves beyond what the process maps now, in
/// bytes; infinity without a limit.
double address_space_room() noexcept;
/// Throws ResourceLimit naming `what` and `instead` where address_space_room() is under `need` bytes.
void check_address_space(double need, const char* what, const char* instead);
/// The address space OpenBLAS maps for its buffers on its first call (under CHOLMOD), with margin:
/// measured after CHOLMOD is opened (cholmod_loader.cpp), the fish at R = 5 ran with 187 MB of
/// room and spun in OpenBLAS's allocation with 158 MB (ulimit -v 340000 and 310000).
inline constexpr double kBlasAddressSpace = 192.0 * (1 << 20);
/// Bytes of the envelope solver's factor with `off_diagonal` entries in its envelope below the
/// diagonal, for N rows.
double envelope_factor_bytes(double off_diagonal, std::size_t n);
/// Bytes conjugate gradients hold beside A for `entries` off-diagonal entries of N rows; with
/// `schwarz`, room for the Schwarz preconditioner (schwarz_share); with `copy` (CG's order is not
/// A's), A's rows and the points copied into CG's order.
double cg_bytes(std::size_t entries, std::size_t n, bool schwarz = false, bool copy = true);
/// The bytes CG sets aside for a Schwarz preconditioner (schwarz.hpp) of A with `entries`
/// off-diagonal entries of N rows: 12 a matrix entry and 320 a row. Measured: 2-D points at 40
/// neighbours take 320 bytes a row, 3-D ones 370, and at 12.5 neighbours (a multiscale fit's finest
/// level) 230 and 310 (2e4 random points); a share of 64 a row left them at the edge (before the
/// patches kept their scaling, 8 bytes a patch's point), and from 6e4 to 2.2e5 points
/// some fits fell back to the incomplete Cholesky (4-12x the steps). test_schwarz.cpp keeps a
/// quarter of the share spare at 6, 12.5 and 40 neighbours. Larger patches still fall back.
double schwarz_share(std::size_t entries, std::size_t n);

/// CG's preconditioner (incomplete_cholesky.hpp): taken once the residual's fall over the first
/// kIcProbeSteps steps predicts more than kIcSwitchSteps steps; a preconditioned step costs about
/// kIcStepCost plain ones (measured: 15 ms against 7.5 at 2e5 controls on the sphere).
inline constexpr std::size_t kIcProbeSteps = 12;
inline constexpr std::size_t kIcSwitchSteps = 80;
inline constexpr double kIcStepCost = 2.0;

/// A failed solve (SolveStatus) as an exception, for callers with no other solver to turn to
/// (KernelSolver::solve_in_place), and for a fit whose every solver has been tried.
class CgStagnated : public std::runtime_error {
 public:
  CgStagnated(const std::string& what, double predicted_steps, std::size_t steps_taken, bool gave_way = false)
      : std::runtime_error(what), predicted_(predicted_steps), taken_(steps_taken), gave_way_(gave_way) {}
  explicit CgStagnated(const SolveStatus& s)
      : CgStagnated(s.message, s.predicted_steps, s.steps, s.info == SystemInfo::GaveWay) {}
  /// Auto's probe found another solver cheaper (CG was still converging, or had just begun); else CG
  /// stagnated or reached its step limit, and would do so again on the same matrix.
  bool gave_way() const noexcept { return gave_way_; }
  /// The steps the solve was predicted to need in all, from its convergence so far (infinity where
  /// it made no progress).
  double predicted_steps() const noexcept { return predicted_; }
  /// The steps it took before it gave up.
  std::size_t steps_taken() const noexcept { return taken_; }

 private:
  double predicted_;
  std::size_t taken_;
  bool gave_way_;
};

/// Estimates of A's smallest and largest eigenvalues: the extreme Ritz values of the Lanczos
/// tridiagonal matrix after up to 300 steps from a seeded random vector (fewer where they settle to
/// 1e-6 or the space is exhausted). Products with A only: for the condition estimate without a factor.
std::pair<double, double> lanczos_extremes(const KernelMatrix& a, unsigned seed);

/// The envelope solver's two steps, shared by the fit and by the solver Auto turns to after CG:
/// ResourceLimit (naming `ordering`) when the envelope of these first columns, known exactly before
/// it is allocated, passes memory_limit_bytes;
/// held_bytes: what the fit holds beside the envelope (A, a solver that gave way), counted with it.
void check_envelope_size(std::span<const std::size_t> first_columns, double memory_limit_bytes,
                         std::string_view ordering, double held_bytes);
/// and the Cholesky factorisation in place of A in `order`, NotPositiveDefinite naming the source
/// (order[row]) rather than the row.
void envelope_cholesky(EnvelopeMatrix& env, std::span<const std::uint32_t> order);

/// The paper's envelope Cholesky of A in `order` (rows: the sources order[k]) as a KernelSolver that
/// takes and gives the input order: the direct solver Auto turns to after CG on a small system.
/// ResourceLimit when the envelope exceeds memory_limit_bytes; NotPositiveDefinite names the source.
/// held_bytes: what the fit holds beside A (a solver that gave way).
std::unique_ptr<KernelSolver> envelope_factor(const KernelMatrix& a, std::vector<std::uint32_t> order,
                                              double memory_limit_bytes, std::string_view ordering,
                                              double held_bytes = 0);

/// A general sparse Cholesky factorisation analysed (ordering, symbolic factorisation, memory check)
/// but not yet computed: its flops are known before it factorises (the tests check csrbf's own
/// cholesky_factor_count, which Auto weighs by, against them).
class SparseAnalysis {
 public:
  virtual ~SparseAnalysis() = default;
  /// Floating-point operations of the numeric factorisation, as the analysis predicts them.
  virtual double flops() const = 0;
  /// The numeric factorisation (once): NotPositiveDefinite on failure.
  virtual std::unique_ptr<KernelSolver> factorise() = 0;
};
/// factor_sparse's first step: ResourceLimit already here when the factor would pass the limit.
/// held_bytes: what the fit holds beside A (a solver that gave way), counted with the factor.
std::unique_ptr<SparseAnalysis> analyse_sparse(const KernelMatrix& a, std::span<const Vec3> sources, Solver which,
                                               double memory_limit_bytes, double held_bytes = 0);

/// Assembles A in compressed columns and factorises it with Solver::Eigen (AMD ordering) or
/// Solver::Cholmod (in nested_dissection_order of the sources). Throws NotPositiveDefinite on
/// failure, InvalidInput when CHOLMOD is asked for but not built in, ResourceLimit when the
/// symbolic analysis predicts a factor beyond memory_limit_bytes (before the numeric factorisation).
std::unique_ptr<KernelSolver> factor_sparse(const KernelMatrix& a, std::span<const Vec3> sources, Solver which,
                                            double memory_limit_bytes, double held_bytes = 0);

}  // namespace csrbf::detail
