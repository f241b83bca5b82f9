#include "csrbf/space_map.hpp"

#include "evaluator.hpp"
#include "sparse_solver.hpp"

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <mutex>
#include <type_traits>

namespace csrbf {

std::string_view polynomial_name(Polynomial p) noexcept {
  switch (p) {
    case Polynomial::None: return "none";
    case Polynomial::Constant: return "constant";
    case Polynomial::Linear: return "linear";
  }
  return "?";
}

std::string_view solver_name(Solver s) noexcept {
  switch (s) {
    case Solver::Envelope: return "envelope";
    case Solver::Eigen: return "eigen";
    case Solver::Cholmod: return "cholmod";
    case Solver::Auto: return "auto";
    case Solver::Cg: return "cg";
  }
  return "?";
}

std::optional<Solver> parse_solver(std::string_view name) noexcept {
  std::string s(name);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (s == "envelope") return Solver::Envelope;
  if (s == "eigen") return Solver::Eigen;
  if (s == "cholmod") return Solver::Cholmod;
  if (s == "auto") return Solver::Auto;
  if (s == "cg") return Solver::Cg;
  return std::nullopt;
}

bool cholmod_available() noexcept {
#ifdef CSRBF_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

Solver resolve_solver(Solver requested, double envelope_work, std::size_t controls, std::size_t neighbor_pairs) noexcept {
  if (requested != Solver::Auto) return requested;
  const double cg_work = kCgStepsEstimate * 3.0 * (2.0 * double(neighbor_pairs) + double(controls));
  if (envelope_work <= kEnvelopeWorkLimit && (controls == 0 || envelope_work <= cg_work)) return Solver::Envelope;
  return Solver::Cg;
}

void set_evaluation_loop(EvaluationLoop loop) {
  if (loop == EvaluationLoop::Avx512 && !detail::avx512_available())
    throw InvalidInput("evaluation loop 'avx512': this CPU or this build of csrbf has no AVX-512; use 'portable'");
  detail::set_eval_isa(loop == EvaluationLoop::Portable ? detail::EvalIsa::Portable : detail::EvalIsa::Avx512);
}

std::string_view evaluation_loop_name() noexcept {
  if (detail::eval_isa() == detail::EvalIsa::Avx512) return "avx512";
#if defined(__x86_64__) && defined(__GNUC__)
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "avx2";
#endif
  return "baseline";
}

std::optional<Polynomial> parse_polynomial(std::string_view name) noexcept {
  std::string s(name);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (s == "none") return Polynomial::None;
  if (s == "constant") return Polynomial::Constant;
  if (s == "linear") return Polynomial::Linear;
  return std::nullopt;
}

void check_phase(double phase) {
  // |phase| <= 1e6: beyond it x + phase d(x) can overflow for displacements that fit allows.
  if (!std::isfinite(phase) || std::abs(phase) > 1e6) {
    std::ostringstream os;
    os << "phase must be a finite number within [-1e6, 1e6], got " << phase;
    throw InvalidInput(os.str());
  }
}

namespace {

using Clock = std::chrono::steady_clock;
// The most memory the evaluation lists of one fit may take (evaluator.hpp); past it, evaluation goes
// through NeighborIndex.
constexpr std::size_t kEvalListBytes = std::size_t(512) << 20;
/// Up to this many sources the fit tests every pair for the neighbour graph (cheaper than the grid).
constexpr std::size_t kBruteForceGraph = 256;
/// Coordinates (and so distances) stay below this, so that their squares are finite.
constexpr double kMaxCoordinate = 1e150;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

int polynomial_terms(Polynomial p) {
  return p == Polynomial::None ? 0 : p == Polynomial::Constant ? 1 : 4;
}

void check_points(std::span<const Vec3> pts, const char* what) {
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (!pts[i].allFinite() || pts[i].cwiseAbs().maxCoeff() > kMaxCoordinate) {
      std::ostringstream os;
      os << what << " " << i << (pts[i].allFinite() ? " is out of range (a coordinate beyond 1e150)" : " is not finite")
         << ": (" << pts[i].x() << ", " << pts[i].y() << ", " << pts[i].z() << ")";
      throw InvalidInput(os.str());
    }
}

}  // namespace

// Everything that depends on the sources only: shared by every map made with with_destinations().
struct SpaceMap::Structure {
  FitOptions options;
  std::vector<Vec3> sources;       // input order
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
  const detail::EvalGrid& grid() const {
    std::call_once(grid_once, [this] { grid_ = detail::EvalGrid::build(sources, options.radius, kEvalListBytes); });
    return grid_;
  }
  AdjacencyGraph graph;            // input order
  std::vector<std::uint32_t> order;  // order[k] = input index of the source at row k
  EnvelopeMatrix factor;           // L, in `order` (Solver::Envelope)
  std::unique_ptr<detail::SparseFactor> sparse;  // the other solvers (then `order` is the identity)
  int terms = 0;                   // columns of P
  Vec3 center = Vec3::Zero();      // polynomial coordinates u = (x - center) / scale
  double scale = 1.0;
  RowMatrix p;                     // N x terms, in `order`
  RowMatrix y;                     // A^{-1} P, in `order`
  Eigen::LLT<Eigen::MatrixXd> schur;  // P^T A^{-1} P
  FitStats stats;                  // the structural part and its times

  void solve_in_place(RowMatrix& b) const {
    if (!sparse) {
      factor.solve_in_place(b);
      return;
    }
    if (!fell_back.load()) {
      try {
        sparse->solve_in_place(b);  // CG writes b only when it converged
        return;
      } catch (const detail::CgStagnated&) {
      }
      // CG stagnated (an ill-conditioned system): a direct factorisation takes over, once, for this
      // fit and every later solve with these sources.
      std::call_once(fallback_once, [this] {
        const Solver direct = cholmod_available() ? Solver::Cholmod : Solver::Eigen;
        fallback = detail::factor_sparse(graph, sources, options.kernel, options.radius, direct, options.memory_limit_bytes);
        fallback_solver = direct;
        fell_back = true;
      });
    }
    fallback->solve_in_place(b);
  }
  mutable std::once_flag fallback_once;
  mutable std::unique_ptr<detail::SparseFactor> fallback;  // when CG stagnated
  mutable Solver fallback_solver = Solver::Auto;
  mutable std::atomic<bool> fell_back{false};

  /// A x through the neighbour graph (the sparse rows of A), rows in the input order of the sources.
  Eigen::MatrixXd times_a(const Eigen::MatrixXd& x) const {
    const double inv_r = 1.0 / options.radius, phi0 = wendland(options.kernel, 0.0);
    Eigen::MatrixXd y(x.rows(), x.cols());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, sources.size(), 4096), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i < r.end(); ++i) {
        const auto k = Eigen::Index(i);
        y.row(k) = phi0 * x.row(k);
        const auto nb = graph.neighbors_of(i);
        const auto d2 = graph.dist2_of(i);
        for (std::size_t e = 0; e < nb.size(); ++e)
          y.row(k) += wendland(options.kernel, std::sqrt(d2[e]) * inv_r) * x.row(Eigen::Index(nb[e]));
      }
    });
    return y;
  }

  mutable std::once_flag condition_once;
  mutable double condition_ = 0;
  /// lambda_max by power iteration with A (through the graph), lambda_min by inverse iteration with
  /// the factorisation. A is symmetric positive definite, so both converge to the extreme eigenvalues.
  double condition() const {
    std::call_once(condition_once, [this] {
      const std::size_t n = sources.size();
      const double phi0 = wendland(options.kernel, 0.0);
      Eigen::MatrixXd v = Eigen::MatrixXd::Constant(Eigen::Index(n), 1, 1.0 / std::sqrt(double(n)));
      double lmax = phi0;
      for (int it = 0; it < 30; ++it) {
        const Eigen::MatrixXd av = times_a(v);
        const double norm = av.norm();
        if (!(norm > 0)) break;
        lmax = norm;
        v = av / norm;
      }
      RowMatrix x = RowMatrix::Constant(Eigen::Index(n), 1, 1.0 / std::sqrt(double(n)));
      double lmin_inv = 1.0 / phi0;
      // Each inverse step is a whole solve: with CG (no factor to reuse) fewer of them, a rougher estimate.
      const int inverse_steps = stats.solver == Solver::Cg && !fell_back ? 8 : 30;
      for (int it = 0; it < inverse_steps; ++it) {
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
  mutable std::once_flag once_double, once_float, once_float_trust;
  mutable bool float_ok = true;       // float evaluation agrees with double (float_trusted())
  mutable double float_error = 0;     // the largest difference measured
  mutable detail::EvalData<double> data_double;
  mutable detail::EvalData<float> data_float;
  template <class T>
  const detail::EvalData<T>& eval_data() const {
    auto& flag = std::is_same_v<T, double> ? once_double : once_float;
    auto& data = [this]() -> detail::EvalData<T>& {
      if constexpr (std::is_same_v<T, double>) return data_double;
      else return data_float;
    }();
    std::call_once(flag, [&] {
      const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> rows = alpha;
      data.assign(st->grid(), st->sources, rows.data(), st->options.kernel);
    });
    return data;
  }
  detail::PolynomialPart poly;                     // beta for the evaluator
  Eigen::Matrix<double, 4, 3> beta = Eigen::Matrix<double, 4, 3>::Zero();  // in u coordinates
  FitStats stats;

  /// p(x); beta's absent rows are zero, so this serves constant and linear alike.
  Vec3 polynomial_at(const Vec3& x) const {
    const Vec3 u = (x - st->center) / st->scale;
    return (beta.row(0) + u.transpose() * beta.bottomRows<3>()).transpose();
  }
};

SpaceMap SpaceMap::fit(std::span<const Vec3> sources, std::span<const Vec3> destinations,
                       const FitOptions& options) {
  if (sources.size() != destinations.size()) {
    std::ostringstream os;
    os << "control points: " << sources.size() << " sources but " << destinations.size() << " destinations";
    throw InvalidInput(os.str());
  }
  if (sources.empty()) throw InvalidInput("control points: none given (need at least 1)");
  // Squared distances and radii must stay normal doubles: R in [1e-150, 1e150].
  if (!(options.radius >= 1e-150 && options.radius <= 1e150)) {
    std::ostringstream os;
    os << "radius must be a positive finite number in [1e-150, 1e150], got " << options.radius;
    throw InvalidInput(os.str());
  }
  if (!(options.memory_limit_bytes > 0)) {  // NaN must not switch the limit off
    std::ostringstream os;
    os << "memory_limit_bytes must be a number > 0, got " << options.memory_limit_bytes;
    throw InvalidInput(os.str());
  }
  check_points(sources, "source");
  check_points(destinations, "destination");
  {
    // The same limit NeighborIndex applies, checked here because small fits build it only later.
    Vec3 lo = sources[0], hi = sources[0];
    for (const auto& p : sources) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    NeighborIndex::check_extent(lo, hi, options.radius, "sources");
  }
  const std::size_t n = sources.size();
  const int terms = polynomial_terms(options.polynomial);

  auto st = std::make_shared<Structure>();
  st->options = options;
  st->sources.assign(sources.begin(), sources.end());
  st->terms = terms;
  FitStats& stats = st->stats;
  stats.controls = n;

  // Polynomial coordinates and their degeneracy, checked before any heavy work.
  st->center = Vec3::Zero();
  for (const auto& s : sources) st->center += s;
  st->center /= double(n);
  double spread = 0.0;
  for (const auto& s : sources) spread = std::max(spread, (s - st->center).cwiseAbs().maxCoeff());
  st->scale = spread > 0.0 ? spread : 1.0;
  if (options.polynomial == Polynomial::Linear) {
    if (n < 4) {
      std::ostringstream os;
      os << "polynomial 'linear' needs at least 4 control points that are not coplanar, got " << n
         << "; use polynomial 'constant' or 'none'";
      throw DegeneratePolynomial(os.str());
    }
    Eigen::MatrixXd u(n, 3);
    for (std::size_t i = 0; i < n; ++i) u.row(Eigen::Index(i)) = (sources[i] - st->center) / st->scale;
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::MatrixXd>(u).singularValues();
    const double tol = 1e-9 * std::max(sv(0), 1e-300);
    if (sv(2) <= tol) {
      std::ostringstream os;
      os << "polynomial 'linear' needs control sources that span 3-D space, but the " << n << " sources are "
         << (sv(1) <= tol ? "collinear" : "coplanar") << " (singular values " << sv(0) << ", " << sv(1) << ", "
         << sv(2) << "); use polynomial 'constant' or 'none'";
      throw DegeneratePolynomial(os.str());
    }
  }

  auto t0 = Clock::now();
  // The neighbour graph: every pair for a few hundred sources (the grid is then left to the first
  // evaluation); from the grid's cell lists above that; from NeighborIndex where the grid is unusable.
  if (n > kBruteForceGraph) {
    const FitMemoryEstimate m = estimate_fit_memory(sources, options.radius);
    if (m.bytes > options.memory_limit_bytes) {
      std::ostringstream os;
      os.precision(3);
      os << "radius " << options.radius << " gives each source about " << m.mean_neighbors << " neighbours ("
         << 100.0 * m.mean_neighbors / double(n - 1) << "% of the " << n << " sources): the fit would need about "
         << m.bytes / double(1ull << 30) << " GiB for its neighbour graph and factor, above the limit of "
         << options.memory_limit_bytes / double(1ull << 30)
         << " GiB (FitOptions::memory_limit_bytes, `--memory-limit`). Use a smaller radius: the compact support "
            "is what keeps the system sparse";
      throw ResourceLimit(os.str());
    }
  }
  const bool brute = n <= kBruteForceGraph;
  if (!brute && !st->grid().usable) st->index();
  stats.seconds_index = seconds_since(t0);

  t0 = Clock::now();
  if (brute)
    st->graph = AdjacencyGraph::brute_force(sources, options.radius);
  else if (st->grid().usable)
    st->grid().neighbor_graph(sources, st->graph.offsets, st->graph.neighbors, st->graph.dist2);
  else
    st->graph = AdjacencyGraph::from_index(st->index(), sources);
  stats.seconds_graph = seconds_since(t0);
  stats.neighbor_pairs = st->graph.neighbors.size() / 2;
  stats.mean_neighbors = double(st->graph.neighbors.size()) / double(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto nb = st->graph.neighbors_of(i);
    const auto d2 = st->graph.dist2_of(i);
    for (std::size_t k = 0; k < nb.size(); ++k)
      if (d2[k] == 0.0) {
        const std::size_t a = std::min<std::size_t>(i, nb[k]), b = std::max<std::size_t>(i, nb[k]);
        std::ostringstream os;
        os << "control sources " << a << " and " << b << " are at the same position (" << sources[a].x() << ", "
           << sources[a].y() << ", " << sources[a].z() << ")";
        throw DuplicateSource(a, b, os.str());
      }
  }

  t0 = Clock::now();
  OrderingChoice oc = choose_ordering(st->graph, options.ordering);
  st->order = std::move(oc.order);
  stats.ordering = oc.chosen;
  stats.identity = oc.identity;
  stats.breadth_first = oc.breadth_first;
  stats.reverse_breadth_first = oc.reverse_breadth_first;
  stats.reverse_cuthill_mckee = oc.reverse_cuthill_mckee;

  // Work of the envelope factorisation in this order: row k costs about (row length)^2 / 2.
  std::vector<std::size_t> first = envelope_first_columns(st->graph, st->order);
  stats.envelope_work = envelope_work(first);
  const Solver solver = resolve_solver(options.solver, stats.envelope_work, n, stats.neighbor_pairs);
  if (solver == Solver::Cholmod && !cholmod_available())
    throw InvalidInput("solver 'cholmod': this build of csrbf has no CHOLMOD (SuiteSparse); use 'envelope' or 'eigen'");
  stats.solver = solver;
  stats.seconds_ordering = seconds_since(t0);

  if (solver == Solver::Envelope) {
    // The envelope of the chosen order is known exactly now, before it is allocated.
    double entries = double(n);
    for (std::size_t k = 0; k < n; ++k) entries += double(k - first[k]);
    if (8 * entries > options.memory_limit_bytes) {
      std::ostringstream os;
      os.precision(3);
      os << "the envelope of the " << ordering_name(stats.ordering) << " ordering holds " << entries
         << " entries, about " << 8 * entries / double(1ull << 30) << " GiB, above the limit of "
         << options.memory_limit_bytes / double(1ull << 30)
         << " GiB (FitOptions::memory_limit_bytes, `--memory-limit`). Use another ordering or solver, or a smaller radius";
      throw ResourceLimit(os.str());
    }
    t0 = Clock::now();
    EnvelopeMatrix a = kernel_matrix(st->graph, st->order, std::move(first), options.kernel, options.radius);
    stats.bandwidth = a.bandwidth();
    stats.envelope_entries = a.envelope_entries();
    stats.envelope_bytes = a.paper_bytes();
    stats.dense_bytes = a.dense_bytes();
    stats.seconds_assembly = seconds_since(t0);

    t0 = Clock::now();
    try {
      a.cholesky_in_place();
    } catch (const NotPositiveDefinite& e) {
      // Report the control's input index, not its row in the ordered matrix.
      throw NotPositiveDefinite(st->order[e.row()], e.pivot());
    }
    st->factor = std::move(a);
    stats.factor_nonzeros = stats.envelope_entries + n;
    stats.seconds_factorization = seconds_since(t0);
  } else {
    // The profile the envelope solver would have had, for comparison.
    const Profile chosen = stats.ordering == Ordering::Identity              ? stats.identity
                           : stats.ordering == Ordering::BreadthFirst        ? stats.breadth_first
                           : stats.ordering == Ordering::ReverseBreadthFirst ? stats.reverse_breadth_first
                                                                            : stats.reverse_cuthill_mckee;
    stats.bandwidth = chosen.bandwidth;
    stats.envelope_entries = chosen.envelope;
    stats.envelope_bytes = 4 * (n + chosen.envelope) + 4 * n;
    stats.dense_bytes = 4 * n * n;
    std::vector<std::uint32_t> envelope_order = std::move(st->order);
    st->order = identity_order(n);
    t0 = Clock::now();
    if (solver == Solver::Cg) {
      // Rows in the envelope ordering for locality in the products; nothing to factorise.
      // Chosen by Auto, CG may spend only a tenth of the envelope's work (an upper bound of a direct
      // factorisation's) before a direct solver takes over: a system it converges on slowly (dense,
      // ill-conditioned) costs little more than the direct solve would have.
      std::size_t steps = kCgMaxIterations;
      if (options.solver == Solver::Auto) {
        const double step = 3.0 * (2.0 * double(stats.neighbor_pairs) + double(n));
        steps = std::size_t(std::clamp(stats.envelope_work / (10.0 * step), 50.0, double(kCgMaxIterations)));
      }
      st->sparse = detail::conjugate_gradients(st->graph, options.kernel, options.radius, std::move(envelope_order),
                                               kCgTolerance, steps);
      stats.seconds_assembly = seconds_since(t0);
    } else {
      st->sparse = detail::factor_sparse(st->graph, sources, options.kernel, options.radius, solver,
                                         options.memory_limit_bytes);
      stats.seconds_factorization = seconds_since(t0);
    }
    stats.factor_nonzeros = st->sparse->nonzeros();
  }

  if (terms > 0) {
    t0 = Clock::now();
    st->p.resize(Eigen::Index(n), terms);
    for (std::size_t k = 0; k < n; ++k) {
      st->p(Eigen::Index(k), 0) = 1.0;
      if (terms == 4) {
        const Vec3 u = (sources[st->order[k]] - st->center) / st->scale;
        st->p.block<1, 3>(Eigen::Index(k), 1) = u.transpose();
      }
    }
    st->y = st->p;
    st->solve_in_place(st->y);
    st->schur.compute(st->p.transpose() * st->y);
    if (st->schur.info() != Eigen::Success)
      throw DegeneratePolynomial(std::string("polynomial '") + std::string(polynomial_name(options.polynomial)) +
                                 "': the sources do not determine it; use polynomial 'none'");
    stats.seconds_solve += seconds_since(t0);
  }
  auto structure_only = std::make_shared<State>();
  structure_only->st = std::move(st);
  return SpaceMap(std::move(structure_only)).solve_destinations(destinations);
}

SpaceMap SpaceMap::with_destinations(std::span<const Vec3> destinations) const {
  if (destinations.size() != size()) {
    std::ostringstream os;
    os << "control points: " << size() << " sources but " << destinations.size() << " destinations";
    throw InvalidInput(os.str());
  }
  check_points(destinations, "destination");
  return solve_destinations(destinations);
}

SpaceMap SpaceMap::solve_destinations(std::span<const Vec3> destinations) const {
  const Structure& st = *s_->st;
  const std::size_t n = st.sources.size();
  auto s = std::make_shared<State>();
  s->st = s_->st;
  s->destinations.assign(destinations.begin(), destinations.end());
  s->stats = st.stats;
  FitStats& stats = s->stats;

  auto t0 = Clock::now();
  RowMatrix z(Eigen::Index(n), 3);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = st.order[k];
    z.row(Eigen::Index(k)) = (destinations[i] - st.sources[i]).transpose();
  }
  st.solve_in_place(z);
  if (st.terms > 0) {
    const Eigen::MatrixXd b = st.schur.solve(st.p.transpose() * z);  // terms x 3
    z -= st.y * b;
    s->beta.topRows(st.terms) = b;
  }
  s->alpha.resize(Eigen::Index(n), 3);
  for (std::size_t k = 0; k < n; ++k) s->alpha.row(st.order[k]) = z.row(Eigen::Index(k));
  s->poly.center = st.center;
  s->poly.inv_scale = 1.0 / st.scale;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 3; ++c) s->poly.b[r][c] = s->beta(r, c);
  stats.seconds_solve += seconds_since(t0);
  if (st.sparse) {
    stats.iterations = st.sparse->iterations();
    stats.solver_residual = st.sparse->residual();
    if (st.fell_back) {
      stats.fell_back = true;
      stats.solver = st.fallback_solver;
      stats.factor_nonzeros = st.fallback->nonzeros();
    }
  }

  // Residual at the controls, through the neighbour graph (the sparse rows of A, unpermuted).
  t0 = Clock::now();
  const Eigen::MatrixXd a_alpha = st.times_a(s->alpha);
  double res = 0.0, gmax = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 v = a_alpha.row(Eigen::Index(i)).transpose() + s->polynomial_at(st.sources[i]);
    const Vec3 g = destinations[i] - st.sources[i];
    const double e = (v - g).norm();
    res = std::isnan(e) ? std::numeric_limits<double>::infinity() : std::max(res, e);
    gmax = std::max(gmax, g.norm());
  }
  // A solve that overflowed leaves NaN or infinite coefficients (std::max above would drop a NaN).
  if (!s->alpha.allFinite() || !s->beta.allFinite()) res = std::numeric_limits<double>::infinity();
  stats.residual_max = res;
  stats.residual_relative = gmax > 0.0 ? res / gmax : res;
  stats.seconds_residual = seconds_since(t0);
  if (stats.residual_relative <= kResidualLimit && gmax > 0 && s->alpha.cwiseAbs().maxCoeff() > 1e6 * gmax) {
    // Coefficients a million times the displacements: the system is ill-conditioned, and rounding in
    // the evaluation (distances recomputed from coordinates) is amplified as much. Measure the
    // residual through the evaluation itself.
    const SpaceMap m(s);
    std::vector<double> in(3 * n), d(3 * n);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) in[3 * i + std::size_t(c)] = st.sources[i][c];
    m.displacements(in.data(), d.data(), n);
    double eval_res = 0;
    for (std::size_t i = 0; i < n; ++i)
      eval_res = std::max(eval_res, (Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]) - (destinations[i] - st.sources[i])).norm());
    stats.residual_max = std::max(stats.residual_max, eval_res);
    stats.residual_relative = stats.residual_max / gmax;
  }
  if (!(stats.residual_relative <= kResidualLimit)) {
    // Name the closest pair of sources: nearly coincident sources are what makes A nearly singular.
    double best = std::numeric_limits<double>::infinity();
    std::size_t a = 0, b = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto nb = st.graph.neighbors_of(i);
      const auto d2 = st.graph.dist2_of(i);
      for (std::size_t e = 0; e < nb.size(); ++e)
        if (d2[e] < best) best = d2[e], a = i, b = nb[e];
    }
    std::ostringstream os;
    os << "the controls cannot be interpolated to a relative residual of " << kResidualLimit << " (got "
       << stats.residual_relative << "): the matrix is too ill-conditioned (condition estimate "
       << st.condition() << ")";
    if (std::isfinite(best))
      os << "; the closest sources, " << std::min(a, b) << " and " << std::max(a, b) << ", are "
         << std::sqrt(best) / st.options.radius << " R apart. Merge or separate them, or use a larger radius";
    throw IllConditioned(os.str());
  }
  return SpaceMap(std::move(s));
}

