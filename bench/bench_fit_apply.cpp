// Whole fits and evaluations on the bundled fish's sizes (92 controls, R = 0.3, 977 vertices in the
// unit cube) and DisplacementField playback against a memcpy of the same bytes.
// Run: build/bench/bench_core --benchmark_filter=Fish
#include "csrbf/displacement_field.hpp"

#include <benchmark/benchmark.h>

#include <cstring>
#include <random>

using namespace csrbf;

namespace {
struct Fish {
  std::vector<Vec3> s, d;
  std::vector<double> verts;
  Fish() {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.05, 0.95);
    for (int i = 0; i < 92; ++i) {
      s.emplace_back(u(rng), u(rng), u(rng));
      d.push_back(s.back() + 0.05 * Vec3(u(rng), u(rng), u(rng)));
    }
    for (int i = 0; i < 3 * 977; ++i) verts.push_back(u(rng));
  }
};
const Fish& fish() {
  static const Fish f;
  return f;
}

void BM_FishFit(benchmark::State& st) {
  const Fish& f = fish();
  for (auto _ : st) benchmark::DoNotOptimize(SpaceMap::fit(f.s, f.d, {0.3, Kernel::C2, Polynomial::None}));
}
void BM_FishApply(benchmark::State& st) {
  const Fish& f = fish();
  const SpaceMap m = SpaceMap::fit(f.s, f.d, {0.3, Kernel::C2, Polynomial::None});
  std::vector<double> out(f.verts.size());
  for (auto _ : st) {
    m.apply(f.verts.data(), out.data(), 977, 0.5);
    benchmark::DoNotOptimize(out.data());
  }
}
void BM_FishPlayback(benchmark::State& st) {
  const Fish& f = fish();
  const SpaceMap m = SpaceMap::fit(f.s, f.d, {0.3, Kernel::C2, Polynomial::None});
  const DisplacementField<float> field(m, std::vector<float>(f.verts.begin(), f.verts.end()).data(), 977);
  std::vector<float> out(f.verts.size());
  double t = 0;
  for (auto _ : st) {
    field.apply(t, out.data());
    t = t > 1 ? 0 : t + 0.01;
    benchmark::DoNotOptimize(out.data());
  }
}
void BM_FishMemcpyBaseline(benchmark::State& st) {
  std::vector<float> a(3 * 977, 1.0f), b(3 * 977);
  for (auto _ : st) {
    std::memcpy(b.data(), a.data(), a.size() * sizeof(float));
    benchmark::DoNotOptimize(b.data());
  }
}
}  // namespace

BENCHMARK(BM_FishFit)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FishApply)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FishPlayback)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FishMemcpyBaseline)->Unit(benchmark::kMicrosecond);
