#include "evaluator.hpp"

#include "eval_kernel.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/units.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <sstream>
#include <utility>
#include <type_traits>

// Multi-versioning: an AVX2 clone and a baseline clone of each hot loop, picked at load time, so a
// portable binary still runs the wide loop on machines that have it.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__has_attribute)
#if __has_attribute(target_clones)
#define CSRBF_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#endif
#endif
#ifndef CSRBF_CLONES
#define CSRBF_CLONES
#endif

namespace csrbf::detail {

EvalGrid EvalGrid::build(std::span<const Vec3> sources, double radius, std::size_t max_bytes, int max_subdivision,
                         int dims) {
  EvalGrid g;
  const std::size_t n = sources.size();
  if (n == 0) return g;
  Vec3 lo = sources[0], hi = sources[0];
  for (const auto& s : sources) {
    lo = lo.cwiseMin(s);
    hi = hi.cwiseMax(s);
  }
  for (int c = 0; c < 3; ++c) {
    const double extent = std::max(hi[c] - lo[c] + 2 * radius, 1e-300);
    const double e = std::exp2(std::ceil(std::log2(extent)));
    const double centre = 0.5 * (lo[c] + hi[c]);
    g.shift[c] = std::abs(centre) < 4 * e ? 0.0 : std::nearbyint(centre / e) * e;
  }
  const double R2 = radius * radius;
  for (int k = std::clamp(max_subdivision, 1, kMaxSubdivision); k >= 1; --k) {
    g.subdivision = k;
    g.radius = radius;
    g.h = radius / k;
    g.inv_h = 1.0 / g.h;
    g.origin = lo - Vec3::Constant(radius);
    Vec3 span = (hi - lo + Vec3::Constant(2 * radius)) * g.inv_h;
    int spanned = 3;
    for (int a = 0; a < 3; ++a)
      if (a >= dims && hi[a] == lo[a]) {  // one layer of cells, [lo - h/2, lo + h/2)
        g.origin[a] = lo[a] - 0.5 * g.h;
        span[a] = 0;
        --spanned;
      }
    const double cells = (std::floor(span.x()) + 1) * (std::floor(span.y()) + 1) * (std::floor(span.z()) + 1);
    // Each source is listed in about 1 + 6K + 3 pi K^2 + 4/3 pi K^3 cells (Steiner's formula for a
    // cell grown by R = K h: 84 for K = 2, 21 for K = 1; in a plane 1 + 4K + pi K^2, on a line
    // 1 + 2K), plus padding; each entry costs 4 bytes here and 72 in the EvalData of both precisions.
    const double kk = k;
    const double steiner = spanned == 3   ? 1 + 6 * kk + 3 * M_PI * kk * kk + 4.0 / 3.0 * M_PI * kk * kk * kk
                           : spanned == 2 ? 1 + 4 * kk + M_PI * kk * kk
                                          : 1 + 2 * kk;
    const double entries = double(n) * 1.07 * steiner;
    // A dense grid only where the sources fill their box reasonably (else the hashed NeighborIndex).
    if (!(cells * 4.0 + entries * 76.0 <= double(max_bytes)) || !(cells <= 32.0 * double(n) + 65536.0)) continue;
    g.nx = std::int64_t(span.x()) + 1;
    g.ny = std::int64_t(span.y()) + 1;
    g.nz = std::int64_t(span.z()) + 1;
    const std::size_t ncell = std::size_t(g.nx * g.ny * g.nz);
    // (cell, source) pairs: every cell whose box is closer than R to the source.
    std::vector<std::uint32_t> count(ncell + 1, 0);
    FillVector<std::pair<std::uint32_t, std::uint32_t>> pairs;  // (cell, source), sources ascending
    pairs.reserve(std::size_t(entries));
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 q = (sources[i] - g.origin) * g.inv_h;  // in cell units
      // Per axis: the cells within K of the source's, and the squared distance to each cell's slab.
      std::int64_t c0[3], c1[3];
      static_assert(2 * kMaxSubdivision + 1 <= 9, "d2 holds the cells within K of the source");
      double d2[3][9];
      const std::int64_t dims[3] = {g.nx, g.ny, g.nz};
      for (int a = 0; a < 3; ++a) {
        const auto c = std::int64_t(q[a]);
        c0[a] = std::max<std::int64_t>(c - k, 0);
        c1[a] = std::min<std::int64_t>(c + k, dims[a] - 1);
        for (std::int64_t cc = c0[a]; cc <= c1[a]; ++cc) {
          const double below = double(cc) - q[a], above = q[a] - double(cc + 1);
          const double d = (below > 0 ? below : above > 0 ? above : 0.0) * g.h;
          d2[a][cc - c0[a]] = d * d;
        }
      }
      for (std::int64_t zc = c0[2]; zc <= c1[2]; ++zc) {
        const double dz = d2[2][zc - c0[2]];
        for (std::int64_t yc = c0[1]; yc <= c1[1]; ++yc) {
          const double ryz = dz + d2[1][yc - c0[1]];
          if (ryz >= R2) continue;
          const std::int64_t row = (zc * g.ny + yc) * g.nx;
          for (std::int64_t xc = c0[0]; xc <= c1[0]; ++xc) {
            if (ryz + d2[0][xc - c0[0]] >= R2) continue;
            const auto cell = std::uint32_t(row + xc);
            pairs.emplace_back(cell, std::uint32_t(i));
            ++count[cell + 1];
          }
        }
      }
    }
    // Offsets with each non-empty run padded to a multiple of kLanes.
    g.begin.assign(ncell + 1, 0);
    for (std::size_t c = 0; c < ncell; ++c)
      g.begin[c + 1] = g.begin[c] + std::uint32_t((count[c + 1] + kLanes - 1) / kLanes * kLanes);
    const std::size_t total = g.begin[ncell];
    if (double(total) * 76.0 + double(ncell) * 4.0 > double(max_bytes) || total >= 0xffffffffu) continue;
    g.source.assign(total, std::uint32_t(n));  // n: the inert source
    std::vector<std::uint32_t> fill(g.begin.begin(), g.begin.end() - 1);
    for (const auto& [cell, src] : pairs) g.source[fill[cell]++] = src;
    g.usable = true;
    return g;
  }
  return EvalGrid{};
}