FitMemoryEstimate estimate_fit_memory(std::span<const Vec3> sources, double radius) {
  const std::size_t n = sources.size();
  FitMemoryEstimate e;
  if (n < 2) return e;
  // Neighbours of a seeded sample of sources, counted against all of them (O(256 n)).
  const std::size_t samples = std::min<std::size_t>(n, 256);
  std::mt19937_64 rng(12345);
  const double r2 = radius * radius;
  double count = 0;
  for (std::size_t k = 0; k < samples; ++k) {
    const std::size_t i = samples == n ? k : std::size_t(rng() % n);
    const Vec3& p = sources[i];
    for (std::size_t j = 0; j < n; ++j) count += j != i && (sources[j] - p).squaredNorm() < r2;
  }
  e.mean_neighbors = count / double(samples);
  const double nd = double(n), pairs = nd * e.mean_neighbors / 2;
  // Graph: both directions, a 4-byte index and an 8-byte squared distance each. The sparse solvers'
  // lower triangle (an 8-byte value and a 4-byte index an entry), held beside the graph. Factor: at
  // least that triangle again, and for a dense-ish matrix the full N^2 / 2 of the envelope. The
  // solver's own analysis checks the factor's real size later, before it is allocated.
  const double graph = 2 * pairs * 12, matrix = 12 * (pairs + nd);
  const double factor = std::max(12 * (pairs + nd), e.mean_neighbors > nd / 4 ? 4 * nd * nd : 0.0);
  e.bytes = graph + matrix + factor;
  return e;
}

