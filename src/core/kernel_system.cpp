// csrbf::KernelSystem (kernel_system.hpp), phase by phase in the order they run:
//   polynomial frame (constructor) -> neighbour graph and A -> ordering and solver (analyse)
//   -> factorisation -> polynomial block (factorise) -> solve -> residual check.
#include "csrbf/kernel_system.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/names.hpp"

#include "auto_solver.hpp"
#include "cholmod_loader.hpp"
#include "point_cloud.hpp"
#include "schwarz.hpp"
#include "sparse_solver.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <exception>
#include <limits>
#include <sstream>
#include <string>

namespace csrbf {

namespace {

/// Up to this many points the graph tests every pair (cheaper than the grid).
constexpr std::size_t kBruteForceGraph = 256;
/// Right-hand sides a solve takes at once (CG's preconditioner works on up to 8).
constexpr std::size_t kSolveColumns = 8;

std::vector<std::uint32_t> compute_ordering(const AdjacencyGraph& g, Ordering o) {
  switch (o) {
    case Ordering::Identity:
      return identity_order(g.size());
    case Ordering::BreadthFirst:
      return breadth_first_order(g);
    case Ordering::ReverseBreadthFirst:
      return reversed_order(breadth_first_order(g));
    default:
      return reverse_cuthill_mckee_order(g);
  }
}

/// The envelope Cholesky as the system's solver: rows in the system's order, solved in place.
class EnvelopeInOrder final : public detail::KernelSolver {
 public:
  EnvelopeInOrder(EnvelopeMatrix factor, std::size_t nonzeros) : factor_(std::move(factor)), nonzeros_(nonzeros) {}
  SolveStatus solve(RowMatrix& b, const RowMatrix* = nullptr) override {
    factor_.solve_in_place(b);
    return {};
  }
  std::size_t nonzeros() const override { return nonzeros_; }
  double held_bytes() const override { return double(factor_.storage_bytes()); }

 private:
  EnvelopeMatrix factor_;
  std::size_t nonzeros_;
};

/// The public constructor's inputs, checked (SpaceMap and Interpolator check their own first).
std::shared_ptr<detail::PointCloud> checked_cloud(std::span<const Vec3> points, const KernelSystemOptions& o,
                                                  std::span<const double> shift) {
  if (points.empty()) throw InvalidInput("kernel system: no points (need at least 1)");
  detail::check_points(points, "point");
  if (!(o.radius >= 1e-150 && o.radius <= 1e150))
    throw InvalidInput("kernel system: the radius must be in [1e-150, 1e150], got " + format_significant(o.radius, 6));
  if (o.dimension < 1 || o.dimension > 3 || o.degree < -1 || o.degree > 1 || !(o.memory_limit_bytes > 0))
    throw InvalidInput("kernel system: the dimension must be 1, 2 or 3, the degree -1, 0 or 1, the memory limit > 0");
  if (!shift.empty() && shift.size() != 1 && shift.size() != points.size())
    throw InvalidInput("kernel system: " + std::to_string(shift.size()) + " shifts for " +
                       std::to_string(points.size()) + " points (give none, one, or one a point)");
  for (double s : shift)
    if (!(s >= 0) || !std::isfinite(s)) throw InvalidInput("kernel system: a shift must be finite and >= 0");
  return std::make_shared<detail::PointCloud>(points, o.radius, o.memory_limit_bytes);
}

}  // namespace

namespace detail {
void check_points(std::span<const Vec3> pts, const char* what) {
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (!pts[i].allFinite() || pts[i].cwiseAbs().maxCoeff() > kMaxCoordinate) {
      std::ostringstream os;
      os << what << " " << i << (pts[i].allFinite() ? " is out of range (a coordinate beyond 1e150)" : " is not finite")
         << ": (" << pts[i].x() << ", " << pts[i].y() << ", " << pts[i].z() << ")";
      throw InvalidInput(os.str());
    }
}
}  // namespace detail

KernelSystem::KernelSystem(std::span<const Vec3> points, const KernelSystemOptions& options,
                           std::span<const double> shift)
    : KernelSystem(checked_cloud(points, options, shift), options, shift) {}

KernelSystem::KernelSystem(std::shared_ptr<detail::PointCloud> points, const KernelSystemOptions& options,
                           std::span<const double> shift)
    : cloud_(std::move(points)), options_(options), shift_(shift.begin(), shift.end()) {
  // The polynomial's coordinates u = (x - center) / scale (better conditioned than x; the same space
  // of polynomials), and for degree 1 the singular values that say whether the points determine it.
  const std::vector<Vec3>& pts = cloud_->points;
  const std::size_t n = pts.size();
  const int dim = options_.dimension;
  stats_.controls = n;
  terms_ = options_.degree < 0 ? 0 : options_.degree == 0 ? 1 : 1 + dim;
  center_ = Vec3::Zero();
  for (const auto& s : pts) center_ += s;
  center_ /= double(n);
  double spread = 0.0;
  for (const auto& s : pts) spread = std::max(spread, (s - center_).cwiseAbs().maxCoeff());
  scale_ = spread > 0.0 ? spread : 1.0;
  if (options_.degree != 1 || n < std::size_t(dim) + 1) return;
  Eigen::MatrixXd u(n, dim);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 v = (pts[i] - center_) / scale_;
    for (int a = 0; a < dim; ++a) u(Eigen::Index(i), a) = v[a];
  }
  singular_values_ = Eigen::JacobiSVD<Eigen::MatrixXd>(u).singularValues();
}

