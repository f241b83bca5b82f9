#include "bench.hpp"
#include "commands.hpp"
#include "fit_input.hpp"

#include "csrbf/anim/scene.hpp"

#include "csrbf/displacement_field.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/space_map.hpp"

#include <Eigen/LU>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#ifdef CSRBF_HAVE_VTK
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkThinPlateSplineTransform.h>
#endif

#include <algorithm>
#include <random>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <sstream>
#include <stdexcept>

#ifndef CSRBF_EXAMPLES_DIR
#define CSRBF_EXAMPLES_DIR "examples"
#endif

namespace csrbf::cli {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

double us_since(Clock::time_point t0) { return std::chrono::duration<double, std::micro>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(m), v.end());
  const double hi = v[m];
  if (v.size() % 2) return hi;
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + std::ptrdiff_t(m)));
}

/// Median time of f in microseconds. Calls are batched so that one sample lasts at least 20 us (the
/// clock's resolution stays below 0.5%); at least min_samples samples, then more for `seconds`.
template <class F>
double median_us(F&& f, double seconds, int min_samples = 7) {
  auto t0 = Clock::now();
  f();  // warm-up: caches, pages, TBB's threads
  const double once = us_since(t0);
  const int batch = once >= 20.0 ? 1 : int(std::ceil(20.0 / std::max(once, 0.01)));
  std::vector<double> samples;
  const auto start = Clock::now();
  while (int(samples.size()) < min_samples || (us_since(start) < seconds * 1e6 && samples.size() < 200000)) {
    t0 = Clock::now();
    for (int b = 0; b < batch; ++b) f();
    samples.push_back(us_since(t0) / batch);
  }
  return median(std::move(samples));
}

/// Median of each phase of FitStats over several fits (microseconds).
struct PhaseMedians {
  std::vector<double> index, graph, ordering, assembly, factorization, solve, residual;
  void add(const FitStats& s) {
    index.push_back(s.seconds_index * 1e6);
    graph.push_back(s.seconds_graph * 1e6);
    ordering.push_back(s.seconds_ordering * 1e6);
    assembly.push_back(s.seconds_assembly * 1e6);
    factorization.push_back(s.seconds_factorization * 1e6);
    solve.push_back(s.seconds_solve * 1e6);
    residual.push_back(s.seconds_residual * 1e6);
  }
  void write(json& row) const {
    row["index_us"] = median(index);
    row["graph_us"] = median(graph);
    row["ordering_us"] = median(ordering);
    row["assembly_us"] = median(assembly);
    row["factorization_us"] = median(factorization);
    row["solve_us"] = median(solve);
    row["residual_us"] = median(residual);
  }
};

std::vector<double> interleave(std::span<const Vec3> p) {
  std::vector<double> out(3 * p.size());
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int k = 0; k < 3; ++k) out[3 * i + std::size_t(k)] = p[i][k];
  return out;
}

/// n points spread evenly over the unit sphere (Fibonacci lattice), deterministic.
std::vector<Vec3> sphere_points(std::size_t n, double offset = 0.0) {
  std::vector<Vec3> p(n);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double y = 1.0 - 2.0 * (double(i) + 0.5) / double(n);
    const double r = std::sqrt(std::max(0.0, 1.0 - y * y));
    const double a = golden * double(i) + offset;
    p[i] = Vec3(r * std::cos(a), y, r * std::sin(a));
  }
  return p;
}