double SpaceMap::condition_estimate() const { return s_->st->condition(); }

Vec3 SpaceMap::displacement(const Vec3& x) const {
  const Structure& st = *s_->st;
  const double inv_r = 1.0 / st.options.radius;
  const Kernel k = st.options.kernel;
  Vec3 d = Vec3::Zero();
  const std::vector<Vec3>& alpha = s_->alpha_by_slot();
  st.index().for_each_slot_within(x, [&](std::size_t slot, double d2) {
    d += wendland(k, std::sqrt(d2) * inv_r) * alpha[slot];
  });
  if (st.terms > 0) d += s_->polynomial_at(x);
  return d;
}

Eigen::Matrix3d SpaceMap::jacobian(const Vec3& x, double phase) const {
  const Structure& st = *s_->st;
  const double inv_r = 1.0 / st.options.radius;
  const Kernel k = st.options.kernel;
  Eigen::Matrix3d j = Eigen::Matrix3d::Zero();
  const NeighborIndex& index = st.index();
  const std::vector<Vec3>& alpha = s_->alpha_by_slot();
  index.for_each_slot_within(x, [&](std::size_t slot, double d2) {
    const double dist = std::sqrt(d2);
    if (dist == 0.0) return;  // grad phi(0) = 0 for C2+; the one-sided C0 cone has no gradient there
    const Vec3 grad = (wendland_derivative(k, dist * inv_r) * inv_r / dist) * (x - index.point(slot));
    j += alpha[slot] * grad.transpose();
  });
  if (st.terms == 4) j += s_->beta.bottomRows<3>().transpose() / st.scale;
  return Eigen::Matrix3d::Identity() + phase * j;
}

