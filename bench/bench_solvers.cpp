// The paper's solver (ordering + Jennings envelope Cholesky, written here) against Eigen's
// SimplicialLLT with AMD ordering, on the same CSRBF matrices (random sources in the unit cube,
// about 25 neighbours each, C2 kernel). Run: build/bench/bench_core --benchmark_filter=Factor
#include "csrbf/envelope_cholesky.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/ordering.hpp"
#include "csrbf/space_map.hpp"

#include <Eigen/SparseCholesky>
#include <benchmark/benchmark.h>

#include <random>

using namespace csrbf;

namespace {

struct Problem {
  std::vector<Vec3> pts;
  double r = 0;
  AdjacencyGraph g;
  std::vector<std::uint32_t> order;
};

Problem make(std::size_t n) {
  Problem p;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  p.pts.resize(n);
  for (auto& x : p.pts) x = Vec3(u(rng), u(rng), u(rng));
  p.r = std::cbrt(25.0 / (4.18879 * double(n)));
  const NeighborIndex index(p.pts, p.r);
  p.g = AdjacencyGraph::from_index(index, p.pts);
  p.order = choose_ordering(p.g, Ordering::Auto).order;
  return p;
}

Eigen::SparseMatrix<double> sparse(const Problem& p) {
  std::vector<Eigen::Triplet<double>> t;
  for (std::size_t i = 0; i < p.pts.size(); ++i) {
    t.emplace_back(int(i), int(i), wendland(Kernel::C2, 0.0));
    const auto nb = p.g.neighbors_of(i);
    const auto d2 = p.g.dist2_of(i);
    for (std::size_t e = 0; e < nb.size(); ++e)
      t.emplace_back(int(i), int(nb[e]), wendland(Kernel::C2, std::sqrt(d2[e]) / p.r));
  }
  Eigen::SparseMatrix<double> m(Eigen::Index(p.pts.size()), Eigen::Index(p.pts.size()));
  m.setFromTriplets(t.begin(), t.end());
  return m;
}

void BM_FactorEnvelope(benchmark::State& st) {
  const Problem p = make(std::size_t(st.range(0)));
  const EnvelopeMatrix a0 = kernel_matrix(p.g, p.order, Kernel::C2, p.r);
  RowMatrix b = RowMatrix::Ones(Eigen::Index(p.pts.size()), 3);
  for (auto _ : st) {
    EnvelopeMatrix a = a0;
    a.cholesky_in_place();
    RowMatrix x = b;
    a.solve_in_place(x);
    benchmark::DoNotOptimize(x.data());
  }
  st.counters["envelope"] = double(a0.envelope_entries());
}
void BM_FactorEigenSimplicialLLT(benchmark::State& st) {
  const Problem p = make(std::size_t(st.range(0)));
  const Eigen::SparseMatrix<double> m = sparse(p);
  const Eigen::MatrixXd b = Eigen::MatrixXd::Ones(m.rows(), 3);
  for (auto _ : st) {
    Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> llt(m);
    Eigen::MatrixXd x = llt.solve(b);
    benchmark::DoNotOptimize(x.data());
  }
}

}  // namespace

BENCHMARK(BM_FactorEnvelope)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FactorEigenSimplicialLLT)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMicrosecond);
