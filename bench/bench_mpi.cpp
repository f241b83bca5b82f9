// Strong and weak scaling of csrbf::mpi (docs/DISTRIBUTED.md): the distributed fit of N controls and
// the evaluation of M points, under mpirun -np K. Each rank makes only its own share: the unit cube
// is cut into K slabs along x, and rank r draws its controls (at random) and points (a lattice) in
// slab r (seeded by r), so no rank ever holds the whole set. One JSON line from rank 0: medians over --repeat runs of
// the slowest rank's fit and evaluation, each rank's peak memory and halo, and at K = 1 the serial SpaceMap (what csrbf
// runs without mpirun) in the same process, as the baseline.
//
//   mpirun -np K build/bin/bench_mpi --controls 1e5 --points 1e7 [--neighbours 20] [--repeat 3]
//       [--weak] [--threads 1] [--solver auto|mumps|cg] [--order coherent|random]
//
// --weak: N and M are per rank (the totals grow with K). --threads: TBB threads per rank (1: the
// ranks alone make the parallelism, as on a cluster of single-core ranks). --order: the points in
// a mesh's order (coherent: a jittered lattice numbered as a structured mesh is, x fastest; the
// default) or in no order at all (random: the evaluation then gathers them by cell first, which
// costs memory and time: docs/PERFORMANCE.md).
#include "csrbf/mpi/distributed.hpp"
#include "csrbf/mpi/runtime.hpp"
#include "csrbf/space_map.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

using namespace csrbf;

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

double slowest(double t) {
  double out = 0;
  MPI_Allreduce(&t, &out, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return out;
}

Vec3 field(const Vec3& s) {
  return Vec3(0.02 * std::sin(6 * s.y()), 0.015 * std::cos(5 * s.z()), 0.01 * std::sin(4 * s.x()));
}

}  // namespace