bool SpaceMap::float_trusted() const {
  std::call_once(s_->once_float_trust, [this] {
    // Single-precision evaluation sums terms of the coefficients' size: when they are far larger
    // than the displacements (an ill-conditioned fit) or the model sits far from the origin, the
    // float sum can be garbage although the double one is exact. Compare both on (a seeded sample
    // of) the sources, rounded to float first so that only the evaluation differs.
    const Structure& st = *s_->st;
    const std::size_t n = st.sources.size(), m = std::min<std::size_t>(n, 4096);
    std::mt19937_64 rng(20261201);
    std::vector<float> inf(3 * m), outf(3 * m);
    std::vector<double> ind(3 * m), outd(3 * m);
    double gmax = 0;
    for (std::size_t i = 0; i < n; ++i) gmax = std::max(gmax, (s_->destinations[i] - st.sources[i]).norm());
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t i = m == n ? k : std::size_t(rng() % n);
      for (int c = 0; c < 3; ++c) {
        inf[3 * k + std::size_t(c)] = float(st.sources[i][c]);
        ind[3 * k + std::size_t(c)] = double(inf[3 * k + std::size_t(c)]);
      }
    }
    apply_direct(inf.data(), outf.data(), m, 1.0, false);
    apply_direct(ind.data(), outd.data(), m, 1.0, false);
    double err = 0;
    for (std::size_t k = 0; k < 3 * m; ++k) {
      const double e = std::abs(double(outf[k]) - outd[k]);
      err = std::isnan(e) ? std::numeric_limits<double>::infinity() : std::max(err, e);
    }
    s_->float_error = err;
    s_->float_ok = gmax == 0 ? err == 0 : err <= kFloatTolerance * gmax;
  });
  return s_->float_ok;
}

