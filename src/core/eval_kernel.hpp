// The per-vertex loop of the fast evaluation path, shared by evaluator.cpp (portable code, AVX2
// clone) and evaluator_avx512.cpp (hand-written AVX-512). Everything here has internal linkage on
// purpose: each translation unit compiles its own copy with its own instruction set, and the linker
// must never merge an AVX-512 instantiation into the portable path.
#pragma once

#include "evaluator.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

// Lanes (GCC vectors) go by value between the always-inlined functions below: the ABI note that
// GCC gives where the translation unit lacks the vector's instruction set concerns calls that are
// never made.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace csrbf::detail {
namespace {  // NOLINT(google-build-namespaces): see above

/// phi(r) / phi_lead(K) for r in [0, 1], branch-free; every member is exactly 0 at r = 1. V is a
/// scalar or a GCC vector of S (the vector extensions broadcast the scalar constants). Dividing by
/// the leading coefficient of the polynomial factor makes that factor monic, which saves a multiply
/// per candidate (C2: (1-r)^4 (r + 1/4) instead of (1-r)^4 (4r + 1)); EvalData's coefficients carry
/// the factor instead.
template <Kernel K, class V, class S = V>
inline __attribute__((always_inline)) V phi(V r) {
  const V s = S(1) - r;
  const V s2 = s * s;
  if constexpr (K == Kernel::C0)
    return s2;
  else if constexpr (K == Kernel::C2)
    return (s2 * s2) * (r + S(0.25));
  else if constexpr (K == Kernel::C4)
    return (s2 * s2 * s2) * ((r + S(18.0 / 35.0)) * r + S(3.0 / 35.0));
  else
    return (s2 * s2) * (s2 * s2) * (((r + S(25.0 / 32.0)) * r + S(0.25)) * r + S(1.0 / 32.0));
}

/// phi'(r) / (r phi_lead(K)) for r in (0, 1] is dphi_factor<K>() dphi_shape<K>(r): the gradient of
/// phi(|t - s|) in t is that times (t - s), in units of R. The constant factor is applied once to a
/// sum, not to every term. V is a scalar or a GCC vector of S. Smooth at r = 0 for C2-C6 (C2:
/// -5 (1-r)^3); the C0 cone has no gradient at its tip, where the caller clamps r above 0 and the
/// product with t - s = 0 gives 0 (as SpaceMap::jacobian does).
template <Kernel K>
constexpr double dphi_factor() {
  return K == Kernel::C0 ? -2.0 : K == Kernel::C2 ? -5.0 : K == Kernel::C4 ? -8.0 : -11.0;
}
template <Kernel K, class V, class S = V>
inline __attribute__((always_inline)) V dphi_shape(V r) {
  const V s = S(1) - r;
  if constexpr (K == Kernel::C0)
    return s / r;
  else if constexpr (K == Kernel::C2)
    return s * s * s;
  else if constexpr (K == Kernel::C4)
    return (s * s) * (s * s) * s * (r + S(0.2));
  else
    return ((s * s) * (s * s) * (s * s) * s) * ((r + S(7.0 / 16.0)) * r + S(1.0 / 16.0));
}

/// Runs sum a cell's run [b, e) (a multiple of kLanes long) for kGroup points at once: the
/// points share each load of the run, and their independent chains keep the pipelines full. (One
/// point at a time, the loop is bound by the latency of its chain and by the mispredicted exit of
/// a short loop at every vertex.) Points that do not share a cell use a group of one.
constexpr std::size_t kGroup = 4;

/// One call of evaluate(): the grid's geometry, the points and what to write.
template <class T>
struct Block {
  const EvalGrid& g;
  const EvalData<T>& a;
  const PolynomialPart* poly;
  const T* in;
  T* out;
  double phase;
  bool add_point;
  double inv_r = 1.0 / g.radius;
  double h_over_r = g.h / g.radius;
  static constexpr std::size_t none = ~std::size_t(0);
  /// 1 plus a margin far above the rounding of the cell coordinates below (1e-16 of a cell index)
  /// and of the limit to float (6e-8).
  static constexpr double kLimitSlack = 1.0 + 1e-6;

