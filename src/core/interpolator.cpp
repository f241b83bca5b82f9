// csrbf::Interpolator (interpolator.hpp): the levels, each V values in D dimensions over the kernel
// system (kernel_system.hpp: its phases, polynomial block and residual check); evaluated through
// SpaceMap's loops, three values a map over the level's points, padded to 3-D with zeros (the
// distances are the same).
#include "csrbf/interpolator.hpp"
#include "csrbf/units.hpp"

#include "fit_state.hpp"
#include "point_cloud.hpp"
#include "radius.hpp"
#include "schwarz.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <array>
#include <unordered_map>
#include <unordered_set>

namespace csrbf {

namespace {

/// Points evaluated a batch (padded to 3-D in a scratch buffer).
constexpr std::size_t kBatch = std::size_t(1) << 17;

int terms_of(int degree, int dim) { return degree < 0 ? 0 : degree == 0 ? 1 : 1 + dim; }

std::string num(double v) { return format_significant(v, 6); }

/// The volume of the unit ball in D dimensions.

void validate(std::span<const double> points, int dim, std::span<const double> values, std::size_t v,
              const InterpolatorOptions& o) {
  if (dim < 1 || dim > Interpolator::kMaxDimension) {
    std::ostringstream os;
    os << "points: dimension D = " << dim
       << " is not supported: the Wendland functions are positive definite on R^D only for D <= 3 (they are "
          "built for R^3), so for D > 3 the system may be singular; D must be 1, 2 or 3";
    throw InvalidInput(os.str());
  }
  if (points.size() % std::size_t(dim) != 0)
    throw InvalidInput("points: " + std::to_string(points.size()) + " numbers are not a whole number of " +
                       std::to_string(dim) + "-D points");
  const std::size_t n = points.size() / std::size_t(dim);
  if (n == 0) throw InvalidInput("points: none given (need at least 1)");
  if (v == 0) throw InvalidInput("values: no value a point (need at least 1)");
  if (values.size() != n * v) {
    std::ostringstream os;
    os << "values: " << values.size() << " numbers for " << n << " points of " << v << " values each (expected "
       << n * v << ")";
    throw InvalidInput(os.str());
  }
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!std::isfinite(points[i]) || std::abs(points[i]) > detail::kMaxCoordinate) {
      std::ostringstream os;
      os << "points[" << i / std::size_t(dim) << ", " << i % std::size_t(dim) << "] is " << points[i]
         << (std::isfinite(points[i]) ? " (beyond 1e150)" : " (points must be finite)");
      throw InvalidInput(os.str());
    }
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]) || std::abs(values[i]) > detail::kMaxCoordinate) {
      std::ostringstream os;
      os << "values[" << i / v << ", " << i % v << "] is " << values[i]
         << (std::isfinite(values[i]) ? " (beyond 1e150: the solve's squares would overflow)"
                                      : " (values must be finite)");
      throw InvalidInput(os.str());
    }
  // The fit holds about eight P x V copies of the values (its right-hand sides, residuals and
  // coefficients), counted before any is made.
  const double value_bytes = 8.0 * 8.0 * double(values.size());
  if (value_bytes > o.memory_limit_bytes) {
    std::ostringstream os;
    os.precision(3);
    os << "values: " << n << " points of " << v << " values need about " << value_bytes / kGiB
       << " GiB for the fit's copies of them, above the memory limit of " << o.memory_limit_bytes / kGiB << " GiB";
    throw ResourceLimit(os.str());
  }
  if (!(o.radius >= 0) || !std::isfinite(o.radius) || (o.radius > 0 && (o.radius < 1e-150 || o.radius > 1e150)))
    throw InvalidInput("radius must be a positive finite number in [1e-150, 1e150] (or automatic), got " +
                       num(o.radius));
  if (!(o.neighbors >= 0) || !(o.neighbors <= 1e9))
    throw InvalidInput("neighbors must be a positive number up to 1e9 (or 0: the default), got " + num(o.neighbors));
  if (o.degree < -1 || o.degree > 1)
    throw InvalidInput("degree must be -1 (no polynomial), 0 or 1, got " + std::to_string(o.degree));
  if (!o.smoothing.empty() && o.smoothing.size() != 1 && o.smoothing.size() != n)
    throw InvalidInput("smoothing: " + std::to_string(o.smoothing.size()) + " values for " + std::to_string(n) +
                       " points (give one value, or one a point)");
  for (std::size_t i = 0; i < o.smoothing.size(); ++i)
    if (!(o.smoothing[i] >= 0) || !std::isfinite(o.smoothing[i]))
      throw InvalidInput("smoothing[" + std::to_string(i) + "] is " + num(o.smoothing[i]) +
                         " (smoothing must be finite and >= 0)");
  if (o.levels < 0 || o.levels > kMaxLevels)
    throw InvalidInput("levels must be 0 (automatic) or 1.." + std::to_string(kMaxLevels) + ", got " +
                       std::to_string(o.levels));
  if (!(o.memory_limit_bytes > 0))
    throw InvalidInput("memory_limit_bytes must be a number > 0, got " + num(o.memory_limit_bytes));
}