int main(int argc, char** argv) {
  mpi::Runtime rt(&argc, &argv);
  double n_arg = 1e5, m_arg = 1e6, neighbours = 20;
  int repeat = 3, threads = 1;
  bool weak = false, coherent = true;
  std::string solver_name = "auto";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&] {
      if (i + 1 >= argc) {
        if (rt.rank() == 0) std::cerr << "bench_mpi: " << a << " needs a value\n";
        MPI_Abort(MPI_COMM_WORLD, 2);
      }
      return std::string(argv[++i]);
    };
    if (a == "--controls")
      n_arg = std::stod(next());
    else if (a == "--points")
      m_arg = std::stod(next());
    else if (a == "--neighbours")
      neighbours = std::stod(next());
    else if (a == "--repeat")
      repeat = std::stoi(next());
    else if (a == "--threads")
      threads = std::stoi(next());
    else if (a == "--solver")
      solver_name = next();
    else if (a == "--weak")
      weak = true;
    else if (a == "--order") {
      const std::string v = next();
      if (v != "coherent" && v != "random") {
        if (rt.rank() == 0) std::cerr << "bench_mpi: --order coherent or random\n";
        MPI_Abort(MPI_COMM_WORLD, 2);
      }
      coherent = v == "coherent";
    } else {
      if (rt.rank() == 0) std::cerr << "bench_mpi: unknown option " << a << "\n";
      MPI_Abort(MPI_COMM_WORLD, 2);
    }
  }
  const auto solver = mpi::parse_distributed_solver(solver_name);
  if (!solver || repeat < 1 || threads < 1) {
    if (rt.rank() == 0) std::cerr << "bench_mpi: bad --solver, --repeat or --threads\n";
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
  const int k = rt.size(), r = rt.rank();
  const std::size_t n_total = std::size_t(weak ? n_arg * k : n_arg), m_total = std::size_t(weak ? m_arg * k : m_arg);
  // This rank's share: slab r of the unit cube, an even split of the totals.
  const std::size_t n = n_total / std::size_t(k) + (std::size_t(r) < n_total % std::size_t(k) ? 1 : 0);
  const std::size_t m = m_total / std::size_t(k) + (std::size_t(r) < m_total % std::size_t(k) ? 1 : 0);
  std::mt19937_64 rng(20261202 + std::uint64_t(r));
  std::uniform_real_distribution<double> u(0, 1), slab(double(r) / k, double(r + 1) / k);
  std::vector<Vec3> s(n), d(n), x(m), out(m);
  for (auto& p : s) p = Vec3(slab(rng), u(rng), u(rng));
  for (std::size_t i = 0; i < n; ++i) d[i] = s[i] + field(s[i]);
  {
    // The points: a jittered lattice over the slab, numbered as a structured mesh is (x fastest,
    // neighbours 1/M^(1/3) apart: far closer than R), or shuffled (--order random).
    const double width = 1.0 / k, spacing = std::cbrt(width / double(std::max<std::size_t>(m, 1)));
    const auto nx = std::size_t(std::max(1.0, std::round(width / spacing)));
    const auto ny = std::size_t(std::max(1.0, std::round(1.0 / spacing)));
    const std::size_t nz = (m + nx * ny - 1) / (nx * ny);
    std::uniform_real_distribution<double> jitter(-0.25, 0.25);
    for (std::size_t i = 0; i < m; ++i) {
      const std::size_t a = i % nx, b = (i / nx) % ny, c = i / (nx * ny);
      x[i] = Vec3(double(r) / k + (double(a) + 0.5 + jitter(rng)) * width / double(nx),
                  (double(b) + 0.5 + jitter(rng)) / double(ny), (double(c) + 0.5 + jitter(rng)) / double(nz));
    }
    if (!coherent) std::shuffle(x.begin(), x.end(), rng);
  }
  FitOptions o;
  o.radius = std::cbrt(3.0 * neighbours / (4.0 * std::numbers::pi * double(n_total)));
  o.memory_limit_bytes = 64.0 * (1ull << 30);
  std::vector<double> fit_s, eval_s;
  std::vector<mpi::RankStats> stats(static_cast<std::size_t>(k));
  mpi::DistributedStats dstats;
  for (int rep = 0; rep < repeat; ++rep) {
    MPI_Barrier(MPI_COMM_WORLD);
    double t0 = now();
    mpi::DistributedMap map = mpi::DistributedMap::fit(MPI_COMM_WORLD, s, d, o, *solver);
    fit_s.push_back(slowest(now() - t0));
    MPI_Barrier(MPI_COMM_WORLD);
    t0 = now();
    map.apply(x, out, 1.0);
    eval_s.push_back(slowest(now() - t0));
    mpi::RankStats mine = map.rank_stats();
    mine.peak_bytes = mpi::peak_memory_bytes();
    MPI_Gather(&mine, int(sizeof mine), MPI_BYTE, stats.data(), int(sizeof mine), MPI_BYTE, 0, MPI_COMM_WORLD);
    dstats = map.stats();
  }
  // At one rank: the serial program's fit and evaluation of the same set, in this process.
  double serial_fit = 0, serial_eval = 0;
  if (k == 1) {
    std::vector<double> f, e;
    for (int rep = 0; rep < repeat; ++rep) {
      double t0 = now();
      const SpaceMap map = SpaceMap::fit(s, d, o);
      f.push_back(now() - t0);
      t0 = now();
      map.apply(x, out, 1.0);
      e.push_back(now() - t0);
    }
    serial_fit = median(f);
    serial_eval = median(e);
  }
  if (r == 0) {
    std::printf(
        "{\"ranks\": %d, \"threads_per_rank\": %d, \"weak\": %s, \"order\": \"%s\", \"controls\": %zu, \"points\": "
        "%zu, "
        "\"radius\": %.6g, \"solver\": \"%s\", \"iterations\": %zu, \"fit_s\": %.4f, \"evaluate_s\": %.4f",
        k, threads, weak ? "true" : "false", coherent ? "coherent" : "random", n_total, m_total, o.radius,
        mpi::distributed_solver_name(dstats.solver).c_str(), dstats.iterations, median(fit_s), median(eval_s));
    if (k == 1) std::printf(", \"serial_fit_s\": %.4f, \"serial_evaluate_s\": %.4f", serial_fit, serial_eval);
    std::printf(", \"per_rank\": [");
    for (int q = 0; q < k; ++q) {
      const auto& st = stats[std::size_t(q)];
      std::printf(
          "%s{\"rank\": %d, \"controls\": %zu, \"halo\": %zu, \"eval_halo\": %zu, \"points\": %zu, "
          "\"peak_mib\": %.1f, \"sent_mib\": %.2f, \"assembly_s\": %.3f, \"solve_s\": %.3f}",
          q ? ", " : "", q, st.controls_owned, st.controls_halo, st.eval_halo, st.points,
          double(st.peak_bytes) / double(1 << 20), double(st.bytes_sent) / double(1 << 20), st.seconds_assembly,
          st.seconds_solve);
    }
    std::printf("]}\n");
  }
  return 0;
}