/// About m vertices over the unit sphere in the order a mesh stores them: ring by ring (latitude),
/// around each ring (longitude), so that consecutive vertices are neighbours in space.
std::vector<Vec3> sphere_mesh_points(std::size_t m) {
  const auto rings = std::size_t(std::max(2.0, std::round(std::sqrt(double(m) * M_PI / 4.0))));
  std::vector<Vec3> p;
  p.reserve(m);
  double total = 0;
  for (std::size_t r = 0; r < rings; ++r) total += std::sin(M_PI * (double(r) + 0.5) / double(rings));
  std::size_t placed = 0;
  for (std::size_t r = 0; r < rings; ++r) {
    const double theta = M_PI * (double(r) + 0.5) / double(rings);
    const std::size_t want = r + 1 == rings ? m - placed : std::size_t(std::round(double(m) * std::sin(theta) / total));
    for (std::size_t k = 0; k < want && placed < m; ++k, ++placed) {
      const double phi = 2 * M_PI * (double(k) + 0.5 * double(r % 2)) / double(want);
      p.emplace_back(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
    }
  }
  return p;
}

/// Destinations for controls on the unit sphere: a smooth field of bumps along the normal.
std::vector<Vec3> sphere_destinations(std::span<const Vec3> s, double amplitude) {
  std::vector<Vec3> d(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    d[i] = s[i] * (1.0 + amplitude * std::sin(5 * s[i].x()) * std::cos(4 * s[i].y()) * std::sin(3 * s[i].z() + 1));
  return d;
}

/// R for about `neighbours` other controls within R of each of n controls on the unit sphere:
/// a cap of chord R holds the fraction R^2 / 4 of the sphere.
double sphere_radius(std::size_t n, double neighbours = 25.0) { return std::sqrt(4.0 * neighbours / double(n)); }

class Printer {
 public:
  explicit Printer(bool json_lines) : json_(json_lines) {}
  void row(json r) const {
    if (r.value("scenario", std::string()) != "solvers") r["loop"] = std::string(evaluation_loop_name());
    if (json_) {
      std::cout << r.dump() << std::endl;
      return;
    }
    std::ostringstream os;
    os << std::left << std::setw(8) << r.value("scenario", std::string());
    for (const auto& [key, value] : r.items()) {
      if (key == "scenario") continue;
      os << "  " << key << "=";
      if (value.is_number_float()) {
        const double v = value.get<double>();
        os << std::setprecision(v >= 100  ? 0
                                : v >= 10 ? 1
                                          : 3)
           << std::fixed << v << std::defaultfloat << std::setprecision(6);
      } else if (value.is_string()) {
        os << value.get<std::string>();
      } else {
        os << value.dump();
      }
    }
    std::cout << os.str() << std::endl;
  }

 private:
  bool json_;
};

struct ThreadLimit {
  explicit ThreadLimit(int n) : control(tbb::global_control::max_allowed_parallelism, std::size_t(std::max(n, 1))) {}
  tbb::global_control control;
};

int all_threads() { return tbb::info::default_concurrency(); }

// ---------------------------------------------------------------------------------------------------
// fish, face: a bundled mesh and its controls; fit, full evaluation, playback, one thread.

void mesh_scenario(const BenchOptions& o, const Printer& out, const std::string& name, double radius) {
  const std::filesystem::path dir =
      o.data_dir.empty() ? std::filesystem::path(CSRBF_EXAMPLES_DIR) : std::filesystem::path(o.data_dir);
  const auto mesh = io::MeshDocument::load(dir / (name + ".obj"));
  const auto controls = io::read_controls((dir / (name + ".controls")).string());
  const int threads = o.threads > 0 ? o.threads : 1;
  ThreadLimit limit(threads);
  const FitOptions fo{radius, Kernel::C2, Polynomial::None};
  PhaseMedians phases;
  const double fit_us = median_us(
      [&] {
        const SpaceMap m = SpaceMap::fit(controls.sources, controls.destinations, fo);
        phases.add(m.stats());
      },
      o.seconds);
  const SpaceMap map = SpaceMap::fit(controls.sources, controls.destinations, fo);
  const std::size_t n = mesh.positions().size();
  const std::vector<double> xyz = interleave(mesh.positions());
  const std::vector<float> xyzf(xyz.begin(), xyz.end());
  std::vector<double> outd(xyz.size());
  std::vector<float> outf(xyz.size());
  double t = 0.5;
  const double eval_float_us = median_us([&] { map.apply(xyzf.data(), outf.data(), n, t); }, o.seconds);
  const double eval_double_us = median_us([&] { map.apply(xyz.data(), outd.data(), n, t); }, o.seconds);
  const DisplacementField<float> field(map, xyzf.data(), n);
  const double playback_us = median_us(
      [&] {
        field.apply(t, outf.data());
        t = t >= 1.0 ? 0.0 : t + 1.0 / 64;
      },
      o.seconds);
  std::vector<float> copy(xyzf.size());
  const double memcpy_us = median_us(
      [&] {
        std::memcpy(copy.data(), xyzf.data(), xyzf.size() * sizeof(float));
        asm volatile("" : : "r"(copy.data()) : "memory");
      },
      o.seconds);
  // The float path's accuracy against the double path on this mesh (phase 1).
  map.apply(xyz.data(), outd.data(), n, 1.0);
  map.apply(xyzf.data(), outf.data(), n, 1.0);
  double float_error = 0;
  for (std::size_t i = 0; i < xyz.size(); ++i) float_error = std::max(float_error, std::abs(double(outf[i]) - outd[i]));
  json row{{"scenario", name},
           {"vertices", n},
           {"controls", map.size()},
           {"radius", radius},
           {"threads", threads},
           {"solver", std::string(solver_name(map.stats().solver))},
           {"fit_us", fit_us},
           {"eval_us", eval_float_us},
           {"eval_double_us", eval_double_us},
           {"playback_us", playback_us},
           {"memcpy_us", memcpy_us},
           {"playback_memcpy_ratio", playback_us / memcpy_us},
           {"float_max_error", float_error}};
  phases.write(row);
  out.row(row);
}

// ---------------------------------------------------------------------------------------------------
// ball: a 386-vertex box (8 x 8 quads a face, 768 triangles) dented by a bouncing sphere; the controls
// change every frame, so every frame is a full recompute.

std::vector<Vec3> box_vertices(int seg) {
  std::vector<Vec3> v;
  for (int z = 0; z <= seg; ++z)
    for (int y = 0; y <= seg; ++y)
      for (int x = 0; x <= seg; ++x)
        if (x == 0 || y == 0 || z == 0 || x == seg || y == seg || z == seg)
          v.emplace_back(double(x) / seg, double(y) / seg, double(z) / seg);
  return v;
}

/// Triangle wave in [-1, 1] with period 1.
double tri(double t) {
  const double f = t - std::floor(t);
  return f < 0.5 ? 4 * f - 1 : 3 - 4 * f;
}

/// The controls of frame f: the sphere (radius 0.2) on its path, pressing on the walls it comes within
/// its radius of (anim::contact_controls, the `contact` deformation of examples/ball.scene.json).
void ball_controls(int frame, std::vector<Vec3>& s, std::vector<Vec3>& d) {
  const double t = frame / 240.0, rb = 0.2;
  const Vec3 centre = Vec3(0.5, 0.5, 0.5) + 0.36 * Vec3(tri(1.0 * t), tri(1.3 * t + 0.2), tri(0.7 * t + 0.4));
  anim::contact_controls(Vec3::Zero(), Vec3::Ones(), centre, rb, 0.6, s, d);
}

void ball_scenario(const BenchOptions& o, const Printer& out) {
  const int threads = o.threads > 0 ? o.threads : 1;
  ThreadLimit limit(threads);
  const std::vector<Vec3> box = box_vertices(8);
  const std::vector<float> rest = [&] {
    std::vector<float> r;
    for (const auto& p : box) r.insert(r.end(), {float(p.x()), float(p.y()), float(p.z())});
    return r;
  }();
  std::vector<float> frame_out(rest.size());
  const double radius = 0.4;
  const FitOptions fo{radius, Kernel::C2, Polynomial::None};
  constexpr int frames = 240;
  std::vector<std::vector<Vec3>> src(frames), dst(frames);
  std::size_t min_c = SIZE_MAX, max_c = 0, dented = 0;
  for (int f = 0; f < frames; ++f) {
    ball_controls(f, src[std::size_t(f)], dst[std::size_t(f)]);
    min_c = std::min(min_c, src[std::size_t(f)].size());
    max_c = std::max(max_c, src[std::size_t(f)].size());
    dented += src[std::size_t(f)].size() > 8;
  }
  int f = 0;
  std::vector<double> fit_t, eval_t;
  const double recompute_us = median_us(
      [&] {
        const auto t0 = Clock::now();
        const SpaceMap m = SpaceMap::fit(src[std::size_t(f)], dst[std::size_t(f)], fo);
        const auto t1 = Clock::now();
        m.apply(rest.data(), frame_out.data(), box.size(), 1.0);
        fit_t.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
        eval_t.push_back(us_since(t1));
        f = (f + 1) % frames;
      },
      o.seconds, 2 * frames);
  out.row(json{{"scenario", "ball"},
               {"vertices", box.size()},
               {"controls", std::to_string(min_c) + "-" + std::to_string(max_c)},
               {"radius", radius},
               {"threads", threads},
               {"frames", frames},
               {"frames_dented", dented},
               {"recompute_us", recompute_us},
               {"fit_us", median(fit_t)},
               {"eval_us", median(eval_t)},
               {"fps_compute", 1e6 / recompute_us}});
}

// ---------------------------------------------------------------------------------------------------
// scale: controls and vertices on the unit sphere, ~25 neighbours a control, sweeps of M and N.

struct SweepPoint {
  std::size_t m, n;
  const char* sweep;
};

void scale_row(const BenchOptions& o, const Printer& out, const SweepPoint& p) {
  const int threads = o.threads > 0 ? o.threads : all_threads();
  const std::vector<Vec3> s = sphere_points(p.n);
  const std::vector<Vec3> d = sphere_destinations(s, 0.02);
  const double radius = sphere_radius(p.n);
  const FitOptions fo{radius, Kernel::C2, Polynomial::None};
  PhaseMedians phases;
  const bool big = p.n >= 100000 || p.m >= 10000000;
  const double seconds = big ? 0.0 : o.seconds;
  const int reps = p.n >= 100000 ? 3 : p.m >= 10000000 ? 3 : 5;
  std::optional<SpaceMap> map;
  double fit_us = 0;
  {
    ThreadLimit limit(threads);
    fit_us = median_us(
        [&] {
          map = SpaceMap::fit(s, d, fo);
          phases.add(map->stats());
        },
        seconds, reps);
  }
  const std::vector<double> xyz = interleave(sphere_mesh_points(p.m));
  const std::vector<float> xyzf(xyz.begin(), xyz.end());
  std::vector<double> outd(xyz.size());
  std::vector<float> outf(xyz.size());
  double eval_1t = 0, eval_nt = 0, eval_float_nt = 0, playback = 0, memcpy_us = 0;
  {
    ThreadLimit limit(1);
    eval_1t = median_us([&] { map->apply(xyz.data(), outd.data(), p.m, 0.5); }, seconds, reps);
  }
  ThreadLimit limit(threads);
  // The same points in a random order (a point cloud, a renumbered mesh), timed in the same run.
  std::vector<double> shuffled(xyz.size());
  {
    std::vector<std::size_t> perm(p.m);
    for (std::size_t i = 0; i < p.m; ++i) perm[i] = i;
    std::shuffle(perm.begin(), perm.end(), std::mt19937_64(20261201));
    for (std::size_t i = 0; i < p.m; ++i)
      for (int c = 0; c < 3; ++c) shuffled[3 * i + c] = xyz[3 * perm[i] + c];
  }
  const std::vector<float> shuffledf(shuffled.begin(), shuffled.end());
  double eval_random = 0, eval_random_float = 0;
  // Interleaved, so that a noisy spell of the shared machine hits both orders alike.
  for (int round = 0; round < 2; ++round) {
    eval_nt = median_us([&] { map->apply(xyz.data(), outd.data(), p.m, 0.5); }, seconds, reps);
    eval_random = median_us([&] { map->apply(shuffled.data(), outd.data(), p.m, 0.5); }, seconds, reps);
  }
  eval_float_nt = median_us([&] { map->apply(xyzf.data(), outf.data(), p.m, 0.5); }, seconds, reps);
  eval_random_float = median_us([&] { map->apply(shuffledf.data(), outf.data(), p.m, 0.5); }, seconds, reps);
  const DisplacementField<float> field(*map, xyzf.data(), p.m);
  double t = 0.25;
  playback = median_us(
      [&] {
        field.apply(t, outf.data());
        t = t >= 1.0 ? 0.0 : t + 1.0 / 64;
      },
      seconds, 2 * reps);
  std::vector<float> copy(xyzf.size());
  memcpy_us = median_us(
      [&] {
        std::memcpy(copy.data(), xyzf.data(), xyzf.size() * sizeof(float));
        asm volatile("" : : "r"(copy.data()) : "memory");
      },
      seconds, 2 * reps);
  // Mean number of controls within R of a vertex.
  std::size_t hits = 0;
  const std::size_t probe = std::min<std::size_t>(p.m, 2000);
  for (std::size_t i = 0; i < probe; ++i)
    map->index().for_each_within(Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]),
                                 [&](std::size_t, double) { ++hits; });
  json row{{"scenario", "scale"},
           {"sweep", p.sweep},
           {"vertices", p.m},
           {"controls", p.n},
           {"radius", radius},
           {"threads", threads},
           {"mean_neighbors", map->stats().mean_neighbors},
           {"vertex_neighbors", double(hits) / double(probe)},
           {"solver", std::string(solver_name(map->stats().solver))},
           {"fit_us", fit_us},
           {"eval_us", eval_nt},
           {"eval_1thread_us", eval_1t},
           {"eval_float_us", eval_float_nt},
           {"eval_random_us", eval_random},
           {"eval_random_float_us", eval_random_float},
           {"random_ratio", eval_random / eval_nt},
           {"random_float_ratio", eval_random_float / eval_float_nt},
           {"playback_us", playback},
           {"memcpy_us", memcpy_us},
           {"playback_memcpy_ratio", playback / memcpy_us}};
  phases.write(row);
  out.row(row);
}