using Cell = std::array<std::int64_t, 3>;
struct CellHash {
  std::size_t operator()(const Cell& c) const noexcept {
    return std::size_t((std::uint64_t(c[0]) * 73856093u) ^ (std::uint64_t(c[1]) * 19349663u) ^
                       (std::uint64_t(c[2]) * 83492791u));
  }
};

/// Nested subsets by thinning: level l keeps, for each cell of side cells[l] (halving level by
/// level, one origin), the point nearest the cell's centre, beside the points coarser levels kept.
/// Returns, for each point, the first level that holds it (levels.size() - 1 for the rest).
std::vector<std::uint8_t> thin(std::span<const Vec3> pts, int dim, std::span<const double> cells) {
  const std::size_t n = pts.size();
  const std::size_t last = cells.size();  // the finest level holds every point
  std::vector<std::uint8_t> first(n, std::uint8_t(last));
  Vec3 lo = pts[0];
  for (const Vec3& p : pts) lo = lo.cwiseMin(p);
  for (std::size_t l = 0; l < cells.size(); ++l) {
    const double h = cells[l];
    std::unordered_map<Cell, std::pair<std::size_t, double>, CellHash> best;  // cell -> point, distance^2
    std::unordered_set<Cell, CellHash> taken;                                 // cells holding a coarser point
    std::unordered_set<Cell, CellHash> occupied;
    best.reserve(n / 4 + 16);
    // Cells of side h >= 1e-9 of the points' extent (the grid's own rule) fit an int64.
    const auto cell_of = [&](const Vec3& p) {
      Cell key{};
      for (int a = 0; a < dim; ++a) key[std::size_t(a)] = std::int64_t(std::floor((p[a] - lo[a]) / h));
      return key;
    };
    for (std::size_t i = 0; i < n; ++i) occupied.insert(cell_of(pts[i]));
    for (std::size_t i = 0; i < n; ++i) {
      const Cell key = cell_of(pts[i]);
      // The point a cell keeps is the one nearest its centre, except towards a side where the
      // neighbouring cell is empty (the points' boundary): there the one nearest that side, so that
      // a coarse level reaches the boundary as the points do (a level whose outermost points stop
      // half a cell short leaves its finer levels a residual they cannot smooth out: 1.9e-3 against
      // 1e-7 inside, on Franke's function).
      double d2 = 0;
      for (int a = 0; a < dim; ++a) {
        const double x = pts[i][a] - lo[a], base = double(key[std::size_t(a)]) * h;
        Cell below = key, above = key;
        --below[std::size_t(a)];
        ++above[std::size_t(a)];
        const bool open_below = !occupied.count(below), open_above = !occupied.count(above);
        const double target = open_below == open_above ? base + 0.5 * h : open_below ? base : base + h;
        d2 += (x - target) * (x - target);
      }
      if (first[i] < l) {
        taken.insert(key);
        continue;
      }
      auto [it, fresh] = best.try_emplace(key, i, d2);
      if (!fresh && d2 < it->second.second) it->second = {i, d2};
    }
    for (const auto& [key, pick] : best)
      if (!taken.count(key)) first[pick.first] = std::uint8_t(l);
  }
  return first;
}

/// A fit's levels: the finest level's radius, the thinned levels' cells and each point's first level.
struct LevelPlan {
  double finest = 0;                // R_f, the radius of the finest level (every point)
  std::vector<double> cells;        // coarsest first, without the finest level (all points)
  std::vector<std::uint8_t> first;  // for each point, the first level that holds it
  std::size_t levels() const { return cells.size() + 1; }
};

