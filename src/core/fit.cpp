// SpaceMap::fit, as the paper's phases (section 4), each a function below in the order it runs:
//   validate -> polynomial frame -> neighbour graph -> the matrix A -> ordering and solver
//   -> factorisation -> polynomial block -> solve -> residual check.
// with_destinations() reruns only the last two.
#include "cholmod_loader.hpp"
#include "csrbf/units.hpp"
#include "schwarz.hpp"
#include "fit_state.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace csrbf {

namespace {

/// Up to this many sources the fit tests every pair for the neighbour graph (cheaper than the grid).
constexpr std::size_t kBruteForceGraph = 256;

int polynomial_terms(Polynomial p) { return p == Polynomial::None ? 0 : p == Polynomial::Constant ? 1 : 4; }

std::string gib(double bytes) { return format_gib(bytes); }

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
using detail::check_points;

/// The phases, with access to SpaceMap's state.
struct FitPhases {
  using Structure = SpaceMap::Structure;
  using State = SpaceMap::State;

  /// Sizes, finite coordinates, the radius, the memory limit, the grid's extent.
  static void validate(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options) {
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
    if (options.ordering != Ordering::Auto && (options.solver == Solver::Eigen || options.solver == Solver::Cholmod))
      throw InvalidInput("ordering '" + std::string(ordering_name(options.ordering)) + "': solver '" +
                         std::string(solver_name(options.solver)) +
                         "' orders the matrix itself; an ordering applies to the envelope solver and cg");
    check_points(sources, "source");
    check_points(destinations, "destination");
    // The same limit NeighborIndex applies, checked here because small fits build it only later.
    Vec3 lo = sources[0], hi = sources[0];
    for (const auto& p : sources) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    NeighborIndex::check_extent(lo, hi, options.radius, "sources");
  }

  /// The polynomial's coordinates u = (x - center) / scale, and whether the sources determine it;
  /// checked before any heavy work.
  static void polynomial_frame(Structure& st) {
    const auto& sources = st.sources;
    const std::size_t n = sources.size();
    st.terms = polynomial_terms(st.options.polynomial);
    st.center = Vec3::Zero();
    for (const auto& s : sources) st.center += s;
    st.center /= double(n);
    double spread = 0.0;
    for (const auto& s : sources) spread = std::max(spread, (s - st.center).cwiseAbs().maxCoeff());
    st.scale = spread > 0.0 ? spread : 1.0;
    if (st.options.polynomial != Polynomial::Linear) return;
    if (n < 4) {
      std::ostringstream os;
      os << "polynomial 'linear' needs at least 4 control points that are not coplanar, got " << n
         << "; use polynomial 'constant' or 'none'";
      throw DegeneratePolynomial(os.str());
    }
    Eigen::MatrixXd u(n, 3);
    for (std::size_t i = 0; i < n; ++i) u.row(Eigen::Index(i)) = (sources[i] - st.center) / st.scale;
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::MatrixXd>(u).singularValues();
    const double tol = 1e-9 * std::max(sv(0), 1e-300);
    st.poly_condition = sv(2) > 0 ? sv(0) / sv(2) : std::numeric_limits<double>::infinity();
    if (sv(2) <= tol) {
      std::ostringstream os;
      os << "polynomial 'linear' needs control sources that span 3-D space, but the " << n << " sources are "
         << (sv(1) <= tol ? "collinear" : "coplanar") << " (singular values " << sv(0) << ", " << sv(1) << ", " << sv(2)
         << "); use polynomial 'constant' or 'none'";
      throw DegeneratePolynomial(os.str());
    }
  }

