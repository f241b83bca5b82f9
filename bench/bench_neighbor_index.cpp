// Fixed-radius neighbour search: the hashed uniform grid of csrbf::NeighborIndex against a
// variable-depth point octree (the paper's structure, section 4.1) and brute force, on the same
// points and queries. Run: build/bench/bench_core --benchmark_filter=Neighbor
#include "csrbf/neighbor_index.hpp"

#include <benchmark/benchmark.h>

#include <array>
#include <memory>
#include <random>

using csrbf::Vec3;

namespace {

// A bucket point-region octree: leaves hold up to 16 points; a query descends into every child
// whose box intersects the query ball.
class Octree {
 public:
  Octree(const std::vector<Vec3>& pts, double r) : pts_(pts), r_(r) {
    Vec3 lo = pts[0], hi = pts[0];
    for (const auto& p : pts) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    std::vector<std::uint32_t> ids(pts.size());
    for (std::uint32_t i = 0; i < ids.size(); ++i) ids[i] = i;
    const Vec3 c = 0.5 * (lo + hi);
    root_ = build(std::move(ids), c, 0.5 * (hi - lo).maxCoeff() + 1e-12, 0);
  }
  template <class F>
  void query(const Vec3& q, F&& f) const {
    visit(*root_, q, f);
  }

 private:
  struct Node {
    Vec3 center;
    double half = 0;
    std::vector<std::uint32_t> ids;
    std::array<std::unique_ptr<Node>, 8> kids;
    bool leaf = true;
  };
  std::unique_ptr<Node> build(std::vector<std::uint32_t> ids, const Vec3& c, double half, int depth) {
    auto n = std::make_unique<Node>();
    n->center = c;
    n->half = half;
    if (ids.size() <= 16 || depth > 20) {
      n->ids = std::move(ids);
      return n;
    }
    n->leaf = false;
    std::array<std::vector<std::uint32_t>, 8> part;
    for (auto i : ids) {
      const Vec3& p = pts_[i];
      part[(p.x() > c.x()) | ((p.y() > c.y()) << 1) | ((p.z() > c.z()) << 2)].push_back(i);
    }
    for (int k = 0; k < 8; ++k) {
      if (part[k].empty()) continue;
      const Vec3 cc = c + 0.5 * half * Vec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
      n->kids[k] = build(std::move(part[k]), cc, 0.5 * half, depth + 1);
    }
    return n;
  }
  template <class F>
  void visit(const Node& n, const Vec3& q, F& f) const {
    const Vec3 d = ((q - n.center).cwiseAbs().array() - n.half).cwiseMax(0.0);
    if (d.squaredNorm() >= r_ * r_) return;
    if (n.leaf) {
      for (auto i : n.ids) {
        const double d2 = (pts_[i] - q).squaredNorm();
        if (d2 < r_ * r_) f(i, d2);
      }
      return;
    }
    for (const auto& k : n.kids)
      if (k) visit(*k, q, f);
  }
  const std::vector<Vec3>& pts_;
  double r_;
  std::unique_ptr<Node> root_;
};

struct Data {
  std::vector<Vec3> pts, queries;
  double r;
};
Data make(std::size_t n) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(0, 1);
  Data d;
  d.pts.resize(n);
  for (auto& p : d.pts) p = Vec3(u(rng), u(rng), u(rng));
  d.queries.resize(10000);
  for (auto& p : d.queries) p = Vec3(u(rng), u(rng), u(rng));
  d.r = std::cbrt(25.0 / (4.18879 * double(n)));  // about 25 neighbours per query
  return d;
}

void BM_NeighborGrid(benchmark::State& st) {
  const Data d = make(std::size_t(st.range(0)));
  const csrbf::NeighborIndex index(d.pts, d.r);
  for (auto _ : st) {
    double acc = 0;
    for (const auto& q : d.queries) index.for_each_within(q, [&](std::size_t, double d2) { acc += d2; });
    benchmark::DoNotOptimize(acc);
  }
  st.SetItemsProcessed(std::int64_t(st.iterations()) * std::int64_t(d.queries.size()));
}
void BM_NeighborOctree(benchmark::State& st) {
  const Data d = make(std::size_t(st.range(0)));
  const Octree tree(d.pts, d.r);
  for (auto _ : st) {
    double acc = 0;
    for (const auto& q : d.queries) tree.query(q, [&](std::uint32_t, double d2) { acc += d2; });
    benchmark::DoNotOptimize(acc);
  }
  st.SetItemsProcessed(std::int64_t(st.iterations()) * std::int64_t(d.queries.size()));
}
void BM_NeighborBruteForce(benchmark::State& st) {
  const Data d = make(std::size_t(st.range(0)));
  for (auto _ : st) {
    double acc = 0;
    for (const auto& q : d.queries)
      for (const auto& p : d.pts) {
        const double d2 = (p - q).squaredNorm();
        if (d2 < d.r * d.r) acc += d2;
      }
    benchmark::DoNotOptimize(acc);
  }
  st.SetItemsProcessed(std::int64_t(st.iterations()) * std::int64_t(d.queries.size()));
}
void BM_NeighborGridBuild(benchmark::State& st) {
  const Data d = make(std::size_t(st.range(0)));
  for (auto _ : st) benchmark::DoNotOptimize(csrbf::NeighborIndex(d.pts, d.r));
}
void BM_NeighborOctreeBuild(benchmark::State& st) {
  const Data d = make(std::size_t(st.range(0)));
  for (auto _ : st) benchmark::DoNotOptimize(Octree(d.pts, d.r));
}

}  // namespace

BENCHMARK(BM_NeighborGrid)->Arg(100)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NeighborOctree)->Arg(100)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NeighborBruteForce)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NeighborGridBuild)->Arg(1000)->Arg(100000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NeighborOctreeBuild)->Arg(1000)->Arg(100000)->Unit(benchmark::kMicrosecond);