void scale_scenario(const BenchOptions& o, const Printer& out) {
  std::vector<SweepPoint> points;
  if (o.quick) {
    for (std::size_t m : {1000, 10000, 100000}) points.push_back({m, 1000, "M"});
    for (std::size_t n : {100, 10000}) points.push_back({100000, n, "N"});
  } else {
    for (std::size_t m : {1000, 10000, 100000, 1000000, 10000000}) points.push_back({m, 10000, "M"});
    for (std::size_t n : {100, 1000, 100000}) points.push_back({1000000, n, "N"});
  }
  for (const auto& p : points) scale_row(o, out, p);
}

// ---------------------------------------------------------------------------------------------------
// solvers: whole fits of the same systems by every back end, in one run: on the unit sphere (a
// surface, as controls on a model are) and in the unit cube (a volume: a CFD mesh's points), at about
// 25 and 100 neighbours a control, N = 1e3 ... 1e6 (1e3 and 1e4 with --quick). Auto is compared with
// the fastest back end of its row (auto_over_best). A back end is left out where it would take
// minutes: the envelope past 1.5e11 multiply-adds (known before it starts), Eigen's simplicial
// Cholesky past 2e6 neighbour entries, CHOLMOD at N = 1e6; a fit refused by the memory limit is
// reported as such.

