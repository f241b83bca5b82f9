// The CSRBF system of a set of points, in phases as Eigen's sparse solvers are (STYLE.md): its inputs
// are the points, the radius R, the kernel phi and a diagonal shift lambda (the smoothing of an
// approximation), and a polynomial of degree -1 (none), 0 or 1:
//   analyse()   the neighbour graph, A = [phi(||x_i - x_j|| / R)] + diag(lambda), the ordering and
//               the solver (kernel_system.cpp; Auto's rule in fit_options.hpp);
//   factorise() the factorisation (envelope, CHOLMOD or Eigen), or conjugate gradients' set-up, then
//               the polynomial block of George & Liu's block elimination: Y = A^-1 P, S = P^T Y;
//   solve()     m right-hand sides g at once: A z = g, S beta = P^T z, alpha = z - Y beta;
//   info()      what the last phase came to, as a status (SystemInfo), not an exception.
// Under Solver::Auto (and Solver::Cg) the solver is Auto's (src/core/auto_solver.hpp): CG with its
// probe, and every hand-over to another solver, where CG stagnates or another is predicted cheaper.
// SpaceMap (three values in 3-D) and Interpolator (V values in D dimensions) are both this system
// with their own checks around it; residual() is the one residual check of their solutions.
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/fit_stats.hpp"
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/types.hpp"
#include "csrbf/units.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace csrbf {

/// What a phase of a kernel system, or one solve, came to (as Eigen's ComputationInfo): a status,
/// not an exception.
enum class SystemInfo {
  Success,
  NoConvergence,         ///< CG stagnated, or stopped at its step limit short of a usable residual
  GaveWay,               ///< Auto's probe stopped CG: another solver is predicted to be cheaper
  DegeneratePolynomial,  ///< degree 1, and the points do not span their D-dimensional space
  NumericalIssue,        ///< the polynomial block's P^T A^-1 P is not positive definite
};

/// One solve's outcome. Where CG fell short: the steps it was predicted to need in all (infinity
/// where it made no progress), the steps it took, and why, in words.
struct SolveStatus {
  SystemInfo info = SystemInfo::Success;
  double predicted_steps = 0;
  std::size_t steps = 0;
  std::string message;
  bool ok() const noexcept { return info == SystemInfo::Success; }
};

namespace detail {
class KernelSolver;
class AutoSolver;
struct PointCloud;
}  // namespace detail

struct KernelSystemOptions {
  double radius = 0.0;  ///< R, in the points' units (not squared), in [1e-150, 1e150]
  Kernel kernel = Kernel::C2;
  int dimension = 3;  ///< D = 1, 2 or 3: the points' coordinates past D are 0
  int degree = -1;    ///< the polynomial: -1 none, 0 a constant, 1 linear (1 + D terms)
  Solver solver = Solver::Auto;
  Ordering ordering = Ordering::Auto;  ///< of the envelope solver and CG's rows
  double memory_limit_bytes = 4.0 * kGiB;
  /// Scattered points (csrbf::Interpolator): CG may take additive Schwarz over patches of the points
  /// as its preconditioner (src/core/schwarz.hpp); and where it does for Auto, the envelope is not
  /// weighed.
  bool schwarz = false;
  /// The points are already in the Schwarz patches' order (detail::schwarz_order): CG then reads A in
  /// place, in its own order.
  bool schwarz_sorted = false;
  /// The right-hand sides Auto counts a CG step for when it weighs CG against the other solvers: a
  /// SpaceMap's 3 and its polynomial block's; an interpolator's level, 3 (its values and block are
  /// not counted).
  double cg_work_columns = 3;
  /// Auto: where the envelope Cholesky breaks down (a pivot below its threshold), the general direct
  /// solver takes over (csrbf::Interpolator: 5e4 points on a line); otherwise NotPositiveDefinite.
  bool direct_after_breakdown = false;
};

/// A solve's rows follow order() (the points order[k]); a warm start is given in it (warm_start()).
/// Not copyable (it holds the factor). solve() and condition() may change the solver (Auto's
/// hand-over) and are thread-safe; the other members are const.
class KernelSystem {
 public:
  /// points: N >= 1, finite, within 1e150; shift: empty, one value, or one a point (each >= 0);
  /// InvalidInput otherwise. The polynomial's frame (center and scale of u = (x - center) / scale) is
  /// computed here.
  KernelSystem(std::span<const Vec3> points, const KernelSystemOptions& options, std::span<const double> shift = {});
  /// For csrbf::core: over points whose neighbour grid the maps made from this system share, the
  /// inputs checked by the caller.
  KernelSystem(std::shared_ptr<detail::PointCloud> points, const KernelSystemOptions& options,
               std::span<const double> shift = {});
  ~KernelSystem();
  KernelSystem(const KernelSystem&) = delete;
  KernelSystem& operator=(const KernelSystem&) = delete;