/// The levels. Single scale: R, given or automatic (K = `neighbors` within R). Multiscale: the finest
/// level, every point, has radius R_f: the given radius, or half the automatic one (about K / 2^D
/// neighbours: random points come close in pairs, and the finest level's system, the one that
/// holds them all, is the one that gets harder to solve as its radius grows: 100 CG steps on
/// Franke's 1e5 points where at K CHOLMOD took 3.2 s). The thinned levels have cells of side
/// h_l = 4 h, 8 h, ... and radii 4 R_f, 8 R_f, ... (coarser), h = R_f (ball / K)^(1/D), a cell
/// holding one point, so that a point has about K others within its level's radius. There is no
/// thinned level at 2 h: cells of about one point each keep 60% of the points, close pairs with
/// them, and cost as much as the finest (1e5 points: 1.3 s against 0.9, the RMS error 1.07e-5
/// against 1.39e-5 at K = 40, 8.7e-6 at K = 50).
LevelPlan plan_levels(std::span<const Vec3> all, int dim, const InterpolatorOptions& options) {
  const std::size_t n = all.size();
  LevelPlan plan;
  const bool multiscale = options.levels != 1 && n > 1;
  const double neighbors = options.neighbors > 0 ? options.neighbors
                           : multiscale          ? kMultiscaleNeighbors
                                                 : kDefaultNeighbors;
  plan.finest = options.radius > 0 ? options.radius
                : multiscale       ? 0.5 * detail::neighbour_radius(all, dim, neighbors)
                                   : detail::neighbour_radius(all, dim, neighbors);
  {
    // The grid's rule, before the thinning's cells (at most 1e9 radii across, so that a cell of side
    // finest (ball / K)^(1/D), K <= 1e9, is numbered within 64 bits).
    Vec3 lo = all[0], hi = all[0];
    for (const Vec3& p : all) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    NeighborIndex::check_extent(lo, hi, plan.finest, "points");
  }
  const double cell = plan.finest * std::pow(detail::unit_ball(dim) / neighbors, 1.0 / dim);
  if (multiscale) {
    // As many thinned levels as asked for, or (automatic) until the coarsest has at most
    // kCoarsestPoints points; never one of fewer than 2 points. A thinned level has one point an
    // occupied cell: counted first, then the points picked in one pass.
    const int most = options.levels == 0 ? kAutoLevels : options.levels;
    Vec3 lo = all[0];
    for (const Vec3& p : all) lo = lo.cwiseMin(p);
    int thinned = 0;
    for (int l = 1; l < most; ++l) {
      const double h = cell * std::ldexp(1.0, l + 1);
      std::unordered_set<Cell, CellHash> occupied;
      for (const Vec3& p : all) {
        Cell key{};
        for (int a = 0; a < dim; ++a) key[std::size_t(a)] = std::int64_t(std::floor((p[a] - lo[a]) / h));
        occupied.insert(key);
      }
      if (occupied.size() < 2) break;
      thinned = l;
      if (options.levels == 0 && double(occupied.size()) <= kCoarsestPoints) break;
    }
    for (int l = 0; l < thinned; ++l) plan.cells.push_back(cell * std::ldexp(1.0, thinned - l + 1));
    if (!plan.cells.empty()) plan.first = thin(all, dim, plan.cells);
  }
  if (plan.first.empty()) plan.first.assign(n, 0);
  return plan;
}

/// One level's points: pts[k] is the input point member[k].
struct LevelPoints {
  std::vector<std::size_t> member;
  std::vector<Vec3> pts;
  bool sorted = false;  // into the Schwarz patches' order
};

/// The points of level l (of radius `radius`), its radius and extent checked.
LevelPoints select_level(std::span<const Vec3> all, const LevelPlan& plan, std::size_t l, double radius, int dim,
                         const InterpolatorOptions& options) {
  const std::size_t n = all.size(), levels = plan.levels();
  LevelPoints lp;
  std::vector<std::size_t>& member = lp.member;
  for (std::size_t i = 0; i < n; ++i)
    if (plan.first[i] <= l) member.push_back(i);
  const std::size_t m = member.size();
  std::vector<Vec3>& pts = lp.pts;
  pts.resize(m);
  for (std::size_t k = 0; k < m; ++k) pts[k] = all[member[k]];
  if (!(radius >= 1e-150 && radius <= 1e150)) {
    std::ostringstream os;
    os << "the radius" << (levels > 1 ? " of level " + std::to_string(l + 1) : std::string()) << " would be " << radius
       << ", outside [1e-150, 1e150]" << (levels > 1 ? ": use fewer levels or scale the points" : ": scale the points");
    throw InvalidInput(os.str());
  }
  Vec3 lo = pts[0], hi = pts[0];
  for (const Vec3& p : pts) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  NeighborIndex::check_extent(lo, hi, radius, "points");
  // Where CG with the Schwarz patches will solve the level (scattered points in 2-D or 3-D, many
  // of them), its points are sorted into the patches' order first: A is then built in CG's order,
  // and CG reads it in place rather than copying it (fit.cpp, ordering_and_solver). The level
  // keeps its points in that order; `member` maps them back to the input.
  lp.sorted =
      dim >= 2 && m >= detail::kSchwarzOnlyPoints && (options.solver == Solver::Auto || options.solver == Solver::Cg);
  if (lp.sorted) {
    const std::vector<std::uint32_t> perm = detail::schwarz_order(pts, radius);
    std::vector<std::size_t> by(m);
    for (std::size_t k = 0; k < m; ++k) {
      by[k] = member[perm[k]];
      pts[k] = all[by[k]];
    }
    member = std::move(by);
  }
  return lp;
}