void check_graph_entries(double entries, double max_entries, std::size_t n) {
  if (entries <= max_entries) return;
  std::ostringstream os;
  os.precision(3);
  os << "the neighbour graph of the " << n << " sources has " << entries << " entries ("
     << entries / double(std::max<std::size_t>(n, 1)) << " neighbours a source), " << entries * 12.0 / kGiB
     << " GiB, above what the memory limit leaves it (FitOptions::memory_limit_bytes, `--memory-limit`): some "
        "sources are far denser than the rest; use a smaller radius";
  throw ResourceLimit(os.str());
}

void EvalGrid::neighbor_graph(std::span<const Vec3> sources, std::vector<std::size_t>& offsets,
                              FillVector<std::uint32_t>& neighbors, FillVector<double>& dist2,
                              double max_entries) const {
  const std::size_t n = sources.size();
  const double R2 = radius * radius;
  // The sources grouped by cell (a counting sort): each cell's run is gathered once into contiguous
  // coordinates and tested against every source of the cell, where a pass in input order fetched
  // the run's sources from all over memory for each source. Two parallel passes over the groups:
  // count each source's neighbours, then (offsets known, the arrays allocated once at their exact
  // size) write them. A source's neighbours come in its run's order, whatever the order of the pass.
  CellOrder<double> groups;
  order_by_cell(*this, sources.data()->data(), n, groups);
  const auto& order = groups.order;
  const auto& cell_of = groups.cell;
  std::vector<std::uint32_t> first{0};  // first[g] .. first[g + 1]: group g's place in `order`
  for (std::size_t k = 1; k < n; ++k)
    if (cell_of[order[k]] != cell_of[order[k - 1]]) first.push_back(std::uint32_t(k));
  first.push_back(std::uint32_t(n));
  const std::size_t ngroups = first.size() - 1;
  struct Run {
    std::vector<double> x, y, z;
    std::vector<std::uint32_t> j;
    mutable std::vector<std::uint32_t> kept_j;  // scratch of the second pass (below)
    mutable std::vector<double> kept_d2;
  };
  // For each group, its run gathered, then f(i, run) for each of its sources i.
  const auto for_each_group = [&](auto&& f) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ngroups, 64), [&](const tbb::blocked_range<std::size_t>& r) {
      Run run;
      for (std::size_t gi = r.begin(); gi < r.end(); ++gi) {
        const std::uint32_t c = cell_of[order[first[gi]]];
        run.x.clear(), run.y.clear(), run.z.clear(), run.j.clear();
        for (std::uint32_t e = begin[c]; e < begin[c + 1]; ++e) {
          const std::uint32_t j = source[e];
          if (j == n) continue;
          run.x.push_back(sources[j].x()), run.y.push_back(sources[j].y()), run.z.push_back(sources[j].z());
          run.j.push_back(j);
        }
        for (std::uint32_t k = first[gi]; k < first[gi + 1]; ++k) f(order[k], run);
      }
    });
  };
  // Both passes without branches on the data (about a third of a run's candidates are within R, so
  // a branch per candidate mispredicted often: the two passes took 0.2 s of a 1e5-point fit's CPU).
  // Whether candidate t is another source within R of source i:
  const auto within = [&](std::uint32_t i, const Vec3& p, const Run& run, std::size_t t, double& d2) {
    const double dx = run.x[t] - p.x(), dy = run.y[t] - p.y(), dz = run.z[t] - p.z();
    d2 = dx * dx + dy * dy + dz * dz;
    return std::size_t(d2 < R2) & std::size_t(run.j[t] != i);
  };
  offsets.assign(n + 1, 0);
  for_each_group([&](std::uint32_t i, const Run& run) {
    const Vec3& p = sources[i];
    std::size_t c = 0;
    double d2;
    for (std::size_t t = 0; t < run.j.size(); ++t) c += within(i, p, run, t, d2);
    offsets[i + 1] = c;
  });
  for (std::size_t i = 0; i < n; ++i) offsets[i + 1] += offsets[i];
  check_graph_entries(double(offsets[n]), max_entries, n);
  neighbors.resize(offsets[n]);
  dist2.resize(offsets[n]);
  // Each candidate written to a row of scratch and kept by advancing past it (the scratch, not the
  // graph: a row's last write lands one past its kept entries, which in the graph is the next row's,
  // maybe another thread's), then the kept entries copied out, in the run's order.
  for_each_group([&](std::uint32_t i, const Run& run) {
    std::vector<std::uint32_t>& js = run.kept_j;
    std::vector<double>& ds = run.kept_d2;
    if (js.size() < run.j.size()) js.resize(run.j.size()), ds.resize(run.j.size());
    const Vec3& p = sources[i];
    std::size_t at = 0;
    for (std::size_t t = 0; t < run.j.size(); ++t) {
      double d2;
      const std::size_t keep = within(i, p, run, t, d2);
      js[at] = run.j[t];
      ds[at] = d2;
      at += keep;
    }
    std::copy(js.begin(), js.begin() + std::ptrdiff_t(at), neighbors.begin() + std::ptrdiff_t(offsets[i]));
    std::copy(ds.begin(), ds.begin() + std::ptrdiff_t(at), dist2.begin() + std::ptrdiff_t(offsets[i]));
  });
}