KernelSystem::~KernelSystem() = default;

namespace {

/// UsageError unless the system is factorised, b has its n rows and guess (if any) b's shape (misuse
/// of the API read and wrote past b's end); `call` names the call.
void check_solve(const char* call, bool factorised, std::size_t n, const RowMatrix& b, const RowMatrix* guess) {
  const auto shape = [](const RowMatrix& x) { return std::to_string(x.rows()) + " x " + std::to_string(x.cols()); };
  if (!factorised) throw UsageError(std::string("KernelSystem: call factorise() before ") + call);
  if (std::size_t(b.rows()) != n)
    throw UsageError(std::string("KernelSystem::") + call + ": the right-hand sides are " + shape(b) +
                     ", not of the system's " + std::to_string(n) + " rows");
  if (guess && (guess->rows() != b.rows() || guess->cols() != b.cols()))
    throw UsageError(std::string("KernelSystem::") + call + ": the guess is " + shape(*guess) +
                     ", the right-hand sides " + shape(b));
}

}  // namespace

std::size_t KernelSystem::size() const noexcept { return cloud_->points.size(); }
std::span<const Vec3> KernelSystem::points() const noexcept { return cloud_->points; }

bool KernelSystem::polynomial_degenerate() const noexcept {
  if (options_.degree != 1) return false;
  const int dim = options_.dimension;
  if (size() < std::size_t(dim) + 1) return true;
  const Eigen::VectorXd& sv = singular_values_;
  return !(sv(dim - 1) > 1e-9 * std::max(sv(0), 1e-300));
}

void KernelSystem::analyse() {
  if (a_.size() == size()) throw UsageError("KernelSystem: analyse() was called already (once a system)");
  graph_and_matrix();
  chosen_ = ordering_and_solver();
}