/// The smoothing of a level's points (one value for all, or one a point), empty where none is > 0.
std::vector<double> level_smoothing(const InterpolatorOptions& options, std::span<const std::size_t> member) {
  std::vector<double> shift;
  if (options.smoothing.size() == 1)
    shift = options.smoothing;
  else if (!options.smoothing.empty())
    for (std::size_t i : member) shift.push_back(options.smoothing[i]);
  const bool any_shift = std::any_of(shift.begin(), shift.end(), [](double s) { return s > 0; });
  if (!any_shift) shift.clear();
  return shift;
}

/// The level's kernel system over its points (whose neighbour grid the level's maps keep): A +
/// Lambda, its solver and factor, and the polynomial block of its degree. The system's own checks
/// are reported in the interpolator's words (points, degree).
std::shared_ptr<KernelSystem> fit_level(const LevelPoints& lp, std::span<const Vec3> all, int dim, double radius,
                                        int degree, const InterpolatorOptions& options, std::span<const double> shift) {
  auto cloud = std::make_shared<detail::PointCloud>(lp.pts, radius, options.memory_limit_bytes);
  cloud->dims = dim;
  // Cells of side R (not R/2): the interpolator's levels each build a grid and its lists, which at
  // cells of R/2 cost more than the finer cells save (Franke's function, 1e5 points, 7 levels: fit
  // and evaluation of 2e5 points 1.4 s against 1.7 s, of 1e6 points 1.4 against 1.9 s).
  cloud->max_subdivision = 1;
  cloud->eval_list_bytes = std::size_t(std::min(options.memory_limit_bytes, 1e18));
  KernelSystemOptions so;
  so.radius = radius;
  so.kernel = options.kernel;
  so.dimension = dim;
  so.degree = degree;
  so.solver = options.solver;
  so.memory_limit_bytes = options.memory_limit_bytes;
  so.schwarz = true;
  so.schwarz_sorted = lp.sorted;
  so.direct_after_breakdown = true;
  auto system = std::make_shared<KernelSystem>(std::move(cloud), so, shift);
  try {
    system->analyse();
    system->factorise();
  } catch (const DuplicateSource& e) {
    const std::size_t a = std::min(lp.member[e.first()], lp.member[e.second()]),
                      b = std::max(lp.member[e.first()], lp.member[e.second()]);  // sorted levels: any order
    std::ostringstream os;
    os << "points " << a << " and " << b << " are at the same position (";
    for (int d = 0; d < dim; ++d) os << (d ? ", " : "") << all[a][d];
    os << "): interpolation needs distinct points (give them smoothing > 0, or merge them)";
    throw DuplicateSource(a, b, os.str());
  }
  const std::size_t m = lp.pts.size();
  if (system->info() == SystemInfo::DegeneratePolynomial) {
    const char* shape = dim == 1 ? "all at one position" : dim == 2 ? "collinear" : "coplanar";
    throw DegeneratePolynomial("degree 1 needs points that span their " + std::to_string(dim) + "-D space, " +
                               (m < std::size_t(dim) + 1
                                    ? "at least " + std::to_string(dim + 1) + " of them, but there " +
                                          (m == 1 ? std::string("is 1") : "are " + std::to_string(m))
                                    : "but the " + std::to_string(m) + " points are " + shape) +
                               "; use degree 0 or -1");
  }
  if (system->info() == SystemInfo::NumericalIssue)
    throw DegeneratePolynomial("degree " + std::to_string(degree) +
                               ": the points do not determine the polynomial; use degree -1");
  return system;
}