/// n seeded random points in the unit cube (in no spatial order, as a mesh's points often come).
std::vector<Vec3> cube_points(std::size_t n) {
  std::mt19937_64 rng(20261201);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> p(n);
  for (auto& x : p) x = Vec3(u(rng), u(rng), u(rng));
  return p;
}

/// A smooth displacement of points in the unit cube, 2% of its side at most.
std::vector<Vec3> cube_destinations(std::span<const Vec3> s) {
  std::vector<Vec3> d(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    d[i] = s[i] + 0.02 * Vec3(std::sin(5 * s[i].y()), std::cos(4 * s[i].z()), std::sin(3 * s[i].x() + 1));
  return d;
}

/// R for about `neighbours` other points within R of each of n points in the unit cube.
double cube_radius(std::size_t n, double neighbours) { return std::cbrt(3.0 * neighbours / (4.0 * M_PI * double(n))); }

/// The envelope factorisation's work for these sources in reverse Cuthill-McKee order (what Auto
/// weighs), from the neighbour graph alone: no factorisation.
double envelope_work_of(std::span<const Vec3> s, double radius) {
  const AdjacencyGraph g = AdjacencyGraph::from_index(NeighborIndex(s, radius), s);
  return envelope_work(envelope_first_columns(g, reverse_cuthill_mckee_order(g)));
}

void solvers_scenario(const BenchOptions& o, const Printer& out) {
  std::vector<std::size_t> sizes{1000, 10000};
  if (!o.quick) sizes.insert(sizes.end(), {100000, 1000000});
  if (!o.controls.empty()) sizes.assign(o.controls.begin(), o.controls.end());
  const int threads = o.threads > 0 ? o.threads : int(tbb::info::default_concurrency());
  ThreadLimit limit(threads);
  for (const std::string geometry : {"sphere", "cube"})
    for (const double neighbours : {25.0, 100.0})
      for (std::size_t n : sizes) {
        if (!o.geometry.empty() && geometry != o.geometry) continue;
        // In the cube at 100 neighbours N = 1e6 takes hours by every back end: left out.
        if (geometry == "cube" && neighbours > 50 && n >= 1000000) continue;
        const bool sphere = geometry == "sphere";
        const std::vector<Vec3> s = sphere ? sphere_points(n) : cube_points(n);
        const std::vector<Vec3> d = sphere ? sphere_destinations(s, 0.02) : cube_destinations(s);
        const double radius = sphere ? sphere_radius(n, neighbours) : cube_radius(n, neighbours);
        json row{
            {"scenario", "solvers"}, {"geometry", geometry}, {"controls", n}, {"radius", radius}, {"threads", threads}};
        const int reps = n >= 1000000 ? 1 : n >= 100000 ? 3 : 5;
        // The back ends take turns, repetition by repetition, after a round that is not counted
        // (below 1e5): the first fits of a process pay for fresh pages and threads, and a machine's
        // slow spell falls on all of them alike. Medians of 5 (N < 1e5), 3 (1e5), 1 (1e6).
        std::vector<Solver> run;
        for (Solver solver : {Solver::Envelope, Solver::Eigen, Solver::Cholmod, Solver::Cg, Solver::Auto}) {
          const std::string name(solver_name(solver));
          bool left_out = (solver == Solver::Cholmod && (!cholmod_available() || n >= 1000000)) ||
                          (solver == Solver::Eigen && double(n) * neighbours > 2e6);
          if (solver == Solver::Envelope) {
            const double work = envelope_work_of(s, radius);
            row["envelope_work"] = work;
            left_out = work > 1.5e11;
          }
          if (left_out)
            row[name + "_fit_us"] = nullptr;
          else
            run.push_back(solver);
        }
        std::map<Solver, std::vector<double>> times;
        for (int r = n < 100000 ? -1 : 0; r < reps; ++r)
          for (std::size_t j = 0; j < run.size(); ++j) {
            // Each repetition runs the back ends in another (seeded) order: the fit right after CG
            // pays for fresh pages (1.5 ms of 4 at N = 1e3), and a rotation would keep that place
            // for the same back end.
            if (j == 0) std::shuffle(run.begin(), run.end(), std::mt19937(unsigned(r + 2)));
            const Solver solver = run[j];
            if (row.contains(std::string(solver_name(solver)) + "_fit_us")) continue;  // refused
            FitOptions fo{radius, Kernel::C2, Polynomial::None};
            fo.solver = solver;
            try {
              const auto t0 = Clock::now();
              const SpaceMap m = SpaceMap::fit(s, d, fo);
              if (r >= 0) times[solver].push_back(us_since(t0));
              row["mean_neighbors"] = m.stats().mean_neighbors;
              if (solver == Solver::Cg) row["cg_steps"] = m.stats().iterations;
              if (solver == Solver::Auto)
                row["auto_solver"] =
                    std::string(solver_name(m.stats().solver)) + (m.stats().fell_back ? "-after-cg" : "");
            } catch (const ResourceLimit&) {
              row[std::string(solver_name(solver)) + "_fit_us"] = "memory limit";
            }
          }
        std::map<std::string, double> fit_us;
        for (auto& [solver, total] : times) {
          const std::string name(solver_name(solver));
          row[name + "_fit_us"] = median(total);
          if (solver != Solver::Auto) fit_us[name] = median(total);
        }
        double best = INFINITY;
        std::string best_name;
        for (const auto& [name, v] : fit_us)
          if (v < best) best = v, best_name = name;
        row["best"] = best_name;
        if (row["auto_fit_us"].is_number()) row["auto_over_best"] = row["auto_fit_us"].get<double>() / best;
        out.row(row);
      }
}

// ---------------------------------------------------------------------------------------------------
// peers: the same interpolation problem through VTK's thin-plate spline and a dense solve.

void peers_scenario(const BenchOptions& o, const Printer& out) {
#ifndef CSRBF_HAVE_VTK
  (void)o;
  (void)out;
  throw csrbf::Error("scenario 'peers' needs VTK: this csrbf was built without it (install libvtk9-dev)");
#else
  const std::size_t n = o.quick ? 200 : 1000, m = o.quick ? 20000 : 1000000;
  const std::vector<Vec3> s = sphere_points(n);
  const std::vector<Vec3> d = sphere_destinations(s, 0.02);
  const double radius = sphere_radius(n);
  const std::vector<double> xyz = interleave(sphere_mesh_points(m));
  std::vector<double> ours(xyz.size()), theirs(xyz.size());
  const int threads = o.threads > 0 ? o.threads : all_threads();
  // Ours, with the linear polynomial like the thin-plate spline's affine part.
  const FitOptions fo{radius, Kernel::C2, Polynomial::Linear};
  std::optional<SpaceMap> map;
  double fit_us = 0, eval_1t = 0, eval_nt = 0;
  {
    ThreadLimit limit(1);
    fit_us = median_us([&] { map = SpaceMap::fit(s, d, fo); }, o.seconds);
    eval_1t = median_us([&] { map->apply(xyz.data(), ours.data(), m, 1.0); }, o.seconds, 3);
  }
  {
    ThreadLimit limit(threads);
    eval_nt = median_us([&] { map->apply(xyz.data(), ours.data(), m, 1.0); }, o.seconds, 3);
  }
  // VTK's thin-plate spline (dense: every landmark for every point), single-threaded.
  vtkNew<vtkPoints> src, dst, in, res;
  for (std::size_t i = 0; i < n; ++i) {
    src->InsertNextPoint(s[i].data());
    dst->InsertNextPoint(d[i].data());
  }
  in->SetDataTypeToDouble();
  in->SetNumberOfPoints(vtkIdType(m));
  for (std::size_t i = 0; i < m; ++i) in->SetPoint(vtkIdType(i), &xyz[3 * i]);
  res->SetDataTypeToDouble();
  vtkNew<vtkThinPlateSplineTransform> tps;
  tps->SetBasisToR();
  tps->SetSourceLandmarks(src);
  tps->SetTargetLandmarks(dst);
  const double vtk_fit_us = median_us(
      [&] {
        tps->Modified();
        tps->Update();
      },
      o.seconds, 3);
  auto t0 = Clock::now();
  tps->TransformPoints(in, res);
  const double vtk_eval_us = us_since(t0);
  // The paper's "naive" group: the full (N+4) x (N+4) system of the same CSRBF, solved densely, and
  // evaluated over every control for every point.
  const Eigen::Index nn = Eigen::Index(n);
  t0 = Clock::now();
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(nn + 4, nn + 4);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nn + 4, 3);
  for (Eigen::Index i = 0; i < nn; ++i) {
    for (Eigen::Index j = 0; j < nn; ++j)
      a(i, j) = wendland(Kernel::C2, (s[std::size_t(i)] - s[std::size_t(j)]).norm() / radius);
    a(i, nn) = a(nn, i) = 1.0;
    for (int k = 0; k < 3; ++k) a(i, nn + 1 + k) = a(nn + 1 + k, i) = s[std::size_t(i)][k];
    rhs.row(i) = (d[std::size_t(i)] - s[std::size_t(i)]).transpose();
  }
  const Eigen::MatrixXd coef = a.partialPivLu().solve(rhs);
  const double dense_fit_us = us_since(t0);
  t0 = Clock::now();
  for (std::size_t v = 0; v < m; ++v) {
    const Vec3 x(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]);
    Vec3 acc = coef.row(nn).transpose() + coef.bottomRows(3).transpose() * x;
    for (Eigen::Index i = 0; i < nn; ++i)
      acc += wendland(Kernel::C2, (x - s[std::size_t(i)]).norm() / radius) * coef.row(i).transpose();
    for (int k = 0; k < 3; ++k) theirs[3 * v + std::size_t(k)] = x[k] + acc[k];
  }
  const double dense_eval_us = us_since(t0);
  double dense_diff = 0;
  for (std::size_t i = 0; i < xyz.size(); ++i) dense_diff = std::max(dense_diff, std::abs(theirs[i] - ours[i]));
  out.row(json{{"scenario", "peers"},
               {"vertices", m},
               {"controls", n},
               {"radius", radius},
               {"threads", threads},
               {"fit_us", fit_us},
               {"eval_us", eval_nt},
               {"eval_1thread_us", eval_1t},
               {"vtk_tps_fit_us", vtk_fit_us},
               {"vtk_tps_eval_us", vtk_eval_us},
               {"dense_fit_us", dense_fit_us},
               {"dense_eval_us", dense_eval_us},
               {"ratio_eval_vtk", vtk_eval_us / eval_nt},
               {"ratio_eval_vtk_1thread", vtk_eval_us / eval_1t},
               {"ratio_eval_dense", dense_eval_us / eval_1t},
               {"ratio_fit_vtk", vtk_fit_us / fit_us},
               {"ratio_fit_dense", dense_fit_us / fit_us},
               {"dense_max_difference", dense_diff}});
