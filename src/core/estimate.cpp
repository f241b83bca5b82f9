// csrbf::estimate and csrbf::suggest_radius (estimate.hpp).
#include "csrbf/estimate.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/ordering.hpp"
#include "csrbf/units.hpp"
#include "fit_state.hpp"
#include "incomplete_cholesky.hpp"
#include "radius.hpp"
#include "sparse_solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <sstream>

namespace csrbf {
namespace {

std::string format(double v) { return format_significant(v, 3); }

}  // namespace

FitEstimate estimate(std::span<const Vec3> sources, double radius, const FitOptions& options) {
  if (!(radius > 0) || !std::isfinite(radius))
    throw InvalidInput("estimate: radius must be positive and finite, got " + format(radius));
  detail::check_points(sources, "source");
  FitEstimate e;
  const std::size_t n = sources.size();
  e.controls = n;
  e.radius = radius;
  if (n == 0) return e;
  const FitMemoryEstimate sample = estimate_fit_memory(sources, radius);
  e.mean_neighbors = sample.mean_neighbors;
  e.max_neighbors = sample.max_neighbors;
  const double nd = double(n);
  double pairs = nd * e.mean_neighbors / 2;
  const double limit = options.memory_limit_bytes;
  // The exact graph where it is affordable: 12 bytes a directed entry.
  double envelope_entries = std::numeric_limits<double>::quiet_NaN(), envelope_work = envelope_entries;
  double direct_entries = envelope_entries, direct_flops = envelope_entries;
  const auto affordable = [&](double p) { return 2 * p * 12 <= limit && 2 * p <= kEstimateExactEntries; };
  std::optional<NeighborIndex> index;
  if (affordable(pairs)) {
    // The sample can miss a dense cluster (1e4 points among 2e6 made 1e8 entries where it predicted
    // 1e7): every source's neighbours are counted first, exactly, allocating nothing per pair; the
    // graph is built only where that count is affordable too.
    index.emplace(sources, radius);
    const std::pair<double, double> counted = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, 2048), std::pair<double, double>{0.0, 0.0},
        [&](const tbb::blocked_range<std::size_t>& r, std::pair<double, double> s) {
          for (std::size_t slot = r.begin(); slot < r.end(); ++slot) {
            double c = -1;  // the source itself
            index->for_each_within(index->point(slot), [&](std::size_t, double) { c += 1; });
            s.first += c;
            s.second = std::max(s.second, c);
          }
          return s;
        },
        [](std::pair<double, double> a, const std::pair<double, double>& b) {
          return std::pair<double, double>{a.first + b.first, std::max(a.second, b.second)};
        });
    pairs = counted.first / 2;
    e.mean_neighbors = counted.first / nd;
    e.max_neighbors = counted.second;
    e.counted = true;
  }
  if (index && affordable(pairs)) {
    const AdjacencyGraph g = AdjacencyGraph::from_index(*index, sources);
    e.exact = true;
    pairs = double(g.neighbors.size()) / 2;
    e.mean_neighbors = 2 * pairs / nd;
    e.max_neighbors = 0;
    for (std::size_t i = 0; i < n; ++i) e.max_neighbors = std::max(e.max_neighbors, double(g.degree(i)));
    const auto first = envelope_first_columns(g, reverse_cuthill_mckee_order(g));
    envelope_work = csrbf::envelope_work(first);
    envelope_entries = 0;
    for (std::size_t k = 0; k < n; ++k) envelope_entries += double(k - first[k]);
    const FactorCount fc =
        cholesky_factor_count(g, nested_dissection_order(g, sources, radius), std::max(0.0, limit / 12.0));
    direct_entries = fc.entries;
    direct_flops = fc.flops;
  }
  e.nonzeros = nd + 2 * pairs;
  const std::size_t entries = std::size_t(2 * pairs);
  // Shared by every solver: the graph becomes A in place (kernel_matrix_bytes), built in about
  // kSecondsPerEntry a non-zero (the index, the graph, the ordering, the assembly).
  const double a_bytes = 12.0 * double(entries) + 8.0 * (nd + 1);
  const double shared_seconds = kSecondsPerEntry * e.nonzeros;
  const double step = 3.0 * (2.0 * pairs + nd);  // a CG step's multiply-adds, three right-hand sides

  SolverEstimate env;
  env.solver = Solver::Envelope;
  if (e.exact) {
    env.bytes = a_bytes + detail::envelope_factor_bytes(envelope_entries, n);
    env.seconds = shared_seconds + kEnvelopeCostRatio * envelope_work * kSecondsPerCgMultiplyAdd;
    env.factor_entries = envelope_entries;
    env.work = envelope_work;
    env.note = "reverse Cuthill-McKee envelope: " + format(envelope_entries) + " entries, " + format(envelope_work) +
               " multiply-adds";
  } else {
    env.bytes = a_bytes + detail::envelope_factor_bytes(nd * e.mean_neighbors, n);  // at least its band
    env.seconds = env.factor_entries = env.work = std::numeric_limits<double>::quiet_NaN();
    env.note =
        "neighbour graph not built (beyond the memory limit or 1e7 entries): its envelope is unknown, at least "
        "this";
  }
  SolverEstimate direct;
  direct.solver = cholmod_available() ? Solver::Cholmod : Solver::Eigen;
  if (e.exact) {
    direct.bytes = a_bytes + 12.0 * direct_entries + 2 * 12.0 * (pairs + nd);
    direct.seconds = shared_seconds + kDirectFlopCost * direct_flops * kSecondsPerCgMultiplyAdd;
    direct.factor_entries = direct_entries;
    direct.work = direct_flops;
    direct.note =
        "nested dissection: " + format(direct_entries) + " factor entries, " + format(direct_flops) + " flops";
    if (!std::isfinite(direct_flops) || direct_entries * 12.0 > limit) direct.note += " (stopped at the memory limit)";
  } else {
    direct.bytes = a_bytes + 2 * 12.0 * (pairs + nd);
    direct.seconds = direct.factor_entries = direct.work = std::numeric_limits<double>::quiet_NaN();
    direct.note = "neighbour graph not built: the factor is unknown, at least this";
  }
  SolverEstimate cg;
  cg.solver = Solver::Cg;
  cg.bytes = a_bytes + detail::cg_bytes(entries, n);
  cg.factor_entries = 2 * pairs;
  cg.work = kCgStepsEstimate * step;
  cg.seconds = shared_seconds + cg.work * kSecondsPerCgMultiplyAdd;
  cg.note = "at " + format(kCgStepsEstimate) +
            " plain steps' work, Auto's estimate (measured at 1e6 controls: 40 plain steps on a sphere; 159 "
            "preconditioned, each two plain ones' work, in a cube of random points)";
  for (SolverEstimate* s : {&env, &direct, &cg}) {
    s->within_limit = s->bytes <= limit;
    e.solvers.push_back(*s);
  }
  e.chosen = resolve_solver(options.solver, e.exact ? envelope_work : std::numeric_limits<double>::infinity(), n,
                            std::size_t(pairs));
  return e;
}

double suggest_radius(std::span<const Vec3> sources, double neighbours) {
  const std::size_t n = sources.size();
  if (n < 2) throw InvalidInput("suggest_radius: needs at least 2 sources, got " + std::to_string(n));
  if (!(neighbours > 0) || !(neighbours < double(n - 1)))
    throw InvalidInput("suggest_radius: neighbours must be within (0, " + std::to_string(n - 1) + "), got " +
                       format(neighbours));
  detail::check_points(sources, "source");
  if (std::all_of(sources.begin(), sources.end(), [&](const Vec3& p) { return p == sources[0]; }))
    throw InvalidInput("suggest_radius: the sources are all at one point");
  // The interpolator's measure (radius.cpp): the distances of a seeded sample of up to 4096 sources
  // to their neighbours, found once with the neighbour grid, the radius the one that many fall
  // within; a bisection on R counting 256 sources at each of ~25 steps was 10x slower at 1e5.
  return detail::neighbour_radius(sources, 3, neighbours);
}

}  // namespace csrbf