// Every pair of points closer than R: by testing every pair for a few hundred points (the grid is
// then left to the first evaluation), from the evaluation grid's cell lists above that, from
// NeighborIndex where the grid is unusable. The memory estimate is checked first. Then A's entries,
// computed once from the squared distances, and its diagonal shift.
void KernelSystem::graph_and_matrix() {
  const std::vector<Vec3>& sources = cloud_->points;
  const KernelSystemOptions& options = options_;
  const std::size_t n = sources.size();
  FitStats& stats = stats_;
  auto t0 = Clock::now();
  if (n > kBruteForceGraph) {
    const FitMemoryEstimate m = estimate_fit_memory(sources, options.radius);
    cloud_->fit_bytes = m.bytes;  // the evaluation grid gets what is left of the limit
    if (m.bytes > options.memory_limit_bytes) {
      std::ostringstream os;
      os.precision(3);
      os << "radius " << options.radius << " gives each source about " << m.mean_neighbors << " neighbours ("
         << 100.0 * m.mean_neighbors / double(n - 1) << "% of the " << n << " sources): the fit would need about "
         << format_gib(m.bytes) << " for its neighbour graph and factor, above the limit of "
         << format_gib(options.memory_limit_bytes)
         << " (FitOptions::memory_limit_bytes, `--memory-limit`). Use a smaller radius: the compact support "
            "is what keeps the system sparse";
      throw ResourceLimit(os.str());
    }
  }
  const bool brute = n <= kBruteForceGraph;
  if (!brute && !cloud_->grid().usable) cloud_->index();
  stats.seconds_index = seconds_since(t0);

  t0 = Clock::now();
  // The graph's rows (a 4-byte index and an 8-byte squared distance an entry), counted before they
  // are allocated: within the limit (the sample above can miss a dense cluster).
  const double graph_entries = options.memory_limit_bytes / 12.0;
  AdjacencyGraph g;
  if (brute)
    g = AdjacencyGraph::brute_force(sources, options.radius);
  else if (cloud_->grid().usable)
    cloud_->grid().neighbor_graph(sources, g.offsets, g.neighbors, g.dist2, graph_entries);
  else
    g = AdjacencyGraph::from_index(cloud_->index(), sources, graph_entries);
  stats.neighbor_pairs = g.neighbors.size() / 2;
  stats.mean_neighbors = double(g.neighbors.size()) / double(n);
  // Points i and j may share a position where both have a shift > 0 (A + diag stays positive definite).
  const auto shifted = [&](std::size_t i, std::size_t j) {
    if (shift_.empty()) return false;
    return shift_.size() == 1 ? shift_[0] > 0 : shift_[i] > 0 && shift_[j] > 0;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const auto nb = g.neighbors_of(i);
    const auto d2 = g.dist2_of(i);
    for (std::size_t k = 0; k < nb.size(); ++k)
      if (d2[k] == 0.0 && !shifted(i, nb[k])) {
        const std::size_t a = std::min<std::size_t>(i, nb[k]), b = std::max<std::size_t>(i, nb[k]);
        std::ostringstream os;
        os << "control sources " << a << " and " << b << " are at the same position (" << sources[a].x() << ", "
           << sources[a].y() << ", " << sources[a].z() << ")";
        throw DuplicateSource(a, b, os.str());
      }
  }
  stats.seconds_graph = seconds_since(t0);
  t0 = Clock::now();
  a_ = KernelMatrix(std::move(g), options.kernel, options.radius);
  a_.add_to_diagonal(shift_);
  stats.seconds_assembly = seconds_since(t0);
}

double KernelSystem::cg_total_bytes() const {
  return detail::kernel_matrix_bytes(a_) +
         detail::cg_bytes(a_.values().size(), size(), options_.schwarz, !cg_in_place_);
}