  /// Every pair of sources closer than R: by testing every pair for a few hundred sources (the grid
  /// is then left to the first evaluation), from the evaluation grid's cell lists above that, from
  /// NeighborIndex where the grid is unusable. The memory estimate is checked first. Then A's entries,
  /// computed once from the squared distances.
  static void neighbour_graph_and_matrix(Structure& st) {
    const auto& sources = st.sources;
    const FitOptions& options = st.options;
    const std::size_t n = sources.size();
    FitStats& stats = st.stats;
    auto t0 = Clock::now();
    if (n > kBruteForceGraph) {
      const FitMemoryEstimate m = estimate_fit_memory(sources, options.radius);
      st.fit_bytes = m.bytes;  // the evaluation grid gets what is left of the limit
      if (m.bytes > options.memory_limit_bytes) {
        std::ostringstream os;
        os.precision(3);
        os << "radius " << options.radius << " gives each source about " << m.mean_neighbors << " neighbours ("
           << 100.0 * m.mean_neighbors / double(n - 1) << "% of the " << n << " sources): the fit would need about "
           << gib(m.bytes) << " for its neighbour graph and factor, above the limit of "
           << gib(options.memory_limit_bytes)
           << " (FitOptions::memory_limit_bytes, `--memory-limit`). Use a smaller radius: the compact support "
              "is what keeps the system sparse";
        throw ResourceLimit(os.str());
      }
    }
    const bool brute = n <= kBruteForceGraph;
    if (!brute && !st.grid().usable) st.index();
    stats.seconds_index = seconds_since(t0);

    t0 = Clock::now();
    // The graph's rows (a 4-byte index and an 8-byte squared distance an entry), counted before they
    // are allocated: within the limit (the sample above can miss a dense cluster).
    const double graph_entries = options.memory_limit_bytes / 12.0;
    AdjacencyGraph g;
    if (brute)
      g = AdjacencyGraph::brute_force(sources, options.radius);
    else if (st.grid().usable)
      st.grid().neighbor_graph(sources, g.offsets, g.neighbors, g.dist2, graph_entries);
    else
      g = AdjacencyGraph::from_index(st.index(), sources, graph_entries);
    stats.neighbor_pairs = g.neighbors.size() / 2;
    stats.mean_neighbors = double(g.neighbors.size()) / double(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto nb = g.neighbors_of(i);
      const auto d2 = g.dist2_of(i);
      for (std::size_t k = 0; k < nb.size(); ++k)
        if (d2[k] == 0.0 && !shifted(st, i, nb[k])) {
          const std::size_t a = std::min<std::size_t>(i, nb[k]), b = std::max<std::size_t>(i, nb[k]);
          std::ostringstream os;
          os << "control sources " << a << " and " << b << " are at the same position (" << sources[a].x() << ", "
             << sources[a].y() << ", " << sources[a].z() << ")";
          throw DuplicateSource(a, b, os.str());
        }
    }
    stats.seconds_graph = seconds_since(t0);
    t0 = Clock::now();
    st.a = KernelMatrix(std::move(g), options.kernel, options.radius);
    st.a.add_to_diagonal(st.diagonal_shift);
    stats.seconds_assembly = seconds_since(t0);
  }