template <class T>
void SpaceMap::apply_impl(const T* in, T* out, std::size_t n, double phase, bool add_point) const {
  check_phase(phase);
  if constexpr (std::is_same_v<T, float>) {
    if (!float_trusted()) {
      // Evaluated in double, in blocks, and rounded once at the end.
      constexpr std::size_t block = 1 << 16;
      std::vector<double> a(3 * std::min(n, block)), b(a.size());
      for (std::size_t i0 = 0; i0 < n; i0 += block) {
        const std::size_t m = std::min(block, n - i0);
        for (std::size_t k = 0; k < 3 * m; ++k) a[k] = double(in[3 * i0 + k]);
        apply_direct(a.data(), b.data(), m, phase, add_point);
        for (std::size_t k = 0; k < 3 * m; ++k) out[3 * i0 + k] = float(b[k]);
      }
      return;
    }
  }
  apply_direct(in, out, n, phase, add_point);
}

template <class T>
void SpaceMap::apply_direct(const T* in, T* out, std::size_t n, double phase, bool add_point) const {
  const Structure& st = *s_->st;
  const detail::EvalGrid& grid = st.grid();
  if (grid.usable) {
    const detail::PolynomialPart* poly = st.terms > 0 ? &s_->poly : nullptr;
    const Kernel k = st.options.kernel;
    const detail::EvalData<T>& data = s_->template eval_data<T>();
    // Small batches in the calling thread: a task switch costs more than a game mesh's evaluation.
    constexpr std::size_t grain = 4096;
    if (n <= grain) {
      detail::evaluate(grid, data, k, poly, in, out, 0, n, phase, add_point);
      return;
    }
    if (n < (std::size_t(1) << 32) && detail::incoherent(grid, in, n)) {
      // Points in no spatial order: gathered by cell, evaluated in place, and written back in the
      // caller's order (in may be out: every point is read before any is written). The buffers stay
      // with the calling thread for its next batch.
      thread_local detail::CellOrder<T> scratch;
      detail::order_by_cell(grid, in, n, scratch);
      const std::uint32_t* order = scratch.order.data();
      scratch.points.resize(3 * n);
      T* points = scratch.points.data();
      // The gather and the scatter touch the caller's arrays at random: prefetched a few points
      // ahead, so that several misses are in flight at once.
      constexpr std::size_t ahead = 16;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t j = r.begin(); j < r.end(); ++j) {
          if (j + ahead < n) __builtin_prefetch(in + 3 * std::size_t(order[j + ahead]));
          for (int c = 0; c < 3; ++c) points[3 * j + c] = in[3 * std::size_t(order[j]) + c];
        }
        detail::evaluate(grid, data, k, poly, points, points, r.begin(), r.end(), phase, add_point);
      });
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t j = r.begin(); j < r.end(); ++j) {
          if (j + ahead < n) __builtin_prefetch(out + 3 * std::size_t(order[j + ahead]), 1);
          for (int c = 0; c < 3; ++c) out[3 * std::size_t(order[j]) + c] = points[3 * j + c];
        }
      });
      return;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
      detail::evaluate(grid, data, k, poly, in, out, r.begin(), r.end(), phase, add_point);
    });
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 2048), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const Vec3 x{double(in[3 * i]), double(in[3 * i + 1]), double(in[3 * i + 2])};
      const Vec3 d = displacement(x);
      if (add_point) {
        out[3 * i] = T(x.x() + phase * d.x());
        out[3 * i + 1] = T(x.y() + phase * d.y());
        out[3 * i + 2] = T(x.z() + phase * d.z());
      } else {
        out[3 * i] = T(d.x());
        out[3 * i + 1] = T(d.y());
        out[3 * i + 2] = T(d.z());
      }
    }
  });
}