// The solver, and the one ordering it needs. Auto weighs the envelope's work in reverse
// Cuthill-McKee order against CG's; the envelope solver then compares the four orderings (when asked
// for Auto), CG keeps RCM for the locality of its products, and CHOLMOD and Eigen order the matrix
// themselves. No ordering is computed only to be thrown away.
Solver KernelSystem::ordering_and_solver() {
  const KernelSystemOptions& options = options_;
  const AdjacencyGraph& g = a_.pattern();
  const std::size_t n = size();
  FitStats& stats = stats_;
  const auto t0 = Clock::now();
  Solver solver = options.solver;
  if (solver == Solver::Cholmod && !cholmod_available())
    throw InvalidInput("solver 'cholmod': " + detail::cholmod_load_error() + "; use 'envelope' or 'eigen'");
  cg_in_place_ = options.schwarz_sorted;
  schwarz_bytes_ = 0;
  if (options.schwarz && (solver == Solver::Auto || solver == Solver::Cg) && options.dimension >= 2 &&
      n >= detail::kSchwarzOnlyPoints &&
      2.0 * double(stats.neighbor_pairs) >= detail::kSchwarzOnlyNeighbors * double(n))
    schwarz_bytes_ = cg_total_bytes();  // what the Schwarz path would hold, A in place where sorted
  if (schwarz_bytes_ > 0 && schwarz_bytes_ <= options.memory_limit_bytes) {
    // csrbf::Interpolator's scattered points in 2-D or 3-D, many and well connected: the envelope
    // cannot win (RCM's envelope work is above kEnvelopeWorkLimit there: 1.5e8 at 2e4 planar points
    // with 6 neighbours, 2.2e9 with 40; test_schwarz.cpp checks it), so RCM and the envelope's count
    // are not computed (10% of a fit of 1e5 points). CG's rows are in the Schwarz patches' spatial
    // order; where Auto's probe finds CG too slow, the direct solver takes over (never the envelope:
    // its work is counted as infinite). Where CG would pass the memory limit, Auto weighs the
    // envelope as before (points on a curve: its envelope is small). Points sorted so already: CG
    // reads A in place, in its own order.
    order_ = options.schwarz_sorted ? identity_order(n) : detail::schwarz_order(cloud_->points, options.radius);
    stats.ordering = Ordering::Identity;
    stats.envelope_work = std::numeric_limits<double>::infinity();
    stats.dense_bytes = 4 * n * n;
    stats.solver = Solver::Cg;
    stats.seconds_ordering = seconds_since(t0);
    return Solver::Cg;
  }
  cg_in_place_ = false;  // any other path copies A's rows into CG's order (RCM)
  std::vector<std::size_t> first;
  if (solver == Solver::Auto || solver == Solver::Cg ||
      (solver == Solver::Envelope && options.ordering != Ordering::Auto)) {
    const Ordering one = options.ordering == Ordering::Auto ? Ordering::ReverseCuthillMcKee : options.ordering;
    order_ = compute_ordering(g, one);
    stats.ordering = one;
    profile_of(stats, one) = profile(g, order_);
    first = envelope_first_columns(g, order_);
    stats.envelope_work = envelope_work(first);
    solver = resolve_solver(solver, stats.envelope_work, n, stats.neighbor_pairs);
  }
  if (solver == Solver::Envelope && options.ordering == Ordering::Auto) {
    // The paper's choice: the smallest envelope of the four orderings, RCM's reused.
    OrderingChoice c = choose_ordering(g, Ordering::Auto, std::move(order_));
    order_ = std::move(c.order);
    stats.ordering = c.chosen;
    stats.identity = c.identity;
    stats.breadth_first = c.breadth_first;
    stats.reverse_breadth_first = c.reverse_breadth_first;
    stats.reverse_cuthill_mckee = c.reverse_cuthill_mckee;
    stats.orderings_compared = true;
    first = envelope_first_columns(g, order_);
    stats.envelope_work = envelope_work(first);
  }
  if (!order_.empty()) {
    const Profile chosen = profile_of(stats, stats.ordering);
    stats.bandwidth = chosen.bandwidth;
    stats.envelope_entries = chosen.envelope;
    stats.envelope_bytes = 4 * (n + chosen.envelope) + 4 * n;
  }
  stats.dense_bytes = 4 * n * n;
  first_columns_ = std::move(first);
  stats.solver = solver;
  stats.seconds_ordering = seconds_since(t0);
  return solver;
}

void KernelSystem::factorise() {
  if (a_.size() != size()) throw UsageError("KernelSystem: call analyse() before factorise()");
  if (solver_) throw UsageError("KernelSystem: factorise() was called already (once a system)");
  info_ = SystemInfo::Success;
  if (chosen_ == Solver::Envelope) {
    try {
      factorise_envelope();
    } catch (const NotPositiveDefinite&) {
      if (!(options_.solver == Solver::Auto && options_.direct_after_breakdown)) throw;
      const std::exception_ptr breakdown = std::current_exception();
      const auto t0 = Clock::now();
      first_columns_ = {};
      solver_ = detail::AutoSolver::after_breakdown(a_, cloud_->points, options_.memory_limit_bytes, breakdown);
      order_ = identity_order(size());  // the sparse solvers take and give the input order
      in_order_ = false;
      stats_.solver = cholmod_available() ? Solver::Cholmod : Solver::Eigen;
      stats_.factor_nonzeros = solver_->nonzeros();
      stats_.seconds_factorization = seconds_since(t0);
    }
  } else {
    factorise_sparse();
  }
  polynomial_block();
}

