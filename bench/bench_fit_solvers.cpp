// Whole fits (graph, ordering, factorisation or CG, solve, residual check) by each solver on the
// Fibonacci sphere, about 23 neighbours a control (R = sqrt(100 / N)), C2, polynomial none: the
// figures of docs/PERFORMANCE.md, "Conjugate gradients". Run:
//   build/bin/bench_core --benchmark_filter=Fit/
// Arguments: N, then the solver (0 envelope, 1 CHOLMOD or Eigen, 2 CG, 3 auto).
#include "csrbf/space_map.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using namespace csrbf;

namespace {

void fibonacci_sphere(std::size_t n, std::vector<Vec3>& s, std::vector<Vec3>& d) {
  s.resize(n);
  d.resize(n);
  const double turn = M_PI * (3 - std::sqrt(5.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double z = 1 - 2 * (double(i) + 0.5) / double(n), r = std::sqrt(1 - z * z);
    s[i] = Vec3(r * std::cos(turn * double(i)), r * std::sin(turn * double(i)), z);
    d[i] = s[i] * (1 + 0.02 * std::sin(7 * s[i].x()) * std::cos(5 * s[i].y()));
  }
}

void BM_Fit(benchmark::State& state) {
  const auto n = std::size_t(state.range(0));
  std::vector<Vec3> s, d;
  fibonacci_sphere(n, s, d);
  const Solver solvers[] = {Solver::Envelope, cholmod_available() ? Solver::Cholmod : Solver::Eigen, Solver::Cg,
                            Solver::Auto};
  FitOptions o{std::sqrt(100.0 / double(n)), Kernel::C2, Polynomial::None};
  o.solver = solvers[state.range(1)];
  FitStats stats;
  for (auto _ : state) {
    const SpaceMap m = SpaceMap::fit(s, d, o);
    stats = m.stats();
    benchmark::DoNotOptimize(m.coefficients().data());
  }
  state.SetLabel(std::string(solver_name(stats.solver)) +
                 (stats.iterations ? ", " + std::to_string(stats.iterations) + " steps" : ""));
  state.counters["neighbours"] = stats.mean_neighbors;
}

// An animation frame: 1% of the destinations move (every hundredth control, by 1% of the radius)
// and the fitted map re-solves with with_destinations (CG warm-started from the previous solution).
// Compare with BM_Fit/N/3, a fresh fit of the same system.
void BM_WithDestinations(benchmark::State& state) {
  const auto n = std::size_t(state.range(0));
  std::vector<Vec3> s, d;
  fibonacci_sphere(n, s, d);
  FitOptions o{std::sqrt(100.0 / double(n)), Kernel::C2, Polynomial::None};
  const SpaceMap m = SpaceMap::fit(s, d, o);
  FitStats stats;
  int frame = 0;
  for (auto _ : state) {
    std::vector<Vec3> moved = d;
    ++frame;
    for (std::size_t i = std::size_t(frame) % 100; i < n; i += 100) moved[i] += Vec3(0, 0, 0.01 * o.radius);
    const SpaceMap next = m.with_destinations(moved);
    stats = next.stats();
    benchmark::DoNotOptimize(next.coefficients().data());
  }
  state.SetLabel(std::string(solver_name(stats.solver)) +
                 (stats.iterations ? ", " + std::to_string(stats.iterations) + " steps" : ""));
}

// M = 1e6 points on the sphere (radius 0.99) through N = 1e4 controls, in ring order (0) or shuffled
// (1, seeded), in double (0) or float (1). The target: shuffled within 1.25x of ring order.
//   build/bin/bench_core --benchmark_filter=ApplyOrder --benchmark_repetitions=5
void BM_ApplyOrder(benchmark::State& state) {
  const std::size_t n = 10000, m = 1000000;
  std::vector<Vec3> s, d, v;
  fibonacci_sphere(n, s, d);
  for (std::size_t ring = 0; ring < 1000; ++ring) {  // a UV sphere: rings of latitude, points along each
    const double z = 1 - 2 * (double(ring) + 0.5) / 1000, r = std::sqrt(1 - z * z);
    for (std::size_t k = 0; k < m / 1000; ++k)
      v.emplace_back(r * std::cos(2 * M_PI * double(k) / double(m / 1000)),
                     r * std::sin(2 * M_PI * double(k) / double(m / 1000)), z);
  }
  if (state.range(0)) std::shuffle(v.begin(), v.end(), std::mt19937_64(7));
  const SpaceMap map = SpaceMap::fit(s, d, FitOptions{std::sqrt(100.0 / double(n)), Kernel::C2, Polynomial::None});
  std::vector<double> in(3 * m), out(3 * m);
  for (std::size_t i = 0; i < m; ++i)
    for (int c = 0; c < 3; ++c) in[3 * i + c] = 0.99 * v[i][c];
  std::vector<float> inf(in.begin(), in.end()), outf(3 * m);
  for (auto _ : state) {
    if (state.range(1))
      map.apply(inf.data(), outf.data(), m);
    else
      map.apply(in.data(), out.data(), m);
    benchmark::ClobberMemory();
  }
}

}  // namespace

BENCHMARK(BM_ApplyOrder)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WithDestinations)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Fit)
    ->ArgsProduct({{100, 300, 1000, 10000}, {0, 1, 2, 3}})
    ->Args({100000, 1})
    ->Args({100000, 2})
    ->Args({100000, 3})
    ->Args({1000000, 3})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