/// A level's coefficients: alpha (m x V, the level's input order) and beta (terms x V).
struct LevelCoefficients {
  RowMatrix alpha;
  Eigen::MatrixXd beta;
};

/// lv.residual_relative, the system's residual check of (A + Lambda) alpha + P beta - f (g: f, in
/// the input order of the level); IllConditioned beyond kResidualLimit.
void check_level_residual(InterpolatorLevel& lv, const KernelSystem& system, const LevelPoints& lp,
                          const LevelCoefficients& c, const RowMatrix& g, std::size_t l, std::size_t levels) {
  lv.residual_relative = system.residual(c.alpha, c.beta, g).relative;
  if (!(lv.residual_relative <= kResidualLimit)) {
    std::ostringstream os;
    os << "the values cannot be fitted to a relative residual of " << kResidualLimit << " (got " << lv.residual_relative
       << ")";
    if (levels > 1) os << " at level " << l + 1 << " of " << levels;
    os << ": the matrix is too ill-conditioned at radius " << lv.radius;
    if (!system.matrix().values().empty()) {
      const auto [a, b] = system.matrix().closest_pair();
      os << "; the closest points, " << lp.member[a] << " and " << lp.member[b] << ", are "
         << (lp.pts[a] - lp.pts[b]).norm() / lv.radius << " R apart";
    }
    os << ". Use a smaller radius (fewer neighbours), smoothing > 0, or merge close points";
    throw IllConditioned(os.str());
  }
}

/// Level l fitted to `residual` (n x V: what the coarser levels leave), with lv.rms_before and
/// lv.residual_relative (check_level_residual).
LevelCoefficients solve_level(InterpolatorLevel& lv, KernelSystem& system, const LevelPoints& lp,
                              std::span<const double> residual, std::size_t nv, std::size_t l, std::size_t levels) {
  const std::size_t m = lp.pts.size();
  const std::span<const std::uint32_t> order = system.order();  // row k of the solves is member[order[k]]
  LevelCoefficients c;
  RowMatrix& z = c.alpha;
  z.resize(Eigen::Index(m), Eigen::Index(nv));
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t v = 0; v < nv; ++v) z(Eigen::Index(i), Eigen::Index(v)) = residual[lp.member[i] * nv + v];
  double sum2 = 0;
  for (std::size_t k = 0; k < m; ++k) sum2 += z.row(Eigen::Index(order[k])).squaredNorm();
  lv.rms_before = std::sqrt(sum2 / double(m * nv));
  const RowMatrix g = z;
  KernelSystem::require(system.solve(z, c.beta));
  check_level_residual(lv, system, lp, c, g, l, levels);
  return c;
}

/// The level's record: its points, coefficients and what its fit did.
void store_level(InterpolatorLevel& lv, const KernelSystem& system, std::span<const Vec3> pts,
                 const LevelCoefficients& c, int dim, std::size_t nv) {
  const std::size_t m = pts.size();
  const int terms = system.terms();
  lv.mean_neighbors = system.stats().mean_neighbors;
  lv.solver = system.solver();
  lv.iterations = system.iterations();
  lv.points.resize(m * std::size_t(dim));
  for (std::size_t k = 0; k < m; ++k)
    for (int a = 0; a < dim; ++a) lv.points[k * std::size_t(dim) + std::size_t(a)] = pts[k][a];
  lv.alpha.assign(c.alpha.data(), c.alpha.data() + c.alpha.size());
  if (terms > 0) {
    lv.beta.resize(std::size_t(terms) * nv);
    for (int t = 0; t < terms; ++t)
      for (std::size_t v = 0; v < nv; ++v) lv.beta[std::size_t(t) * nv + v] = c.beta(t, Eigen::Index(v));
  }
}

/// A level's evaluation structure: its points and their grid, radius, kernel and polynomial; no
/// matrix (the system's, with its factor, is not needed to evaluate).
std::shared_ptr<SpaceMap::Structure> level_structure(std::shared_ptr<detail::PointCloud> cloud, Kernel kernel,
                                                     int degree, const Vec3& center, double scale) {
  auto st = std::make_shared<SpaceMap::Structure>();
  st->cloud = std::move(cloud);
  st->options.radius = st->cloud->radius;
  st->options.kernel = kernel;
  st->options.memory_limit_bytes = st->cloud->memory_limit_bytes;
  // The evaluation adds the polynomial where the structure has one (beta's rows past D are zero).
  st->options.polynomial = degree < 0 ? Polynomial::None : degree == 0 ? Polynomial::Constant : Polynomial::Linear;
  st->terms = degree < 0 ? 0 : degree == 0 ? 1 : 4;
  st->center = center;
  st->scale = scale;
  st->stats.controls = st->cloud->points.size();
  return st;
}