// The envelope Cholesky of A in its ordering: A lives beside its envelope (the residual check reads it).
void KernelSystem::factorise_envelope() {
  const std::size_t n = size();
  FitStats& stats = stats_;
  detail::check_envelope_size(first_columns_, options_.memory_limit_bytes, ordering_name(stats.ordering),
                              detail::kernel_matrix_bytes(a_));
  auto t0 = Clock::now();
  EnvelopeMatrix env = envelope_matrix(a_, order_, std::move(first_columns_));
  stats.envelope_bytes = env.paper_bytes();
  stats.dense_bytes = env.dense_bytes();
  stats.seconds_assembly += seconds_since(t0);
  t0 = Clock::now();
  detail::envelope_cholesky(env, order_);
  stats.factor_nonzeros = stats.envelope_entries + n;
  solver_ = std::make_unique<EnvelopeInOrder>(std::move(env), stats.factor_nonzeros);
  in_order_ = true;
  stats.seconds_factorization = seconds_since(t0);
}

// CG's matrix in its row order (nothing to factorise: Auto's solver), or CHOLMOD's or Eigen's
// factorisation.
void KernelSystem::factorise_sparse() {
  const KernelSystemOptions& options = options_;
  const std::size_t n = size();
  FitStats& stats = stats_;
  first_columns_ = {};
  std::vector<std::uint32_t> rows = std::move(order_);
  order_ = identity_order(n);  // the sparse solvers take and give the input order
  in_order_ = false;
  const auto t0 = Clock::now();
  if (chosen_ == Solver::Cg) {
    // CG holds A's rows in its order beside A itself, and its vectors.
    const double bytes = cg_total_bytes();
    if (bytes > options.memory_limit_bytes) {
      std::ostringstream os;
      os.precision(3);
      os << "conjugate gradients would hold " << format_gib(bytes) << " for A's " << a_.values().size() + n
         << (cg_in_place_ ? " entries (read in place)" : " entries, their copy in CG's order")
         << " and their vectors, above the limit of " << format_gib(options.memory_limit_bytes)
         << " (FitOptions::memory_limit_bytes, `--memory-limit`)";
      // The interpolator's sorted points: the Schwarz path, refused for its bytes alone, needs less.
      if (!cg_in_place_ && schwarz_bytes_ > 0 && schwarz_bytes_ < bytes)
        os << "; with the Schwarz patches, which read A in place, " << format_gib(schwarz_bytes_);
      os << ". Use a smaller radius";
      throw ResourceLimit(os.str());
    }
    const detail::AutoInputs in{.asked = options.solver,
                                .memory_limit_bytes = options.memory_limit_bytes,
                                .ordering = stats.ordering,
                                .envelope_work = stats.envelope_work,
                                .envelope_entries = stats.envelope_entries,
                                .neighbor_pairs = stats.neighbor_pairs,
                                .work_columns = options.cg_work_columns,
                                .cg_total_bytes = bytes};
    detail::CgPreconditioner preconditioner;
    if (options.schwarz) preconditioner.points = cloud_->points;  // borrowed: the cloud outlives the solver
    auto solver = std::make_unique<detail::AutoSolver>(a_, cloud_->points, std::move(rows), in, preconditioner);
    auto_ = solver.get();
    solver_ = std::move(solver);
    stats.seconds_assembly += seconds_since(t0);
  } else {
    solver_ = detail::factor_sparse(a_, cloud_->points, chosen_, options.memory_limit_bytes);
    stats.seconds_factorization = seconds_since(t0);
  }
  stats.factor_nonzeros = solver_->nonzeros();
}