void SpaceMap::apply(const double* in, double* out, std::size_t n, double phase) const {
  apply_impl(in, out, n, phase, true);
}
void SpaceMap::apply(const float* in, float* out, std::size_t n, double phase) const {
  apply_impl(in, out, n, phase, true);
}
void SpaceMap::apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) const {
  if (in.size() != out.size()) throw InvalidInput("apply: input and output sizes differ");
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three packed doubles");
  apply_impl(in.data()->data(), out.data()->data(), in.size(), phase, true);
}
void SpaceMap::displacements(const double* in, double* out, std::size_t n) const {
  apply_impl(in, out, n, 1.0, false);
}
void SpaceMap::displacements(const float* in, float* out, std::size_t n) const {
  apply_impl(in, out, n, 1.0, false);
}

std::size_t SpaceMap::size() const noexcept { return s_->st->sources.size(); }
double SpaceMap::radius() const noexcept { return s_->st->options.radius; }
Kernel SpaceMap::kernel() const noexcept { return s_->st->options.kernel; }
Polynomial SpaceMap::polynomial() const noexcept { return s_->st->options.polynomial; }
std::span<const Vec3> SpaceMap::sources() const noexcept { return s_->st->sources; }
std::span<const Vec3> SpaceMap::destinations() const noexcept { return s_->destinations; }
const Eigen::Matrix<double, Eigen::Dynamic, 3>& SpaceMap::coefficients() const noexcept { return s_->alpha; }
std::span<const std::uint32_t> SpaceMap::order() const noexcept { return s_->st->order; }
const FitStats& SpaceMap::stats() const noexcept { return s_->stats; }
const NeighborIndex& SpaceMap::index() const { return s_->st->index(); }

