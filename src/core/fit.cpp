// SpaceMap::fit: three values in 3-D over the kernel system (kernel_system.hpp), with the map's own
// checks around its phases:
//   validate -> the polynomial's sources -> analyse -> factorise -> solve -> amplification
//   -> residual check (the system's, and through the evaluation where the coefficients are large).
// with_destinations() reruns only the last three.
#include "csrbf/units.hpp"
#include "fit_state.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace csrbf {

using detail::check_points;

namespace {

using Structure = SpaceMap::Structure;
using State = SpaceMap::State;

int polynomial_terms(Polynomial p) { return p == Polynomial::None ? 0 : p == Polynomial::Constant ? 1 : 4; }

/// Sizes, finite coordinates, the radius, the memory limit, the grid's extent.
void validate(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options) {
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

/// Whether the sources determine the linear polynomial, from the system's singular values of the
/// centred and scaled sources; checked before any heavy work. Sets st.poly_condition.
void check_polynomial(Structure& st, const KernelSystem& system) {
  if (st.options.polynomial != Polynomial::Linear) return;
  const std::size_t n = system.size();
  if (n < 4) {
    std::ostringstream os;
    os << "polynomial 'linear' needs at least 4 control points that are not coplanar, got " << n
       << "; use polynomial 'constant' or 'none'";
    throw DegeneratePolynomial(os.str());
  }
  const Eigen::VectorXd& sv = system.singular_values();
  const double tol = 1e-9 * std::max(sv(0), 1e-300);
  st.poly_condition = sv(2) > 0 ? sv(0) / sv(2) : std::numeric_limits<double>::infinity();
  if (system.polynomial_degenerate()) {
    std::ostringstream os;
    os << "polynomial 'linear' needs control sources that span 3-D space, but the " << n << " sources are "
       << (sv(1) <= tol ? "collinear" : "coplanar") << " (singular values " << sv(0) << ", " << sv(1) << ", " << sv(2)
       << "); use polynomial 'constant' or 'none'";
    throw DegeneratePolynomial(os.str());
  }
}

/// Near-coplanar (or near-collinear) sources pass the rank test but leave the linear
/// polynomial's gradient across their plane to the noise of the data: displacements of 0.1 then
/// gave +-103 a radius away. The linear part's largest change over the sources' cube (u in
/// [-1, 1]^3) against the largest control displacement measures it: an affine map the controls
/// admit changes by about 2 times that, however flat the sources, so a flat part turned or moved
/// rigidly still fits. Refused beyond kMaxAmplification, or beyond kFlatAmplification where the
/// sources' condition (largest over smallest singular value, centred and scaled) passes
/// kMaxCondition. The message gives the condition and the remedy.
void check_amplification(const Structure& st, const State& s, std::span<const Vec3> destinations) {
  constexpr double kMaxCondition = 1000.0, kFlatAmplification = 10.0, kMaxAmplification = 100.0;
  double largest = 0.0;
  for (std::size_t i = 0; i < st.sources().size(); ++i)
    largest = std::max(largest, (destinations[i] - st.sources()[i]).norm());
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

/// The displacements g = destination - source, N x 3 in the sources' order.
RowMatrix displacements_of(const Structure& st, std::span<const Vec3> destinations) {
  RowMatrix g(Eigen::Index(destinations.size()), 3);
  double* row = g.data();  // row-major, 3 a row
  for (std::size_t i = 0; i < destinations.size(); ++i, row += 3) {
    const Vec3 d = destinations[i] - st.sources()[i];
    row[0] = d.x(), row[1] = d.y(), row[2] = d.z();
  }
  return g;
}

/// The system's solve of g (alpha, beta), the linear part's amplification checked. `previous` (a map
/// with the same structure) gives CG its starting point.
void solve(const Structure& st, State& s, std::span<const Vec3> destinations, const State* previous) {
  KernelSystem& system = *st.system;
  const std::size_t n = st.sources().size();
  FitStats& stats = s.stats;
  const auto t0 = Clock::now();
  RowMatrix z = displacements_of(st, destinations);
  RowMatrix guess;
  const bool warm = previous && previous->alpha.rows() == Eigen::Index(n) && system.warm_starts();
  if (warm) guess = system.warm_start(previous->alpha, previous->beta);
  const bool had_handed_over = system.handed_over();
  Eigen::MatrixXd beta;
  KernelSystem::require(system.solve(z, beta, warm ? &guess : nullptr));
  if (st.terms > 0) s.beta.topRows(st.terms) = beta;
  s.alpha = z;
  if (st.terms == 4) check_amplification(st, s, destinations);
  s.poly.center = st.center;
  s.poly.inv_scale = 1.0 / st.scale;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 3; ++c) s.poly.b[r][c] = s.beta(r, c);
  stats.seconds_solve += seconds_since(t0);
  stats.warm_start = warm && !system.handed_over();
  if (previous && previous->alpha.rows() == Eigen::Index(n)) {
    // with_destinations: only the solve (and the residual check) ran for this map.
    stats.seconds_index = stats.seconds_graph = stats.seconds_ordering = stats.seconds_assembly = 0;
    stats.seconds_factorization = 0;
    stats.seconds_solve = seconds_since(t0);
  }
  system.report(stats, had_handed_over);
}

/// The system's residual check at the controls (and, for large coefficients, through the evaluation
/// itself); IllConditioned beyond kResidualLimit.
void check_residual(const std::shared_ptr<State>& s, std::span<const Vec3> destinations) {
  const Structure& st = *s->st;
  KernelSystem& system = *st.system;
  const std::size_t n = st.sources().size();
  FitStats& stats = s->stats;
  const auto t0 = Clock::now();
  const KernelSystem::Residual r = system.residual(RowMatrix(s->alpha), Eigen::MatrixXd(s->beta.topRows(st.terms)),
                                                   displacements_of(st, destinations));
  const double gmax = r.largest;
  stats.residual_max = r.max;
  stats.residual_relative = r.relative;
  stats.seconds_residual = seconds_since(t0);
  if (stats.residual_relative <= kResidualLimit && gmax > 0 && s->alpha.cwiseAbs().maxCoeff() > 1e6 * gmax) {
    // Coefficients a million times the displacements: the system is ill-conditioned, and rounding in
    // the evaluation (distances recomputed from coordinates) is amplified as much. Measure the
    // residual through the evaluation itself.
    const SpaceMap m(s);
    std::vector<double> in(3 * n), d(3 * n);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) in[3 * i + std::size_t(c)] = st.sources()[i][c];
    m.displacements(in.data(), d.data(), n);
    double eval_res = 0;
    for (std::size_t i = 0; i < n; ++i)
      eval_res =
          std::max(eval_res, (Vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]) - (destinations[i] - st.sources()[i])).norm());
    stats.residual_max = std::max(stats.residual_max, eval_res);
    stats.residual_relative = stats.residual_max / gmax;
  }
  if (stats.residual_relative <= kResidualLimit) return;
  // Name the closest pair of sources: nearly coincident sources are what makes A nearly singular.
  std::ostringstream os;
  os << "the controls cannot be interpolated to a relative residual of " << kResidualLimit << " (got "
     << stats.residual_relative << "): the matrix is too ill-conditioned (condition estimate " << system.condition()
     << ")";
  if (!system.matrix().values().empty()) {
    const auto [a, b] = system.matrix().closest_pair();
    os << "; the closest sources, " << a << " and " << b << ", are "
       << (st.sources()[a] - st.sources()[b]).norm() / st.options.radius
       << " R apart. Merge or separate them, or use a smaller radius (fewer neighbours a source)";
  }
  throw IllConditioned(os.str());
}

}  // namespace