  /// The solver, and the one ordering it needs. Auto weighs the envelope's work in reverse
  /// Cuthill-McKee order against CG's; the envelope solver then compares the four orderings (when
  /// asked for Auto), CG keeps RCM for the locality of its products, and CHOLMOD and Eigen order
  /// the matrix themselves. No ordering is computed only to be thrown away.
  static Solver ordering_and_solver(Structure& st) {
    const FitOptions& options = st.options;
    const AdjacencyGraph& g = st.a.pattern();
    const std::size_t n = st.sources.size();
    FitStats& stats = st.stats;
    const auto t0 = Clock::now();
    Solver solver = options.solver;
    if (solver == Solver::Cholmod && !cholmod_available())
      throw InvalidInput("solver 'cholmod': " + detail::cholmod_load_error() + "; use 'envelope' or 'eigen'");
    st.cg_in_place = st.schwarz_sorted;
    st.schwarz_bytes = 0;
    if (st.cg_schwarz && (solver == Solver::Auto || solver == Solver::Cg) && st.dims >= 2 &&
        n >= detail::kSchwarzOnlyPoints &&
        2.0 * double(stats.neighbor_pairs) >= detail::kSchwarzOnlyNeighbors * double(n))
      st.schwarz_bytes = st.cg_total_bytes();  // what the Schwarz path would hold, A in place where sorted
    if (st.schwarz_bytes > 0 && st.schwarz_bytes <= options.memory_limit_bytes) {
      // csrbf::Interpolator's scattered points in 2-D or 3-D, many and well connected: the envelope
      // cannot win (RCM's envelope work is above kEnvelopeWorkLimit there: 1.5e8 at 2e4 planar points
      // with 6 neighbours, 2.2e9 with 40; test_schwarz.cpp checks it), so RCM and the envelope's
      // count are not computed (10% of a fit of 1e5 points). CG's rows are in the Schwarz patches'
      // spatial order; where Auto's probe finds CG too slow, the direct solver takes over (never the
      // envelope: its work is counted as infinite). Where CG would pass the memory limit, Auto weighs
      // the envelope as before (points on a curve: its envelope is small).
      // Sources sorted so already: CG reads A in place, in its own order.
      st.order = st.schwarz_sorted ? identity_order(n) : detail::schwarz_order(st.sources, options.radius);
      stats.ordering = Ordering::Identity;
      stats.envelope_work = std::numeric_limits<double>::infinity();
      stats.dense_bytes = 4 * n * n;
      stats.solver = Solver::Cg;
      stats.seconds_ordering = seconds_since(t0);
      return Solver::Cg;
    }
    st.cg_in_place = false;  // any other path copies A's rows into CG's order (RCM)
    std::vector<std::size_t> first;
    if (solver == Solver::Auto || solver == Solver::Cg ||
        (solver == Solver::Envelope && options.ordering != Ordering::Auto)) {
      const Ordering one = options.ordering == Ordering::Auto ? Ordering::ReverseCuthillMcKee : options.ordering;
      st.order = compute_ordering(g, one);
      stats.ordering = one;
      profile_of(stats, one) = profile(g, st.order);
      first = envelope_first_columns(g, st.order);
      stats.envelope_work = envelope_work(first);
      solver = resolve_solver(solver, stats.envelope_work, n, stats.neighbor_pairs);
    }
    if (solver == Solver::Envelope && options.ordering == Ordering::Auto) {
      // The paper's choice: the smallest envelope of the four orderings, RCM's reused.
      OrderingChoice c = choose_ordering(g, Ordering::Auto, std::move(st.order));
      st.order = std::move(c.order);
      stats.ordering = c.chosen;
      stats.identity = c.identity;
      stats.breadth_first = c.breadth_first;
      stats.reverse_breadth_first = c.reverse_breadth_first;
      stats.reverse_cuthill_mckee = c.reverse_cuthill_mckee;
      stats.orderings_compared = true;
      first = envelope_first_columns(g, st.order);
      stats.envelope_work = envelope_work(first);
    }
    if (!st.order.empty()) {
      const Profile chosen = profile_of(stats, stats.ordering);
      stats.bandwidth = chosen.bandwidth;
      stats.envelope_entries = chosen.envelope;
      stats.envelope_bytes = 4 * (n + chosen.envelope) + 4 * n;
    }
    stats.dense_bytes = 4 * n * n;
    st.first_columns = std::move(first);
    stats.solver = solver;
    stats.seconds_ordering = seconds_since(t0);
    return solver;
  }