namespace {
/// The next float towards zero (x > 0): rounds a conversion down where it went up.
float below(float x) noexcept { return std::bit_cast<float>(std::bit_cast<std::uint32_t>(x) - 1); }
}  // namespace

template <class T>
void EvalData<T>::assign(const EvalGrid& g, std::span<const Vec3> sources, const double* alpha, Kernel kernel) {
  const double lead = phi_lead(kernel);
  const std::size_t total = g.source.size(), n = sources.size();
  constexpr T far = T(1e18);  // inert padding: r clips to 1 and phi(1) = 0
  const double inv_r = 1.0 / g.radius;
  for (Buffer<T>* b : {&x, &y, &z, &ax, &ay, &az}) b->allocate(total);
  sorted = total >= kSortEntries;
  reach.assign(sorted ? total / EvalGrid::kLanes + 8 : 0, 0.0f);
  const auto put = [&](std::size_t e, std::uint32_t s) {
    if (s == n) {
      x[e] = y[e] = z[e] = far;
      ax[e] = ay[e] = az[e] = T(0);
      return;
    }
    // Relative to a point near the sources: in double the grid's shift (exact differences far from
    // 0, where absolute coordinates kept only the digits the offset left: issue 30; the bits of
    // before near 0), in float its origin (float differences are never exact; the nearest base).
    const Vec3 p = Vec3(sources[s] - (std::is_same_v<T, double> ? g.shift : g.origin)) * inv_r;
    x[e] = T(p.x()), y[e] = T(p.y()), z[e] = T(p.z());
    ax[e] = T(lead * alpha[3 * s]), ay[e] = T(lead * alpha[3 * s + 1]), az[e] = T(lead * alpha[3 * s + 2]);
  };
  if (!sorted) {
    for (std::size_t e = 0; e < total; ++e) put(e, g.source[e]);
    return;
  }
  // Cells in parallel (each entry is written once, so the pages are first touched by the threads that
  // fill them); in each run the sources sorted by their squared distance from the centre, in units
  // of R, as a float rounded down, packed above the source index: one 64-bit key to sort.
  const std::size_t ncell = g.begin.size() - 1;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ncell, 4096), [&](const tbb::blocked_range<std::size_t>& cells) {
    std::vector<std::uint64_t> run;
    for (std::size_t c = cells.begin(); c < cells.end(); ++c) {
      const std::uint32_t b = g.begin[c], e = g.begin[c + 1];
      if (b == e) continue;
      const auto cx = std::int64_t(c) % g.nx, cy = std::int64_t(c) / g.nx % g.ny, cz = std::int64_t(c) / (g.nx * g.ny);
      const Vec3 centre = g.origin + g.h * Vec3(double(cx) + 0.5, double(cy) + 0.5, double(cz) + 0.5);
      run.clear();
      for (std::uint32_t k = b; k < e; ++k) {
        const std::uint32_t src = g.source[k];
        if (src == n) continue;
        const double d2 = (sources[src] - centre).squaredNorm() * (inv_r * inv_r);
        float key = float(d2);
        if (double(key) > d2) key = below(key);
        run.push_back(std::uint64_t(std::bit_cast<std::uint32_t>(key)) << 32 | src);  // >= 0: ordered as integers
      }
      std::sort(run.begin(), run.end());
      for (std::uint32_t k = b; k < e; ++k) put(k, k - b < run.size() ? std::uint32_t(run[k - b]) : std::uint32_t(n));
      for (std::uint32_t k = b; k < e; k += std::uint32_t(EvalGrid::kLanes)) {
        // The block's nearest source (every block holds one): its distance, rounded down.
        const double d = std::sqrt(double(std::bit_cast<float>(std::uint32_t(run[k - b] >> 32))));
        float r = float(d);
        if (double(r) > d) r = below(r);
        reach[k / EvalGrid::kLanes] = r;
      }
    }
  });
}
template struct EvalData<float>;
template struct EvalData<double>;