Eigen::Matrix<double, 4, 3> SpaceMap::polynomial_coefficients() const noexcept {
  // p(x) = b0 + (x - c)^T B / s  =>  constant b0 - c^T B / s, linear part B / s.
  const Structure& st = *s_->st;
  Eigen::Matrix<double, 4, 3> out;
  const Eigen::Matrix3d lin = s_->beta.bottomRows<3>() / st.scale;
  out.row(0) = s_->beta.row(0) - st.center.transpose() * lin;
  out.bottomRows<3>() = lin;
  return out;
}

EnvelopeMatrix kernel_matrix(const AdjacencyGraph& g, std::span<const std::uint32_t> order, Kernel kernel,
                             double radius) {
  return kernel_matrix(g, order, envelope_first_columns(g, order), kernel, radius);
}

EnvelopeMatrix kernel_matrix(const AdjacencyGraph& g, std::span<const std::uint32_t> order,
                             std::vector<std::size_t> first_columns, Kernel kernel, double radius) {
  const std::size_t n = g.size();
  std::vector<std::uint32_t> pos(n);
  for (std::size_t k = 0; k < n; ++k) pos[order[k]] = std::uint32_t(k);
  EnvelopeMatrix a(std::move(first_columns));
  const double inv_r = 1.0 / radius;
  const double phi0 = wendland(kernel, 0.0);
  for (std::size_t k = 0; k < n; ++k) {
    a.at(k, k) = phi0;
    const auto nb = g.neighbors_of(order[k]);
    const auto d2 = g.dist2_of(order[k]);
    for (std::size_t e = 0; e < nb.size(); ++e)
      if (pos[nb[e]] < k) a.at(k, pos[nb[e]]) = wendland(kernel, std::sqrt(d2[e]) * inv_r);
  }
  return a;
}

void deform(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options,
            double* points, std::size_t n, double phase) {
  SpaceMap::fit(sources, destinations, options).apply(points, points, n, phase);
}

}  // namespace csrbf