// George & Liu's block elimination, the part that depends on the points only: Y = A^-1 P and the
// Cholesky factor of P^T Y. Not where the points do not determine a linear polynomial.
void KernelSystem::polynomial_block() {
  if (terms_ == 0) return;
  if (polynomial_degenerate()) {
    info_ = SystemInfo::DegeneratePolynomial;
    return;
  }
  const auto t0 = Clock::now();
  const std::size_t n = size();
  p_.resize(Eigen::Index(n), terms_);
  for (std::size_t k = 0; k < n; ++k) {
    p_(Eigen::Index(k), 0) = 1.0;
    const Vec3 u = (cloud_->points[order_[k]] - center_) / scale_;
    for (int a = 1; a < terms_; ++a) p_(Eigen::Index(k), a) = u[a - 1];
  }
  y_ = p_;
  require(solve_columns(y_, nullptr));
  const bool handed = handed_over();
  const double taken = handed ? auto_->stage().seconds : 0.0;
  if (handed) stats_.seconds_factorization = taken;
  schur_.compute(p_.transpose() * y_);
  if (schur_.info() != Eigen::Success) info_ = SystemInfo::NumericalIssue;
  stats_.seconds_solve += seconds_since(t0) - taken;
}

SolveStatus KernelSystem::solve_columns(RowMatrix& b, const RowMatrix* guess) {
  if (std::size_t(b.cols()) <= kSolveColumns) return solver_->solve(b, guess);
  for (Eigen::Index c0 = 0; c0 < b.cols(); c0 += Eigen::Index(kSolveColumns)) {
    const Eigen::Index w = std::min<Eigen::Index>(Eigen::Index(kSolveColumns), b.cols() - c0);
    RowMatrix part = b.middleCols(c0, w);
    RowMatrix start;
    if (guess) start = guess->middleCols(c0, w);
    const SolveStatus s = solver_->solve(part, guess ? &start : nullptr);
    if (!s.ok()) return s;
    b.middleCols(c0, w) = part;
  }
  return {};
}

SolveStatus KernelSystem::solve(RowMatrix& b, Eigen::MatrixXd& beta, const RowMatrix* guess) {
  check_solve("solve()", solver_ != nullptr, size(), b, guess);
  const std::size_t n = size(), m = std::size_t(b.cols());
  // The envelope solves in its own order: b's rows (row-major, m a row) are copied into it and back.
  RowMatrix z;
  if (in_order_) {
    z.resize(b.rows(), b.cols());
    for (std::size_t k = 0; k < n; ++k) std::copy_n(b.data() + order_[k] * m, m, z.data() + k * m);
  }
  RowMatrix& rows = in_order_ ? z : b;
  const SolveStatus s = solve_columns(rows, guess);
  if (!s.ok()) return s;
  if (terms_ > 0) {
    beta = schur_.solve(p_.transpose() * rows);  // terms x m
    rows -= y_ * beta;
  } else {
    beta.resize(0, b.cols());
  }
  if (in_order_)
    for (std::size_t k = 0; k < n; ++k) std::copy_n(z.data() + k * m, m, b.data() + order_[k] * m);
  return s;
}

SolveStatus KernelSystem::solve_matrix(RowMatrix& b) {
  check_solve("solve_matrix()", solver_ != nullptr, size(), b, nullptr);
  return solve_columns(b, nullptr);
}

void KernelSystem::require(const SolveStatus& status) {
  if (!status.ok()) throw detail::CgStagnated(status);
}