  /// The neighbour graph (DuplicateSource where two points coincide without both being shifted;
  /// ResourceLimit before anything large is built), A, the ordering and the solver. Once.
  void analyse();
  /// The factorisation (NotPositiveDefinite, ResourceLimit), then the polynomial block; info():
  /// DegeneratePolynomial (no block) or NumericalIssue where the points do not determine it. Once,
  /// after analyse().
  void factorise();
  /// b: N x m right-hand sides, rows in the points' input order, becomes alpha; beta: terms x m.
  /// `guess`: a start for CG (warm_start()). Where the status is not Success, b is not a solution.
  SolveStatus solve(RowMatrix& b, Eigen::MatrixXd& beta, const RowMatrix* guess = nullptr);
  /// A^-1 b without the polynomial, b in order() (the condition estimate's inverse iteration).
  SolveStatus solve_matrix(RowMatrix& b);
  /// CG's start from an earlier solution of this system (alpha N x m, input order; beta terms x m or
  /// more rows): z = alpha + Y beta, in order().
  template <class Alpha, class Beta>
  RowMatrix warm_start(const Alpha& alpha, const Beta& beta) const {
    RowMatrix guess(Eigen::Index(size()), alpha.cols());
    for (std::size_t k = 0; k < size(); ++k) guess.row(Eigen::Index(k)) = alpha.row(Eigen::Index(order_[k]));
    if (terms_ > 0) guess += y_ * beta.topRows(terms_);
    return guess;
  }
  SystemInfo info() const noexcept { return info_; }
  /// A failed solve's status thrown, as a fit always reported it (detail::CgStagnated).
  static void require(const SolveStatus& status);

  /// The one residual check of a solution: max_i ||(A alpha)_i + p(x_i) - g_i|| (`max`), and that
  /// relative to `largest`, max_i ||g_i|| (or itself where g = 0). alpha and g: N x m, input order;
  /// beta: terms x m. Coefficients that are not finite count as an infinite residual.
  struct Residual {
    double max = 0, relative = 0, largest = 0;
  };
  Residual residual(const RowMatrix& alpha, const Eigen::MatrixXd& beta, const RowMatrix& g) const;
  /// An estimate of A's 2-norm condition number lambda_max / lambda_min: power iteration with A, and
  /// inverse iteration through the factorisation (Lanczos where the solver is CG); computed once.
  double condition();

  std::size_t size() const noexcept;
  std::span<const Vec3> points() const noexcept;
  const std::shared_ptr<detail::PointCloud>& cloud() const noexcept { return cloud_; }
  const KernelSystemOptions& options() const noexcept { return options_; }
  const KernelMatrix& matrix() const noexcept { return a_; }
  /// order[k] = the point at row k of a solve (the identity for every solver but the envelope).
  std::span<const std::uint32_t> order() const noexcept { return order_; }
  /// The polynomial in u = (x - center) / scale: 0, 1 or 1 + D terms.
  int terms() const noexcept { return terms_; }
  const Vec3& center() const noexcept { return center_; }
  double scale() const noexcept { return scale_; }
  /// Degree 1: the singular values of the points in u (N x D), largest first (empty where N <= D).
  const Eigen::VectorXd& singular_values() const noexcept { return singular_values_; }
  /// Degree 1 with fewer than D + 1 points, or points in a (D - 1)-plane (the smallest singular value
  /// below 1e-9 of the largest).
  bool polynomial_degenerate() const noexcept;
  /// The structural statistics and the phases' times (a SpaceMap's fit adds its solve's).
  const FitStats& stats() const noexcept { return stats_; }
  /// The solver that answers now: the one analyse() chose, or the one that took over from CG.
  Solver solver() const;
  /// Whether another solver has taken over from CG (or CG goes on without Auto's probe).
  bool handed_over() const;
  /// The answering solver's steps in its last solve (0 for a direct one).
  std::size_t iterations() const;
  /// Whether solves start from an initial guess (the solver is CG).
  bool warm_starts() const;
  /// A solve's statistics into `stats`, as a SpaceMap's fit reports them: CG's steps and residual,
  /// and where another solver took over, which, its factor, and (where it took over during the solve
  /// that `handed_over_before` was read before) its factorisation's time moved out of the solve's.
  void report(FitStats& stats, bool handed_over_before) const;

 private:
  void graph_and_matrix();
  Solver ordering_and_solver();
  void factorise_envelope();
  void factorise_sparse();
  void polynomial_block();
  double cg_total_bytes() const;
  SolveStatus solve_columns(RowMatrix& b, const RowMatrix* guess);

  std::shared_ptr<detail::PointCloud> cloud_;
  KernelSystemOptions options_;
  std::vector<double> shift_;  // one value, or one a point (empty: none)
  int terms_ = 0;
  Vec3 center_ = Vec3::Zero();
  double scale_ = 1.0;
  Eigen::VectorXd singular_values_;
  FitStats stats_;
  KernelMatrix a_;                                // input order: its pattern is the neighbour graph
  std::vector<std::uint32_t> order_;              // row k of a solve is the point order_[k]
  std::vector<std::size_t> first_columns_;        // of the envelope in order_, until it is assembled
  Solver chosen_ = Solver::Envelope;              // analyse()'s choice
  bool cg_in_place_ = false;                      // CG reads A in place (sorted points)
  double schwarz_bytes_ = 0;                      // what CG with the Schwarz patches would hold (0: they do not apply)
  bool in_order_ = false;                         // the solver works in order_ (the envelope), not the input order
  std::unique_ptr<detail::KernelSolver> solver_;  // after a_: CG may read A in place
  detail::AutoSolver* auto_ = nullptr;            // solver_, where it is Auto's
  RowMatrix p_;                                   // N x terms, in order_
  RowMatrix y_;                                   // A^-1 P, in order_
  Eigen::LLT<Eigen::MatrixXd> schur_;             // P^T A^-1 P
  SystemInfo info_ = SystemInfo::Success;
  std::once_flag condition_once_;
  double condition_ = 0;
};

}  // namespace csrbf