/// The map of values 3 chunk .. 3 chunk + 2 of a level, over its structure.
SpaceMap level_map(std::shared_ptr<const SpaceMap::Structure> st, const InterpolatorLevel& level, int dim,
                   std::size_t values, std::size_t chunk, int degree) {
  const std::size_t n = level.points.size() / std::size_t(dim);
  Eigen::Matrix<double, Eigen::Dynamic, 3> alpha = Eigen::Matrix<double, Eigen::Dynamic, 3>::Zero(Eigen::Index(n), 3);
  Eigen::Matrix<double, 4, 3> beta = Eigen::Matrix<double, 4, 3>::Zero();
  const int terms = terms_of(degree, dim);
  for (std::size_t c = 0; c < 3 && 3 * chunk + c < values; ++c) {
    const std::size_t v = 3 * chunk + c;
    for (std::size_t i = 0; i < n; ++i) alpha(Eigen::Index(i), Eigen::Index(c)) = level.alpha[i * values + v];
    for (int t = 0; t < terms; ++t) beta(t, Eigen::Index(c)) = level.beta[std::size_t(t) * values + v];
  }
  auto s = std::make_shared<SpaceMap::State>();
  s->st = std::move(st);
  s->alpha = std::move(alpha);
  s->beta = beta;
  s->poly.center = level.center;
  s->poly.inv_scale = 1.0 / level.scale;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 3; ++c) s->poly.b[r][c] = beta(r, c);
  s->stats = s->st->stats;
  return SpaceMap(std::move(s));
}

}  // namespace

std::size_t Interpolator::size() const noexcept {
  return levels_ && !levels_->empty() ? levels_->back().points.size() / std::size_t(dim_) : 0;
}

Interpolator Interpolator::fit(std::span<const double> points, int dim, std::span<const double> values,
                               std::size_t value_count, const InterpolatorOptions& options) {
  const auto t_fit = Clock::now();
  validate(points, dim, values, value_count, options);
  const std::size_t n = points.size() / std::size_t(dim), nv = value_count;
  std::vector<Vec3> all(n, Vec3::Zero());
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < dim; ++a) all[i][a] = points[i * std::size_t(dim) + std::size_t(a)];
  const LevelPlan plan = plan_levels(all, dim, options);
  const std::size_t levels = plan.levels();

  auto out = std::make_shared<std::vector<InterpolatorLevel>>(levels);
  auto maps = std::make_shared<std::vector<std::vector<SpaceMap>>>(levels);
  std::vector<double> residual(values.begin(), values.end());  // n x V: what the levels so far leave
  const std::size_t chunks = (nv + 2) / 3;
  // Every point, interleaved, and its displacement by a level: where the residual is taken.
  std::vector<double> x(levels > 1 ? 3 * n : 0), d(x.size());
  for (std::size_t i = 0; i < x.size() / 3; ++i)
    for (int a = 0; a < 3; ++a) x[3 * i + std::size_t(a)] = all[i][a];
  for (std::size_t l = 0; l < levels; ++l) {
    const auto t0 = Clock::now();
    InterpolatorLevel& lv = (*out)[l];
    const int degree = l == 0 ? options.degree : -1;  // the polynomial belongs to the coarsest level
    lv.radius = std::ldexp(plan.finest, l + 1 < levels ? int(levels - l) : 0);
    const LevelPoints lp = select_level(all, plan, l, lv.radius, dim, options);
    const std::vector<double> shift = level_smoothing(options, lp.member);
    std::shared_ptr<KernelSystem> system = fit_level(lp, all, dim, lv.radius, degree, options, shift);
    lv.center = system->center();
    lv.scale = system->scale();
    {
      const LevelCoefficients coefficients = solve_level(lv, *system, lp, residual, nv, l, levels);
      store_level(lv, *system, lp.pts, coefficients, dim, nv);
    }
    // The system's matrix and factor are not needed to evaluate: freed, the points' grid kept.
    const std::shared_ptr<const SpaceMap::Structure> shared =
        level_structure(system->cloud(), options.kernel, degree, lv.center, lv.scale);
    system.reset();
    for (std::size_t c = 0; c < chunks; ++c) (*maps)[l].push_back(level_map(shared, lv, dim, nv, c, degree));
    // What is left for the finer levels, at every point they hold.
    if (l + 1 < levels) {
      for (std::size_t c = 0; c < chunks; ++c) {
        (*maps)[l][c].displacements(x.data(), d.data(), n);
        for (std::size_t i = 0; i < n; ++i)
          for (std::size_t k = 0; k < 3 && 3 * c + k < nv; ++k) residual[i * nv + 3 * c + k] -= d[3 * i + k];
      }
    }
    lv.seconds = seconds_since(t0);
  }
  Interpolator r;
  r.dim_ = dim;
  r.values_ = nv;
  r.kernel_ = options.kernel;
  r.degree_ = options.degree;
  r.levels_ = std::move(out);
  r.maps_ = std::move(maps);
  r.seconds_fit_ = seconds_since(t_fit);
  return r;
}