KernelSystem::Residual KernelSystem::residual(const RowMatrix& alpha, const Eigen::MatrixXd& beta,
                                              const RowMatrix& g) const {
  const std::size_t n = size();
  const auto m = g.cols();
  const RowMatrix a_alpha = a_ * alpha;
  Residual r;
  for (std::size_t i = 0; i < n; ++i) {
    const auto row = Eigen::Index(i);
    const Vec3 u = (cloud_->points[i] - center_) / scale_;
    double e2 = 0, g2 = 0;
    for (Eigen::Index c = 0; c < m; ++c) {
      double v = a_alpha(row, c);
      if (terms_ > 0) {
        // p(x) = beta_0 + sum_a u_a beta_{1+a}, summed in this order (SpaceMap's evaluation of it).
        double linear = 0;
        for (int a = 0; a + 1 < terms_; ++a) linear = a == 0 ? u[0] * beta(1, c) : linear + u[a] * beta(1 + a, c);
        v += terms_ > 1 ? beta(0, c) + linear : beta(0, c);
      }
      const double d = v - g(row, c);
      e2 += d * d;
      g2 += g(row, c) * g(row, c);
    }
    const double e = std::sqrt(e2);
    r.max = std::isnan(e) ? std::numeric_limits<double>::infinity() : std::max(r.max, e);
    r.largest = std::max(r.largest, std::sqrt(g2));
  }
  // A solve that overflowed leaves NaN or infinite coefficients (std::max above would drop a NaN).
  if (!alpha.allFinite() || (terms_ > 0 && !beta.allFinite())) r.max = std::numeric_limits<double>::infinity();
  r.relative = r.largest > 0.0 ? r.max / r.largest : r.max;
  return r;
}

double KernelSystem::condition() {
  // lambda_max by power iteration with A, lambda_min by inverse iteration with the factorisation. A
  // is symmetric positive definite, so both converge to the extreme eigenvalues.
  std::call_once(condition_once_, [this] {
    const std::size_t n = size();
    const double phi0 = a_.diagonal();
    RowMatrix v = RowMatrix::Constant(Eigen::Index(n), 1, 1.0 / std::sqrt(double(n)));
    double lmax = phi0;
    for (int it = 0; it < 30; ++it) {
      const RowMatrix av = a_ * v;
      const double norm = av.norm();
      if (!(norm > 0)) break;
      lmax = norm;
      v = av / norm;
    }
    if (warm_starts()) {
      // No factor to reuse: each inverse step would be a whole CG solve. Lanczos on A gives both
      // extreme eigenvalues from products alone (the Ritz values of its tridiagonal matrix).
      const auto [lo, hi] = detail::lanczos_extremes(a_, 20261201);
      condition_ = hi / lo;
      return;
    }
    RowMatrix x = RowMatrix::Constant(Eigen::Index(n), 1, 1.0 / std::sqrt(double(n)));
    double lmin_inv = 1.0 / phi0;
    for (int it = 0; it < 30; ++it) {
      require(solve_matrix(x));
      const double norm = x.norm();
      if (!(norm > 0) || !std::isfinite(norm)) break;
      lmin_inv = norm;
      x /= norm;
    }
    condition_ = lmax * lmin_inv;
  });
  return condition_;
}

Solver KernelSystem::solver() const { return handed_over() ? auto_->stage().solver : stats_.solver; }
bool KernelSystem::handed_over() const { return auto_ && auto_->stage().handed_over; }
std::size_t KernelSystem::iterations() const { return solver_ ? solver_->iterations() : 0; }
bool KernelSystem::warm_starts() const { return solver_ && solver_->iterative(); }

void KernelSystem::report(FitStats& stats, bool handed_over_before) const {
  if (in_order_ || !solver_) return;  // the envelope: no steps to report
  if (!auto_) {
    stats.iterations = solver_->iterations();
    stats.solver_residual = solver_->residual();
    return;
  }
  stats.iterations = auto_->cg_iterations();
  stats.solver_residual = auto_->cg_residual();
  const detail::AutoSolver::Stage stage = auto_->stage();
  if (!stage.handed_over) return;
  // The solver that took over factorised inside this solve (else in the polynomial block's, which
  // counted it, or in an earlier map's).
  if (!handed_over_before) {
    stats.seconds_factorization = stage.seconds;
    stats.seconds_solve -= stage.seconds;
  }
  stats.fell_back = stage.solver != Solver::Cg;
  stats.solver = stage.solver;
  if (stage.taken) {  // else CG went on, the direct factors refused by the memory limit
    stats.factor_nonzeros = stage.taken->nonzeros();
    if (stage.taken->iterative()) {
      stats.iterations = stage.taken->iterations();
      stats.solver_residual = stage.taken->residual();
    }
  }
}

}  // namespace csrbf