  /// The cell of point i; none outside the grid (the sources' box grown by R: no source within R)
  /// or for NaN. limit: 1 + |p - c| / R for the cell's centre c, rounded up (EvalData::trim).
  std::size_t cell_of(std::size_t i, float& limit) const {
    const double ux = (double(in[3 * i]) - g.origin.x()) * g.inv_h,
                 uy = (double(in[3 * i + 1]) - g.origin.y()) * g.inv_h,
                 uz = (double(in[3 * i + 2]) - g.origin.z()) * g.inv_h;
    const double fx = std::floor(ux), fy = std::floor(uy), fz = std::floor(uz);
    const double dx = ux - fx - 0.5, dy = uy - fy - 0.5, dz = uz - fz - 0.5;
    limit = float(kLimitSlack + std::sqrt(dx * dx + dy * dy + dz * dz) * h_over_r);
    if (fx >= 0 && fy >= 0 && fz >= 0 && fx < double(g.nx) && fy < double(g.ny) && fz < double(g.nz))
      return std::size_t((std::int64_t(fz) * g.ny + std::int64_t(fy)) * g.nx + std::int64_t(fx));
    return none;
  }
  /// Point i in units of R as EvalData stores the sources: double relative to the grid's shift
  /// (exact for points near the sources, however far from 0), float relative to its origin.
  void local(std::size_t i, T (&t)[3]) const {
    constexpr bool dbl = std::is_same_v<T, double>;
    for (int c = 0; c < 3; ++c) t[c] = T((double(in[3 * i + c]) - (dbl ? g.shift[c] : g.origin[c])) * inv_r);
  }
  /// Writes point i's output from its CSRBF sum d (the polynomial part added here).
  void finish(std::size_t i, const T (&d)[3]) const {
    const double px = double(in[3 * i]), py = double(in[3 * i + 1]), pz = double(in[3 * i + 2]);
    double d0 = double(d[0]), d1 = double(d[1]), d2 = double(d[2]);
    if (poly) {
      const double u0 = (px - poly->center.x()) * poly->inv_scale, u1 = (py - poly->center.y()) * poly->inv_scale,
                   u2 = (pz - poly->center.z()) * poly->inv_scale;
      d0 += poly->b[0][0] + u0 * poly->b[1][0] + u1 * poly->b[2][0] + u2 * poly->b[3][0];
      d1 += poly->b[0][1] + u0 * poly->b[1][1] + u1 * poly->b[2][1] + u2 * poly->b[3][1];
      d2 += poly->b[0][2] + u0 * poly->b[1][2] + u1 * poly->b[2][2] + u2 * poly->b[3][2];
    }
    if (add_point) {
      out[3 * i] = T(px + phase * d0);
      out[3 * i + 1] = T(py + phase * d1);
      out[3 * i + 2] = T(pz + phase * d2);
    } else {
      out[3 * i] = T(d0);
      out[3 * i + 1] = T(d1);
      out[3 * i + 2] = T(d2);
    }
  }
};

/// The portable run: plain loops with one accumulator per lane, which the compiler vectorises.
/// A Run provides cells() (the cells of n points), group() (kGroup points that share a cell's run)
/// and one() (a single point); evaluate_block() drives them.
struct PortableRun {
  template <Kernel K, class T, std::size_t P>
  static inline __attribute__((always_inline)) void sum(const EvalData<T>& a, std::uint32_t b, std::uint32_t e,
                                                        const T (&t)[P][3], T (&d)[P][3]) {
    const T* __restrict sx = a.x.data();
    const T* __restrict sy = a.y.data();
    const T* __restrict sz = a.z.data();
    const T* __restrict ax = a.ax.data();
    const T* __restrict ay = a.ay.data();
    const T* __restrict az = a.az.data();
    constexpr std::size_t L = EvalGrid::kLanes;
    T acc[P][3][L] = {};
    for (std::uint32_t j = b; j < e; j += L) {
      for (std::size_t p = 0; p < P; ++p) {
        const T tx = t[p][0], ty = t[p][1], tz = t[p][2];
#pragma omp simd
        for (std::size_t l = 0; l < L; ++l) {
          const T ddx = sx[j + l] - tx, ddy = sy[j + l] - ty, ddz = sz[j + l] - tz;
          const T rr = std::sqrt(ddx * ddx + ddy * ddy + ddz * ddz);
          const T r = rr < T(1) ? rr : T(1);  // by value: std::min's references defeat if-conversion
          const T f = phi<K, T>(r);
          acc[p][0][l] += f * ax[j + l];
          acc[p][1][l] += f * ay[j + l];
          acc[p][2][l] += f * az[j + l];
        }
      }
    }
    for (std::size_t p = 0; p < P; ++p)
      for (std::size_t c = 0; c < 3; ++c)
        for (std::size_t l = 0; l < L; ++l) d[p][c] += acc[p][c][l];
  }