  /// The envelope Cholesky of A in its ordering; CG's matrix in RCM order (nothing to factorise);
  /// or CHOLMOD's or Eigen's factorisation.
  static void factorise(Structure& st, Solver solver) {
    const FitOptions& options = st.options;
    const std::size_t n = st.sources.size();
    FitStats& stats = st.stats;
    if (solver == Solver::Envelope) {
      // A lives beside its envelope (the residual check reads it).
      detail::check_envelope_size(st.first_columns, options.memory_limit_bytes, ordering_name(stats.ordering),
                                  detail::kernel_matrix_bytes(st.a));
      auto t0 = Clock::now();
      EnvelopeMatrix env = envelope_matrix(st.a, st.order, std::move(st.first_columns));
      stats.envelope_bytes = env.paper_bytes();
      stats.dense_bytes = env.dense_bytes();
      stats.seconds_assembly += seconds_since(t0);
      t0 = Clock::now();
      detail::envelope_cholesky(env, st.order);
      st.factor = std::move(env);
      stats.factor_nonzeros = stats.envelope_entries + n;
      stats.seconds_factorization = seconds_since(t0);
      return;
    }
    st.first_columns = {};
    std::vector<std::uint32_t> rows = std::move(st.order);
    st.order = identity_order(n);  // the sparse solvers take and give the input order
    const auto t0 = Clock::now();
    if (solver == Solver::Cg) {
      // Chosen by Auto, CG checks every kCgProbeSteps steps how many it will need, and gives way
      // where a direct solver is predicted to be faster (fit_options.hpp). Asked for by name, it runs
      // until it converges or stagnates (kCgMaxIterations): its early predictions can be far too
      // high as well as too low (900 points in a cube: more than 3000 predicted after 10 steps, of
      // fewer than 3000).
      detail::CgProbe probe;
      if (options.solver == Solver::Auto) {
        probe.steps = kCgProbeSteps;
        probe.worth_it = [&st, n](double steps, double done) {
          // Costs in CG multiply-adds; the steps taken are spent either way.
          const double left = (steps - done) * st.cg_step_work();
          const double envelope = kEnvelopeCostRatio * st.stats.envelope_work;
          if (st.stats.envelope_work <= kEnvelopeWorkLimit && envelope < left) return false;
          // The general direct solver is weighed (its ordering and its factor's column counts, no
          // numbers) once CG looks long enough for it to win: its flops are then known.
          if (steps - done > kCgAnalyseSteps * std::sqrt(double(n))) {
            const double direct = st.direct_cost();
            // CG's prediction is least sure after its first steps: the direct solver must win by a
            // margin that shrinks as CG goes on (2x after 10 steps, 1.25x after 40).
            const double margin = 1 + kCgProbeSteps / done;
            if (direct * margin < left) return false;
            // Where the memory limit refuses the direct factor, the envelope whatever its work, where it
            // fits beside A and CG (face.obj, 6158 controls at 5263 neighbours each: CG ran 1000 steps
            // and 78 s before it gave way; the envelope takes 22 s).
            const double envelope_bytes =
                detail::envelope_factor_bytes(double(st.stats.envelope_entries), n) + st.cg_total_bytes();
            if (!std::isfinite(direct) && envelope * margin < left && envelope_bytes <= st.options.memory_limit_bytes)
              return false;
          }
          return true;
        };
      }
      // CG holds A's rows in its order beside A itself, and its vectors.
      const double bytes = st.cg_total_bytes();
      if (bytes > options.memory_limit_bytes) {
        std::ostringstream os;
        os.precision(3);
        os << "conjugate gradients would hold " << gib(bytes) << " for A's " << st.a.values().size() + n
           << (st.cg_in_place ? " entries (read in place)" : " entries, their copy in CG's order")
           << " and their vectors, above the limit of " << gib(options.memory_limit_bytes)
           << " (FitOptions::memory_limit_bytes, `--memory-limit`)";
        // The interpolator's sorted points: the Schwarz path, refused for its bytes alone, needs less.
        if (!st.cg_in_place && st.schwarz_bytes > 0 && st.schwarz_bytes < bytes)
          os << "; with the Schwarz patches, which read A in place, " << gib(st.schwarz_bytes);
        os << ". Use a smaller radius";
        throw ResourceLimit(os.str());
      }
      st.cg_rows = rows;
      detail::CgPreconditioner preconditioner;
      if (st.cg_schwarz) preconditioner.points = st.sources;  // borrowed: st outlives st.sparse
      st.sparse = detail::conjugate_gradients(st.a, std::move(rows), kCgTolerance, kCgMaxIterations, std::move(probe),
                                              std::move(preconditioner));
      stats.seconds_assembly += seconds_since(t0);
    } else {
      st.sparse = detail::factor_sparse(st.a, st.sources, solver, options.memory_limit_bytes);
      stats.seconds_factorization = seconds_since(t0);
    }
    stats.factor_nonzeros = st.sparse->nonzeros();
  }

  /// George & Liu's block elimination, the part that depends on the sources only: Y = A^-1 P and the
  /// Cholesky factor of P^T Y.
  static void polynomial_block(Structure& st) {
    if (st.terms == 0) return;
    const auto t0 = Clock::now();
    const std::size_t n = st.sources.size();
    st.p.resize(Eigen::Index(n), st.terms);
    for (std::size_t k = 0; k < n; ++k) {
      st.p(Eigen::Index(k), 0) = 1.0;
      if (st.terms == 4) {
        const Vec3 u = (st.sources[st.order[k]] - st.center) / st.scale;
        st.p.block<1, 3>(Eigen::Index(k), 1) = u.transpose();
      }
    }
    st.y = st.p;
    st.solve_in_place(st.y);
    if (st.fell_back) st.stats.seconds_factorization = st.fallback_seconds;
    st.schur.compute(st.p.transpose() * st.y);
    if (st.schur.info() != Eigen::Success)
      throw DegeneratePolynomial(std::string("polynomial '") + std::string(polynomial_name(st.options.polynomial)) +
                                 "': the sources do not determine it; use polynomial 'none'");
    st.stats.seconds_solve += seconds_since(t0) - (st.fell_back ? st.fallback_seconds : 0.0);
  }