Interpolator Interpolator::from_levels(int dim, std::size_t value_count, Kernel kernel, int degree,
                                       std::vector<InterpolatorLevel> levels, double seconds_fit) {
  if (dim < 1 || dim > kMaxDimension) throw InvalidInput("from_levels: dimension must be 1, 2 or 3");
  if (value_count == 0 || levels.empty() || levels.size() > std::size_t(kMaxLevels))
    throw InvalidInput("from_levels: needs 1.." + std::to_string(kMaxLevels) + " levels and at least one value");
  if (degree < -1 || degree > 1) throw InvalidInput("from_levels: degree must be -1, 0 or 1");
  auto maps = std::make_shared<std::vector<std::vector<SpaceMap>>>(levels.size());
  for (std::size_t l = 0; l < levels.size(); ++l) {
    const InterpolatorLevel& lv = levels[l];
    const std::size_t n = lv.points.size() / std::size_t(dim);
    const int terms = terms_of(l == 0 ? degree : -1, dim);
    // By division, not multiplication: a value_count of 2^62 must not wrap n * value_count to 0.
    if (n == 0 || lv.points.size() != n * std::size_t(dim) || lv.alpha.size() % value_count != 0 ||
        lv.alpha.size() / value_count != n || lv.beta.size() % value_count != 0 ||
        lv.beta.size() / value_count != std::size_t(terms))
      throw InvalidInput("from_levels: level " + std::to_string(l) + " has " + std::to_string(lv.points.size()) +
                         " coordinates, " + std::to_string(lv.alpha.size()) + " coefficients and " +
                         std::to_string(lv.beta.size()) + " polynomial terms, which do not agree with D = " +
                         std::to_string(dim) + " and " + std::to_string(value_count) + " values");
    // A level's structure, shared by its maps: its points and radius, no matrix (evaluation only).
    std::vector<Vec3> pts(n, Vec3::Zero());
    for (std::size_t i = 0; i < n; ++i)
      for (int a = 0; a < dim; ++a) pts[i][a] = lv.points[i * std::size_t(dim) + std::size_t(a)];
    const std::string where = "from_levels: level " + std::to_string(l);
    detail::check_points(pts, (where + ", point").c_str());
    const auto finite = [](const std::vector<double>& v) {
      return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
    };
    bool centre_ok = lv.center.allFinite() && lv.center.cwiseAbs().maxCoeff() <= detail::kMaxCoordinate;
    for (int a = dim; a < 3; ++a) centre_ok = centre_ok && lv.center[a] == 0;  // padding
    if (!(lv.radius >= 1e-150 && lv.radius <= 1e150) || !(lv.scale > 0) || !(lv.scale <= 1e300) || !centre_ok ||
        !finite(lv.alpha) || !finite(lv.beta))
      throw InvalidInput(where +
                         ": the radius must be in [1e-150, 1e150], the scale in (0, 1e300], the centre within "
                         "1e150 (0 past the points' dimension) and the coefficients finite");
    Vec3 lo = pts[0], hi = pts[0];
    for (const Vec3& p : pts) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    NeighborIndex::check_extent(lo, hi, lv.radius, "points");
    const int deg = l == 0 ? degree : -1;
    auto cloud = std::make_shared<detail::PointCloud>(pts, lv.radius, FitOptions{}.memory_limit_bytes);
    cloud->dims = dim;
    cloud->max_subdivision = 1;  // as the fit's levels (fit_level)
    cloud->eval_list_bytes = std::size_t(cloud->memory_limit_bytes);
    const std::shared_ptr<const SpaceMap::Structure> shared =
        level_structure(std::move(cloud), kernel, deg, lv.center, lv.scale);
    for (std::size_t c = 0; c < (value_count + 2) / 3; ++c)
      (*maps)[l].push_back(level_map(shared, lv, dim, value_count, c, deg));
  }
  Interpolator r;
  r.dim_ = dim;
  r.values_ = value_count;
  r.kernel_ = kernel;
  r.degree_ = degree;
  r.levels_ = std::make_shared<const std::vector<InterpolatorLevel>>(std::move(levels));
  r.maps_ = std::move(maps);
  r.seconds_fit_ = std::isfinite(seconds_fit) && seconds_fit >= 0 ? seconds_fit : 0.0;
  return r;
}