namespace {
/// The cell of a point, or the grid's cell count for a point outside it (or NaN). Inside the grid
/// the cell coordinates are non-negative, where truncation is floor: no call to floor (this file is
/// built for baseline x86-64, where floor is a library call), which took half the counting pass.
template <class T>
std::size_t cell_index(const EvalGrid& g, const T* p) noexcept {
  const double ux = (double(p[0]) - g.origin.x()) * g.inv_h, uy = (double(p[1]) - g.origin.y()) * g.inv_h,
               uz = (double(p[2]) - g.origin.z()) * g.inv_h;
  if (ux >= 0 && uy >= 0 && uz >= 0 && ux < double(g.nx) && uy < double(g.ny) && uz < double(g.nz))
    return std::size_t((std::int64_t(uz) * g.ny + std::int64_t(uy)) * g.nx + std::int64_t(ux));
  return std::size_t(g.nx * g.ny * g.nz);
}
}  // namespace

template <class T>
bool incoherent(const EvalGrid& g, const T* in, std::size_t n) {
  constexpr std::size_t kWindows = 64, kPairs = 64;
  if (n < 2 * kWindows * (kPairs + 1)) return false;
  std::size_t breaks = 0;
  for (std::size_t w = 0; w < kWindows; ++w) {
    const std::size_t start = w * (n - kPairs - 1) / (kWindows - 1);
    std::size_t last = cell_index(g, in + 3 * start);
    for (std::size_t i = start + 1; i <= start + kPairs; ++i) {
      const std::size_t c = cell_index(g, in + 3 * i);
      breaks += c != last;
      last = c;
    }
  }
  // Coherent meshes change cell every 4 to 20 points (a vertex ring crosses a cell of side R/2); a
  // random order changes at nearly every point.
  return breaks * 2 > kWindows * kPairs;
}