#endif
}

}  // namespace

const std::vector<std::string>& bench_scenarios() {
  static const std::vector<std::string> names{"fish", "face", "ball", "scale", "solvers", "peers"};
  return names;
}

void run_bench(const BenchOptions& o) {
  if (o.loop == "portable")
    set_evaluation_loop(EvaluationLoop::Portable);
  else if (o.loop == "avx512")
    set_evaluation_loop(EvaluationLoop::Avx512);
  else if (o.loop != "auto")
    throw csrbf::InvalidInput("unknown evaluation loop '" + o.loop + "'");
  const Printer out(o.json);
  const auto run_one = [&](const std::string& name) {
    if (name == "fish")
      mesh_scenario(o, out, "fish", 0.3);
    else if (name == "face")
      mesh_scenario(o, out, "face", 0.2);
    else if (name == "ball")
      ball_scenario(o, out);
    else if (name == "scale")
      scale_scenario(o, out);
    else if (name == "solvers")
      solvers_scenario(o, out);
    else if (name == "peers")
      peers_scenario(o, out);
    else
      throw csrbf::InvalidInput("unknown scenario '" + name + "'");
  };
  if (o.scenario == "all")
    for (const auto& name : bench_scenarios()) run_one(name);
  else
    run_one(o.scenario);
}