  template <class T>
  static inline __attribute__((always_inline)) void cells(const Block<T>& k, std::size_t first, std::size_t n,
                                                          std::size_t* cell, float* limit) {
    for (std::size_t i = 0; i < n; ++i) cell[i] = k.cell_of(first + i, limit[i]);
  }

  /// W interleaved triples from p into o (component-major); lanes from m on repeat triple m - 1.
  template <class T, std::size_t W>
  static inline __attribute__((always_inline)) void load3(const T* p, std::size_t m, T (&o)[3][W]) {
    for (std::size_t l = 0; l < W; ++l)
      for (std::size_t c = 0; c < 3; ++c) o[c][l] = p[3 * std::min(l, m - 1) + c];
  }
  /// The first m lanes of o (component-major) to p as interleaved triples.
  template <class T, std::size_t W>
  static inline __attribute__((always_inline)) void store3(T* p, std::size_t m, const T (&o)[3][W]) {
    for (std::size_t l = 0; l < m; ++l)
      for (std::size_t c = 0; c < 3; ++c) p[3 * l + c] = o[c][l];
  }

  /// Points i .. i + kGroup - 1, all in the cell whose run (trimmed) is [b, e) (may be empty).
  template <Kernel K, class Run, class T>
  static inline __attribute__((always_inline)) void group(const Block<T>& k, std::uint32_t b, std::uint32_t e,
                                                          std::size_t i) {
    T t[kGroup][3], d[kGroup][3] = {};
    for (std::size_t p = 0; p < kGroup; ++p) k.local(i + p, t[p]);
    Run::template sum<K, T, kGroup>(k.a, b, e, t, d);
    for (std::size_t p = 0; p < kGroup; ++p) k.finish(i + p, d[p]);
  }