template <class T>
void order_by_cell(const EvalGrid& g, const T* in, std::size_t n, CellOrder<T>& o) {
  const std::size_t ncell = std::size_t(g.nx * g.ny * g.nz) + 1;  // the last: outside
  // A counting sort in parallel: each chunk of points counts its cells, one scan over (cell, chunk)
  // gives every chunk its place in every cell, and the chunks place their points. Chunks only while
  // their counts take less memory than the points (a grid of many cells keeps one).
  const std::size_t threads = std::size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
  std::size_t chunks = std::min<std::size_t>(2 * threads, (n + 65535) / 65536);
  while (chunks > 1 && chunks * ncell > n) --chunks;
  chunks = std::max<std::size_t>(chunks, 1);
  const std::size_t per = (n + chunks - 1) / chunks;
  auto& cell = o.cell;
  auto& start = o.start;  // chunks x ncell counts, then offsets, cell-major
  cell.resize(n);
  start.assign(chunks * ncell, 0);
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t k) {
    std::uint32_t* count = start.data() + k * ncell;
    for (std::size_t i = k * per; i < std::min(n, (k + 1) * per); ++i) {
      const auto c = std::uint32_t(cell_index(g, in + 3 * i));
      cell[i] = c;
      ++count[c];
    }
  });
  std::uint32_t sum = 0;
  for (std::size_t c = 0; c < ncell; ++c)
    for (std::size_t k = 0; k < chunks; ++k) {
      const std::uint32_t here = start[k * ncell + c];
      start[k * ncell + c] = sum;
      sum += here;
    }
  o.order.resize(n);
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t k) {
    std::uint32_t* place = start.data() + k * ncell;
    for (std::size_t i = k * per; i < std::min(n, (k + 1) * per); ++i) o.order[place[cell[i]]++] = std::uint32_t(i);
  });
}

template bool incoherent<double>(const EvalGrid&, const double*, std::size_t);
template bool incoherent<float>(const EvalGrid&, const float*, std::size_t);
template void order_by_cell<double>(const EvalGrid&, const double*, std::size_t, CellOrder<double>&);
template void order_by_cell<float>(const EvalGrid&, const float*, std::size_t, CellOrder<float>&);

namespace {

#define CSRBF_EVAL_CLONE(K, T)                                                                                       \
  CSRBF_CLONES void eval_##K##_##T(const EvalGrid& g, const EvalData<T>& a, const PolynomialPart* poly, const T* in, \
                                   T* out, std::size_t b, std::size_t e, double phase, bool add_point) {             \
    evaluate_block<Kernel::K, T, PortableRun>(g, a, poly, in, out, b, e, phase, add_point);                          \
  }
CSRBF_EVAL_CLONE(C0, double)
CSRBF_EVAL_CLONE(C2, double)
CSRBF_EVAL_CLONE(C4, double)
CSRBF_EVAL_CLONE(C6, double)
CSRBF_EVAL_CLONE(C0, float)
CSRBF_EVAL_CLONE(C2, float)
CSRBF_EVAL_CLONE(C4, float)
CSRBF_EVAL_CLONE(C6, float)
#undef CSRBF_EVAL_CLONE

}  // namespace

namespace {
/// The portable one-point-a-lane loop: 8 lanes (AVX2's ymm of float; four xmm of double).
constexpr std::size_t kNormalLanes = 8;
#define CSRBF_NORMALS_CLONE(K, T)                                                                          \
  CSRBF_CLONES void normals_##K##_##T(const EvalGrid& g, const EvalData<T>& a, const PolynomialPart* poly, \
                                      const NormalsJob<T>& job, std::size_t b, std::size_t e) {            \
    normals_block<Kernel::K, T, kNormalLanes, PortableRun, PortableRoot>(g, a, poly, job, b, e);           \
  }