  /// Near-coplanar (or near-collinear) sources pass the rank test but leave the linear
  /// polynomial's gradient across their plane to the noise of the data: displacements of 0.1 then
  /// gave +-103 a radius away. The linear part's largest change over the sources' cube (u in
  /// [-1, 1]^3) against the largest control displacement measures it: an affine map the controls
  /// admit changes by about 2 times that, however flat the sources, so a flat part turned or moved
  /// rigidly still fits. Refused beyond kMaxAmplification, or beyond kFlatAmplification where the
  /// sources' condition (largest over smallest singular value, centred and scaled) passes
  /// kMaxCondition. The message gives the condition and the remedy.
  static void check_amplification(const Structure& st, const State& s, std::span<const Vec3> destinations) {
    constexpr double kMaxCondition = 1000.0, kFlatAmplification = 10.0, kMaxAmplification = 100.0;
    double largest = 0.0;
    for (std::size_t i = 0; i < st.sources.size(); ++i)
      largest = std::max(largest, (destinations[i] - st.sources[i]).norm());
    if (!(largest > 0.0)) return;
    double change = 0.0;  // max over the cube's corners of |B^T u|, B the gradient rows 1..3
    for (int corner = 0; corner < 8; ++corner) {
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      for (int a = 0; a < 3; ++a) v += ((corner >> a) & 1 ? 1.0 : -1.0) * s.beta.row(1 + a).transpose();
      change = std::max(change, v.norm());
    }
    const double ratio = change / largest;
    if (ratio > kMaxAmplification || (st.poly_condition > kMaxCondition && ratio > kFlatAmplification) ||
        !std::isfinite(ratio)) {
      std::ostringstream os;
      os << "polynomial 'linear': the sources are nearly "
         << "coplanar or collinear (condition of the polynomial block " << st.poly_condition
         << "), and their linear part would move points up to " << ratio
         << " times the largest control displacement within the sources' extent (" << change << " against " << largest
         << "); use polynomial 'constant' or 'none', or add controls off that plane or line";
      throw DegeneratePolynomial(os.str());
    }
  }