namespace {
/// InvalidInput naming the first point whose result (q x w) is not finite: far beyond the data the
/// polynomial can overflow; no NaN or infinity is returned silently.
template <class T>
void check_results(const T* x, const T* out, std::size_t q, std::size_t d, std::size_t w, std::size_t offset) {
  for (std::size_t i = 0; i < q * w; ++i)
    if (!std::isfinite(out[i])) {
      const std::size_t k = i / w;
      std::ostringstream os;
      os << "x[" << offset + k << "] = (";
      for (std::size_t a = 0; a < d; ++a) os << (a ? ", " : "") << x[k * d + a];
      os << "): the interpolant overflows there (" << out[i] << "), too far beyond the points for "
         << (sizeof(T) == 4 ? "float32" : "float64");
      throw InvalidInput(os.str());
    }
}
}  // namespace

template <class T>
void Interpolator::evaluate_impl(const T* x, std::size_t q, T* out) const {
  if (!maps_) throw InvalidInput("Interpolator: not fitted");
  const std::size_t nv = values_, d = std::size_t(dim_);
  FillVector<T> in(3 * std::min(q, kBatch)), part(in.size());  // each entry written before it is read
  for (std::size_t b = 0; b < q; b += kBatch) {
    const std::size_t m = std::min(kBatch, q - b);
    for (std::size_t i = 0; i < m; ++i)
      for (std::size_t a = 0; a < 3; ++a) in[3 * i + a] = a < d ? x[(b + i) * d + a] : T(0);
    T* o = out + b * nv;
    std::fill(o, o + m * nv, T(0));
    for (const auto& level : *maps_)
      for (std::size_t c = 0; c < level.size(); ++c) {
        level[c].displacements(in.data(), part.data(), m);
        for (std::size_t i = 0; i < m; ++i)
          for (std::size_t k = 0; k < 3 && 3 * c + k < nv; ++k) o[i * nv + 3 * c + k] += part[3 * i + k];
      }
    check_results(x + b * d, o, m, d, nv, b);
  }
}

void Interpolator::evaluate(const double* x, std::size_t q, double* out) const { evaluate_impl(x, q, out); }
void Interpolator::evaluate(const float* x, std::size_t q, float* out) const { evaluate_impl(x, q, out); }

void Interpolator::gradient(const double* x, std::size_t q, double* out) const {
  if (!maps_) throw InvalidInput("Interpolator: not fitted");
  const std::size_t nv = values_, d = std::size_t(dim_);
  const std::size_t batch = std::min(q, kBatch);
  std::vector<double> in(3 * batch), moved(3 * batch), jac(9 * batch);
  for (std::size_t b = 0; b < q; b += kBatch) {
    const std::size_t m = std::min(kBatch, q - b);
    for (std::size_t i = 0; i < m; ++i)
      for (std::size_t a = 0; a < 3; ++a) in[3 * i + a] = a < d ? x[(b + i) * d + a] : 0.0;
    double* o = out + b * nv * d;
    std::fill(o, o + m * nv * d, 0.0);
    for (const auto& level : *maps_)
      for (std::size_t c = 0; c < level.size(); ++c) {
        level[c].apply_with_normals(in.data(), moved.data(), m, 1.0, nullptr, nullptr, jac.data());
        for (std::size_t i = 0; i < m; ++i)
          for (std::size_t k = 0; k < 3 && 3 * c + k < nv; ++k)
            for (std::size_t a = 0; a < d; ++a)
              o[(i * nv + 3 * c + k) * d + a] += jac[9 * i + 3 * k + a] - (k == a ? 1.0 : 0.0);
      }
    check_results(x + b * d, o, m, d, nv * d, b);
  }
}

}  // namespace csrbf