CLI::App* add_bench_command(CLI::App& app, BenchOptions& o) {
  auto* bench = app.add_subcommand("bench", kBenchDescription);
  std::vector<std::string> scenario_names = bench_scenarios();
  scenario_names.push_back("all");
  bench->add_option("--scenario,-s", o.scenario, "fish, face, ball, scale, solvers, peers or all")
      ->required()
      ->check(CLI::IsMember(scenario_names));
  bench->add_flag("--json", o.json, "One JSON object a line");
  bench->add_flag("--quick", o.quick, "Smaller sweeps (scale, solvers, peers)");
  bench->add_option("--controls", o.controls, "solvers: only these N (e.g. --controls 1e5), default 1e3 ... 1e6")
      ->check(CLI::Range(10.0, 1e7));
  bench->add_option("--geometry", o.geometry, "solvers: only 'sphere' or 'cube' (default both)")
      ->check(CLI::IsMember({"sphere", "cube"}));
  bench->add_option("--threads", o.threads, "Threads (default: 1 for fish/face/ball, all for scale/solvers/peers)")
      ->check(CLI::Range(1, 1024));
  bench->add_option("--seconds", o.seconds, "Time spent on each measured quantity")
      ->check(finite_in(0.0, 60.0, "--seconds"))
      ->capture_default_str();
  bench->add_option("--loop", o.loop, "Evaluation loop: auto, portable or avx512 (each row names the one used)")
      ->check(CLI::IsMember({"auto", "portable", "avx512"}))
      ->capture_default_str();
  bench->add_option("--data", o.data_dir, "Folder with fish.obj, face.obj and their .controls (default: bundled)");
  return bench;
}

}  // namespace csrbf::cli