  /// A z = g, beta = (P^T Y)^-1 P^T z, alpha = z - Y beta. `previous` (a map with the same
  /// structure) gives CG its starting point: its z.
  static void solve(const Structure& st, State& s, std::span<const Vec3> destinations, const State* previous) {
    const std::size_t n = st.sources.size();
    FitStats& stats = s.stats;
    const auto t0 = Clock::now();
    RowMatrix z(Eigen::Index(n), 3);
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t i = st.order[k];
      z.row(Eigen::Index(k)) = (destinations[i] - st.sources[i]).transpose();
    }
    RowMatrix guess;
    const bool warm = previous && previous->alpha.rows() == Eigen::Index(n) && st.warm_starts();
    if (warm) {
      guess.resize(Eigen::Index(n), 3);
      for (std::size_t k = 0; k < n; ++k) guess.row(Eigen::Index(k)) = previous->alpha.row(Eigen::Index(st.order[k]));
      if (st.terms > 0) guess += st.y * previous->beta.topRows(st.terms);
    }
    const bool had_fallen_back = st.fell_back;
    st.solve_in_place(z, warm ? &guess : nullptr);
    if (st.terms > 0) {
      const Eigen::MatrixXd b = st.schur.solve(st.p.transpose() * z);  // terms x 3
      z -= st.y * b;
      s.beta.topRows(st.terms) = b;
    }
    s.alpha.resize(Eigen::Index(n), 3);
    for (std::size_t k = 0; k < n; ++k) s.alpha.row(st.order[k]) = z.row(Eigen::Index(k));
    if (st.terms == 4) check_amplification(st, s, destinations);
    s.poly.center = st.center;
    s.poly.inv_scale = 1.0 / st.scale;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 3; ++c) s.poly.b[r][c] = s.beta(r, c);
    stats.seconds_solve += seconds_since(t0);
    stats.warm_start = warm && !st.fell_back;
    if (previous && previous->alpha.rows() == Eigen::Index(n)) {
      // with_destinations: only the solve (and the residual check) ran for this map.
      stats.seconds_index = stats.seconds_graph = stats.seconds_ordering = stats.seconds_assembly = 0;
      stats.seconds_factorization = 0;
      stats.seconds_solve = seconds_since(t0);
    }
    if (st.sparse) {
      stats.iterations = st.sparse->iterations();
      stats.solver_residual = st.sparse->residual();
      if (st.fell_back) {
        // The solver that took over factorised inside this solve (else in the polynomial block's,
        // which counted it, or in an earlier map's).
        if (!had_fallen_back) {
          stats.seconds_factorization = st.fallback_seconds;
          stats.seconds_solve -= st.fallback_seconds;
        }
        stats.fell_back = st.fallback_solver != Solver::Cg;
        stats.solver = st.fallback_solver;
        if (st.fallback) {  // else CG went on, the direct factors refused by the memory limit
          stats.factor_nonzeros = st.fallback->nonzeros();
          if (st.fallback->iterative()) {
            stats.iterations = st.fallback->iterations();
            stats.solver_residual = st.fallback->residual();
          }
        }
      }
    }
  }

  /// The residual at the controls through A (and, for large coefficients, through the evaluation
  /// itself); IllConditioned beyond kResidualLimit.
  static void check_residual(const std::shared_ptr<State>& s, std::span<const Vec3> destinations) {
    const Structure& st = *s->st;
    const std::size_t n = st.sources.size();
    FitStats& stats = s->stats;
    const auto t0 = Clock::now();
    const RowMatrix a_alpha = st.a * RowMatrix(s->alpha);
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
        eval_res =
            std::max(eval_res, (Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]) - (destinations[i] - st.sources[i])).norm());
      stats.residual_max = std::max(stats.residual_max, eval_res);
      stats.residual_relative = stats.residual_max / gmax;
    }
    if (stats.residual_relative <= kResidualLimit) return;
    // Name the closest pair of sources: nearly coincident sources are what makes A nearly singular.
    std::ostringstream os;
    os << "the controls cannot be interpolated to a relative residual of " << kResidualLimit << " (got "
       << stats.residual_relative << "): the matrix is too ill-conditioned (condition estimate " << st.condition()
       << ")";
    if (!st.a.values().empty()) {
      const auto [a, b] = st.a.closest_pair();
      os << "; the closest sources, " << a << " and " << b << ", are "
         << (st.sources[a] - st.sources[b]).norm() / st.options.radius
         << " R apart. Merge or separate them, or use a smaller radius (fewer neighbours a source)";
    }
    throw IllConditioned(os.str());
  }

 private:
  /// Whether sources i and j may share a position: both have a smoothing shift > 0 (A + diag stays
  /// positive definite).
  static bool shifted(const Structure& st, std::size_t i, std::size_t j) {
    const auto& s = st.diagonal_shift;
    if (s.empty()) return false;
    return s.size() == 1 ? s[0] > 0 : s[i] > 0 && s[j] > 0;
  }
  static std::vector<std::uint32_t> compute_ordering(const AdjacencyGraph& g, Ordering o) {
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
};

SpaceMap SpaceMap::fit(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options) {
  FitPhases::validate(sources, destinations, options);
  auto st = std::make_shared<Structure>();
  st->options = options;
  st->sources.assign(sources.begin(), sources.end());
  st->stats.controls = sources.size();
  FitPhases::polynomial_frame(*st);
  FitPhases::neighbour_graph_and_matrix(*st);
  const Solver solver = FitPhases::ordering_and_solver(*st);
  FitPhases::factorise(*st, solver);
  FitPhases::polynomial_block(*st);
  auto structure_only = std::make_shared<State>();
  structure_only->st = std::move(st);
  return SpaceMap(std::move(structure_only)).solve_destinations(destinations);
}