CSRBF_NORMALS_CLONE(C0, double)
CSRBF_NORMALS_CLONE(C2, double)
CSRBF_NORMALS_CLONE(C4, double)
CSRBF_NORMALS_CLONE(C6, double)
CSRBF_NORMALS_CLONE(C0, float)
CSRBF_NORMALS_CLONE(C2, float)
CSRBF_NORMALS_CLONE(C4, float)
CSRBF_NORMALS_CLONE(C6, float)
#undef CSRBF_NORMALS_CLONE
}  // namespace

namespace {
std::atomic<bool> g_use_avx512{avx512_available()};
}  // namespace

bool avx512_available() noexcept {
#ifdef CSRBF_HAVE_AVX512_EVAL
  // This runs from a static initialiser, possibly before libgcc's own: initialise the CPU model first.
  // (__builtin_cpu_supports also checks that the OS saves the AVX-512 registers.)
  static const bool yes = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
           __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
  }();
  return yes;
#else
  return false;
#endif
}

void set_eval_isa(EvalIsa isa) noexcept { g_use_avx512 = isa == EvalIsa::Avx512 && avx512_available(); }
EvalIsa eval_isa() noexcept { return g_use_avx512 ? EvalIsa::Avx512 : EvalIsa::Portable; }

// stmt where this build has the AVX-512 loops and they run (the CPU has them, set_eval_isa allows).
#ifdef CSRBF_HAVE_AVX512_EVAL
#define CSRBF_IF_AVX512(stmt) \
  if (g_use_avx512.load(std::memory_order_relaxed)) stmt
#else
#define CSRBF_IF_AVX512(stmt)
#endif
#define CSRBF_NORMALS_DISPATCH(T)                                                                           \
  void evaluate_normals(const EvalGrid& g, const EvalData<T>& a, Kernel kernel, const PolynomialPart* poly, \
                        const NormalsJob<T>& job, std::size_t begin, std::size_t end) {                     \
    CSRBF_IF_AVX512(return evaluate_normals_avx512(g, a, kernel, poly, job, begin, end));                   \
    switch (kernel) {                                                                                       \
      case Kernel::C0:                                                                                      \
        return normals_C0_##T(g, a, poly, job, begin, end);                                                 \
      case Kernel::C2:                                                                                      \
        return normals_C2_##T(g, a, poly, job, begin, end);                                                 \
      case Kernel::C4:                                                                                      \
        return normals_C4_##T(g, a, poly, job, begin, end);                                                 \
      case Kernel::C6:                                                                                      \
        return normals_C6_##T(g, a, poly, job, begin, end);                                                 \
    }                                                                                                       \
  }
CSRBF_NORMALS_DISPATCH(double)
CSRBF_NORMALS_DISPATCH(float)
#undef CSRBF_NORMALS_DISPATCH
#undef CSRBF_IF_AVX512

void evaluate(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly, const double* in,
              double* out, std::size_t begin, std::size_t end, double phase, bool add_point) {
#ifdef CSRBF_HAVE_AVX512_EVAL
  if (g_use_avx512.load(std::memory_order_relaxed))
    return evaluate_avx512(g, a, kernel, poly, in, out, begin, end, phase, add_point);
#endif
  switch (kernel) {
    case Kernel::C0:
      return eval_C0_double(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C2:
      return eval_C2_double(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C4:
      return eval_C4_double(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C6:
      return eval_C6_double(g, a, poly, in, out, begin, end, phase, add_point);
  }
}

void evaluate(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly, const float* in,
              float* out, std::size_t begin, std::size_t end, double phase, bool add_point) {
#ifdef CSRBF_HAVE_AVX512_EVAL
  if (g_use_avx512.load(std::memory_order_relaxed))
    return evaluate_avx512(g, a, kernel, poly, in, out, begin, end, phase, add_point);
#endif
  switch (kernel) {
    case Kernel::C0:
      return eval_C0_float(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C2:
      return eval_C2_float(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C4:
      return eval_C4_float(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C6:
      return eval_C6_float(g, a, poly, in, out, begin, end, phase, add_point);
  }
}

}  // namespace csrbf::detail