SpaceMap SpaceMap::fit(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options) {
  validate(sources, destinations, options);
  auto st = std::make_shared<Structure>();
  st->options = options;
  st->cloud = std::make_shared<detail::PointCloud>(sources, options.radius, options.memory_limit_bytes);
  KernelSystemOptions so;
  so.radius = options.radius;
  so.kernel = options.kernel;
  so.degree = options.polynomial == Polynomial::None ? -1 : options.polynomial == Polynomial::Constant ? 0 : 1;
  so.solver = options.solver;
  so.ordering = options.ordering;
  so.memory_limit_bytes = options.memory_limit_bytes;
  so.cg_work_columns = 3 + polynomial_terms(options.polynomial);  // the displacements and the polynomial block
  st->system = std::make_shared<KernelSystem>(st->cloud, so);
  KernelSystem& system = *st->system;
  st->terms = system.terms();
  st->center = system.center();
  st->scale = system.scale();
  check_polynomial(*st, system);
  system.analyse();
  system.factorise();
  if (system.info() != SystemInfo::Success)
    throw DegeneratePolynomial(std::string("polynomial '") + std::string(polynomial_name(options.polynomial)) +
                               "': the sources do not determine it; use polynomial 'none'");
  st->stats = system.stats();
  auto structure_only = std::make_shared<State>();
  structure_only->st = std::move(st);
  return SpaceMap(std::move(structure_only)).solve_destinations(destinations);
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
  st->cloud = std::make_shared<detail::PointCloud>(sources, options.radius, options.memory_limit_bytes);
  st->stats.controls = sources.size();
  st->terms = polynomial_terms(options.polynomial);
  st->center = center;
  st->scale = scale;
  if (points > 0 && points / kFineGridPointsPerSource < sources.size()) st->cloud->max_subdivision = 1;
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
  if (s_->st->solved_elsewhere())
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
  solve(*s->st, *s, destinations, s_.get());
  check_residual(s, destinations);
  return SpaceMap(std::move(s));
}

double SpaceMap::condition_estimate() const {
  if (s_->st->solved_elsewhere())
    throw InvalidInput("condition_estimate: this map was made from a solution (from_solution) and has no matrix");
  return s_->st->system->condition();
}

const KernelMatrix& SpaceMap::matrix() const noexcept {
  static const KernelMatrix none;  // a map made from a solution has no matrix
  return s_->st->system ? s_->st->system->matrix() : none;
}

void deform(std::span<const Vec3> sources, std::span<const Vec3> destinations, const FitOptions& options,
            double* points, std::size_t n, double phase) {
  SpaceMap::fit(sources, destinations, options).apply(points, points, n, phase);
}

}  // namespace csrbf