std::shared_ptr<SpaceMap::Structure> detail::fit_structure(std::span<const Vec3> sources, const FitOptions& options,
                                                           std::span<const double> diagonal_shift, int dims,
                                                           bool schwarz_sorted) {
  auto st = std::make_shared<SpaceMap::Structure>();
  st->options = options;
  st->options.polynomial = Polynomial::None;
  st->sources.assign(sources.begin(), sources.end());
  st->diagonal_shift.assign(diagonal_shift.begin(), diagonal_shift.end());
  st->dims = dims;
  // Cells of side R (not R/2): the interpolator's levels each build a grid and its lists, which at
  // cells of R/2 cost more than the finer cells save (Franke's function, 1e5 points, 7 levels: fit
  // and evaluation of 2e5 points 1.4 s against 1.7 s, of 1e6 points 1.4 against 1.9 s).
  st->max_subdivision = 1;
  st->eval_list_bytes = std::size_t(std::min(options.memory_limit_bytes, 1e18));
  st->cg_schwarz = true;
  st->schwarz_sorted = schwarz_sorted;
  st->stats.controls = sources.size();
  FitPhases::polynomial_frame(*st);
  FitPhases::neighbour_graph_and_matrix(*st);
  const Solver solver = FitPhases::ordering_and_solver(*st);
  FitPhases::factorise(*st, solver);
  return st;
}

SpaceMap SpaceMap::from_solution(std::span<const Vec3> sources, const Eigen::Matrix<double, Eigen::Dynamic, 3>& alpha,
                                 const Eigen::Matrix<double, 4, 3>& beta, const Vec3& center, double scale,
                                 const FitOptions& options, std::size_t points) {
  if (alpha.rows() != Eigen::Index(sources.size())) {
    std::ostringstream os;
    os << "from_solution: " << sources.size() << " sources but " << alpha.rows() << " coefficient rows";
    throw InvalidInput(os.str());
  }
  if (!(options.radius >= 1e-150 && options.radius <= 1e150)) {
    std::ostringstream os;
    os << "radius must be a positive finite number in [1e-150, 1e150], got " << options.radius;
    throw InvalidInput(os.str());
  }
  if (!(scale > 0) || !std::isfinite(scale) || !center.allFinite() || !alpha.allFinite() || !beta.allFinite())
    throw InvalidInput("from_solution: the center, scale, coefficients and polynomial must be finite (scale > 0)");
  check_points(sources, "source");
  auto st = std::make_shared<Structure>();
  st->options = options;
  st->sources.assign(sources.begin(), sources.end());
  st->stats.controls = sources.size();
  st->terms = polynomial_terms(options.polynomial);
  st->center = center;
  st->scale = scale;
  st->solved_elsewhere = true;
  if (points > 0 && points / kFineGridPointsPerSource < sources.size()) st->max_subdivision = 1;
  auto s = std::make_shared<State>();
  s->st = std::move(st);
  s->alpha = alpha;
  s->beta = beta;
  if (options.polynomial == Polynomial::None) s->beta.setZero();
  if (options.polynomial == Polynomial::Constant) s->beta.bottomRows<3>().setZero();
  s->poly.center = center;
  s->poly.inv_scale = 1.0 / scale;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 3; ++c) s->poly.b[r][c] = s->beta(r, c);
  s->stats = s->st->stats;
  return SpaceMap(std::move(s));
}

SpaceMap SpaceMap::with_destinations(std::span<const Vec3> destinations) const {
  if (s_->st->solved_elsewhere)
    throw InvalidInput("with_destinations: this map was made from a solution (from_solution) and has no matrix");
  if (destinations.size() != size()) {
    std::ostringstream os;
    os << "control points: " << size() << " sources but " << destinations.size() << " destinations";
    throw InvalidInput(os.str());
  }
  check_points(destinations, "destination");
  return solve_destinations(destinations);
}

SpaceMap SpaceMap::solve_destinations(std::span<const Vec3> destinations) const {
  auto s = std::make_shared<State>();
  s->st = s_->st;
  s->destinations.assign(destinations.begin(), destinations.end());
  s->stats = s_->st->stats;
  FitPhases::solve(*s->st, *s, destinations, s_.get());
  FitPhases::check_residual(s, destinations);
  return SpaceMap(std::move(s));
}

double SpaceMap::condition_estimate() const {
  if (s_->st->solved_elsewhere)
    throw InvalidInput("condition_estimate: this map was made from a solution (from_solution) and has no matrix");
  return s_->st->condition();
}
const KernelMatrix& SpaceMap::matrix() const noexcept { return s_->st->a; }

void deform(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options,
            double* points, std::size_t n, double phase) {
  SpaceMap::fit(sources, destinations, options).apply(points, points, n, phase);
}

}  // namespace csrbf