  /// Point i, whose cell's run is [b, e) (may be empty).
  template <Kernel K, class Run, class T>
  static inline __attribute__((always_inline)) void one(const Block<T>& k, std::uint32_t b, std::uint32_t e,
                                                        std::size_t i) {
    T t[1][3], d[1][3] = {};
    if (b != e) {
      k.local(i, t[0]);
      Run::template sum<K, T, 1>(k.a, b, e, t, d);
    }
    k.finish(i, d[0]);
  }
};

/// Points [begin, end) of in/out through the cell lists.
template <Kernel K, class T, class Run>
inline __attribute__((always_inline)) void evaluate_block(const EvalGrid& g, const EvalData<T>& a,
                                                          const PolynomialPart* poly, const T* in, T* out,
                                                          std::size_t begin, std::size_t end, double phase,
                                                          bool add_point) {
  const Block<T> blk{g, a, poly, in, out, phase, add_point};
  const std::uint32_t* cb = g.begin.data();
  constexpr std::size_t none = Block<T>::none;
  // Cells are found for a chunk of points first (a loop without branches on data), then the points
  // go through their runs: groups of kGroup when consecutive points share a cell, else one by one.
  // Each point's run ends where EvalData::trim says (sorted runs; the whole run otherwise).
  constexpr std::size_t kChunk = 256;
  std::size_t cells[kChunk + kGroup];
  float limit[kChunk];
  for (std::size_t c0 = begin; c0 < end; c0 += kChunk) {
    const std::size_t n = end - c0 < kChunk ? end - c0 : kChunk;
    Run::cells(blk, c0, n, cells, limit);
    for (std::size_t k = n; k < n + kGroup; ++k) cells[k] = none;  // a group never runs past the chunk
    std::size_t k = 0;
    while (k < n) {
      const std::size_t cell = cells[k];
      static_assert(kGroup == 4, "the tests below check 4 cells");
      if (cell != none && cells[k + 1] == cell && cells[k + 2] == cell && cells[k + 3] == cell &&
          cb[cell] != cb[cell + 1]) {
        const float most = std::max(std::max(limit[k], limit[k + 1]), std::max(limit[k + 2], limit[k + 3]));
        Run::template group<K, Run>(blk, cb[cell], a.trim(cb[cell], cb[cell + 1], most), c0 + k);
        k += kGroup;
        continue;
      }
      if (cell != none)
        Run::template one<K, Run>(blk, cb[cell], a.trim(cb[cell], cb[cell + 1], limit[k]), c0 + k);
      else
        Run::template one<K, Run>(blk, 0, 0, c0 + k);
      ++k;
    }
  }
}

/// W lanes of T (a GCC vector: the arithmetic operators work lane by lane, a scalar operand is
/// broadcast, and ?: selects by lane).
template <class T, std::size_t W>
struct LanesOf {
  typedef T type __attribute__((vector_size(W * sizeof(T))));
};

/// The portable square roots of W lanes (AVX-512 uses its reciprocal estimates instead).
struct PortableRoot {
  /// f of each lane.
  template <class V, class F>
  static inline __attribute__((always_inline)) V each(V a, F f) {
    V r;
    constexpr std::size_t W = sizeof(V) / sizeof(a[0]);
#pragma omp simd
    for (std::size_t l = 0; l < W; ++l) r[l] = f(a[l]);
    return r;
  }
  /// sqrt(min(r2, 1)), 1 / sqrt(b) and sqrt(a).
  template <class V>
  static inline __attribute__((always_inline)) V clipped_root(V r2) {
    return each(r2, [](auto x) { return std::sqrt(std::min(x, decltype(x)(1))); });
  }
  template <class V>
  static inline __attribute__((always_inline)) V inv_root(V b) {
    return each(b, [](auto x) { return 1 / std::sqrt(x); });
  }
  template <class V>
  static inline __attribute__((always_inline)) V root(V a) {
    return each(a, [](auto x) { return std::sqrt(x); });
  }
};

/// Points [begin, end) of job.in: out = in + phase d(in); where job.jac, J = dT/dx = I + phase
/// dd/dx (9 a point, row-major); where job.normals_in, normals_out = J^-T n (the cofactor matrix
/// of J times n, of det J's sign, so that a normal keeps its side where the map folds), scaled to
/// |n|, or to 1 where job.unit. Any output may be its input.
///
/// One point a lane, not one source a lane as in evaluate_block: up to W consecutive points in one
/// cell go through the cell's run together, each source's six values broadcast to the lanes. The
/// twelve sums of a point (d and the 3 x 3 gradient) then stay in its lane, with no reduction
/// across lanes, and the Jacobian, the polynomial part and the normal are computed in lanes too.
/// Run gives cells(), load3() and store3(); Root gives clipped_root(r2), the root of min(r2, 1) for r2 > 0, inv_root(b)
/// = 1 / sqrt(b) and root(a) = sqrt(a), of lanes.
template <Kernel K, class T, std::size_t W, class Run, class Root>
inline __attribute__((always_inline)) void normals_block(const EvalGrid& g, const EvalData<T>& a,
                                                         const PolynomialPart* poly, const NormalsJob<T>& job,
                                                         std::size_t begin, std::size_t end) {
  using V = typename LanesOf<T, W>::type;
  using D = typename LanesOf<double, W>::type;
  const Block<T> blk{g, a, poly, job.in, job.out, job.phase, true};
  const std::uint32_t* cb = g.begin.data();
  constexpr std::size_t none = Block<T>::none;
  constexpr T tiny = std::is_same_v<T, double> ? T(1e-300) : T(1e-30);
  // The sums of G are over dphi_shape in units of R: dphi_factor / R makes them the gradient.
  const double phase = job.phase, grad = dphi_factor<K>() * blk.inv_r;
  // J = I + phase (G / R + L): G the sum over the run in units of R, L the polynomial's linear part.
  double lin[3][3] = {};
  if (poly)
    for (int m = 0; m < 3; ++m)
      for (int n = 0; n < 3; ++n) lin[m][n] = poly->b[1 + n][m] * poly->inv_scale;
  const T* __restrict sx = a.x.data();
  const T* __restrict sy = a.y.data();
  const T* __restrict sz = a.z.data();
  const T* __restrict ax = a.ax.data();
  const T* __restrict ay = a.ay.data();
  const T* __restrict az = a.az.data();
  constexpr std::size_t kChunk = 256;
  std::size_t cells[kChunk];
  float limit[kChunk];
  for (std::size_t c0 = begin; c0 < end; c0 += kChunk) {
    const std::size_t n = end - c0 < kChunk ? end - c0 : kChunk;
    Run::cells(blk, c0, n, cells, limit);
    for (std::size_t k = 0; k < n;) {
      const std::size_t cell = cells[k];
      std::size_t m = 1;
      float most = limit[k];
      while (m < W && k + m < n && cells[k + m] == cell) most = std::max(most, limit[k + m++]);
      const std::size_t i0 = c0 + k;
      k += m;
      // The group's points in double lanes (the last repeated in the lanes beyond m), and in units
      // of R as Block::local computes them.
      T pl[3][W];
      Run::load3(job.in + 3 * i0, m, pl);
      D p[3];
      V t[3];
      for (int c = 0; c < 3; ++c) {
        V pc;
        std::memcpy(&pc, pl[c], sizeof(V));
        p[c] = __builtin_convertvector(pc, D);
        t[c] = __builtin_convertvector((p[c] - (std::is_same_v<T, double> ? g.shift[c] : g.origin[c])) * blk.inv_r, V);
      }
      V acc[12] = {};  // d x y z, then G row by row
      if (cell != none) {
        const std::uint32_t b = cb[cell], e = a.trim(cb[cell], cb[cell + 1], most);
        for (std::uint32_t j = b; j < e; ++j) {
          const V dx = t[0] - sx[j], dy = t[1] - sy[j], dz = t[2] - sz[j];
          // tiny added, not a maximum taken: one multiply-add fewer, and below r2's rounding
          // wherever r2 exceeds 1e-22 (float) or 1e-284 (double).
          const V r = Root::clipped_root(dx * dx + (dy * dy + (dz * dz + tiny)));
          const V f = phi<K, V, T>(r), h = dphi_shape<K, V, T>(r);
          const V ux = h * dx, uy = h * dy, uz = h * dz;
          const T cx = ax[j], cy = ay[j], cz = az[j];
          acc[0] += f * cx, acc[1] += f * cy, acc[2] += f * cz;
          acc[3] += cx * ux, acc[4] += cx * uy, acc[5] += cx * uz;
          acc[6] += cy * ux, acc[7] += cy * uy, acc[8] += cy * uz;
          acc[9] += cz * ux, acc[10] += cz * uy, acc[11] += cz * uz;
        }
      }
      // Positions in double, as Block::finish computes them.
      D d[3];
      for (int c = 0; c < 3; ++c) d[c] = __builtin_convertvector(acc[c], D);
      if (poly) {
        const D u0 = (p[0] - poly->center.x()) * poly->inv_scale, u1 = (p[1] - poly->center.y()) * poly->inv_scale,
                u2 = (p[2] - poly->center.z()) * poly->inv_scale;
        for (int c = 0; c < 3; ++c)
          d[c] += poly->b[0][c] + u0 * poly->b[1][c] + u1 * poly->b[2][c] + u2 * poly->b[3][c];
      }
      T res[3][W];
      for (int c = 0; c < 3; ++c) {
        const V y = __builtin_convertvector(p[c] + phase * d[c], V);
        std::memcpy(res[c], &y, sizeof(V));
      }
      Run::store3(job.out + 3 * i0, m, res);
      // J in T's lanes (float: a relative error near 1e-7, 1e-7 rad in the normal).
      V j[3][3];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) j[r][c] = T(r == c) + T(phase) * (acc[3 + 3 * r + c] * T(grad) + T(lin[r][c]));
      if (job.jac) {
        T jl[9][W];
        for (int q = 0; q < 9; ++q) std::memcpy(jl[q], &j[q / 3][q % 3], sizeof(V));
        for (std::size_t l = 0; l < m; ++l)
          for (int q = 0; q < 9; ++q) job.jac[9 * (i0 + l) + std::size_t(q)] = jl[q][l];
      }
      if (!job.normals_in) continue;
      T nl[3][W];
      Run::load3(job.normals_in + 3 * i0, m, nl);
      V nv[3];
      for (int c = 0; c < 3; ++c) std::memcpy(&nv[c], nl[c], sizeof(V));
      // J scaled to its largest entry first (of no effect on the direction or on det's sign): its
      // cofactors cannot overflow, in float either. Lanes where that entry is 0, infinite or NaN
      // keep J as it is (a zero or a non-finite normal).
      const auto absv = [](V x) { return x < 0 ? -x : x; };
      const auto fine = [](V x) { return x > 0 && x < std::numeric_limits<T>::infinity(); };
      const V one = V{} + T(1);
      V big = absv(j[0][0]);
      for (int q = 1; q < 9; ++q) big = absv(j[q / 3][q % 3]) > big ? absv(j[q / 3][q % 3]) : big;
      const V sc = fine(big) ? one / big : one;
      for (int q = 0; q < 9; ++q) j[q / 3][q % 3] *= sc;
      // cof = det(J) J^-T, its columns the cross products of J's columns; w = cof n.
      const auto cross = [&](int a0, int a1, int c) {  // (column a0 x column a1)[c]
        const int c1 = (c + 1) % 3, c2 = (c + 2) % 3;
        return j[c1][a0] * j[c2][a1] - j[c2][a0] * j[c1][a1];
      };
      // n scaled to its largest component too, and w = cof n to its own before its squared norm:
      // no length of n (1e-30 or 1e20 in float) overflows or underflows on the way. |n| = nmax |n'|.
      V nmax = absv(nv[0]);
      nmax = absv(nv[1]) > nmax ? absv(nv[1]) : nmax;
      nmax = absv(nv[2]) > nmax ? absv(nv[2]) : nmax;
      const V ns = fine(nmax) ? one / nmax : one;
      for (int c = 0; c < 3; ++c) nv[c] *= ns;
      V w[3];
      for (int c = 0; c < 3; ++c) w[c] = nv[0] * cross(1, 2, c) + nv[1] * cross(2, 0, c) + nv[2] * cross(0, 1, c);
      const V det = j[0][0] * cross(1, 2, 0) + j[1][0] * cross(1, 2, 1) + j[2][0] * cross(1, 2, 2);
      V wmax = absv(w[0]);
      wmax = absv(w[1]) > wmax ? absv(w[1]) : wmax;
      wmax = absv(w[2]) > wmax ? absv(w[2]) : wmax;
      const V ws = fine(wmax) ? one / wmax : one;
      for (int c = 0; c < 3; ++c) w[c] *= ws;
      const V len2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
      V fv = Root::inv_root(len2);  // to 1, or to |n|
      if (!job.unit) fv *= (fine(nmax) ? nmax : one) * Root::root(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
      fv = det < 0 ? -fv : fv;
      fv = fine(len2) ? fv : one;
      T res_n[3][W];
      for (int c = 0; c < 3; ++c) {
        const V y = w[c] * fv;
        std::memcpy(res_n[c], &y, sizeof(V));
      }
      Run::store3(job.normals_out + 3 * i0, m, res_n);
    }
  }
}

}  // namespace
}  // namespace csrbf::detail
