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
#include <type_traits>

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

/// phi'(r) / (r phi_lead(K)) for r in [0, 1]: the gradient of phi(|t - s|) in t is this times
/// (t - s), in units of R. Smooth at r = 0 for C2-C6 (C2: -5 (1-r)^3); the C0 cone has no gradient
/// at its tip, where this gives 0 (as SpaceMap::jacobian does).
template <Kernel K, class T>
inline __attribute__((always_inline)) T dphi_over_r(T r) {
  const T s = T(1) - r;
  if constexpr (K == Kernel::C0)
    return r > T(0) ? T(-2) * s / r : T(0);
  else if constexpr (K == Kernel::C2)
    return T(-5) * (s * s * s);
  else if constexpr (K == Kernel::C4)
    return -(s * s) * (s * s) * s * (T(8) * r + T(1.6));
  else
    return T(-22.0 / 32.0) * ((s * s) * (s * s) * (s * s) * s) * ((T(16) * r + T(7)) * r + T(1));
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

/// Points [begin, end) of in: out = in + phase d(in), and jac (9 a point, row-major) = dT/dx =
/// I + phase dd/dx, through the cell lists, in double. One point at a time, the run in lanes.
template <Kernel K>
inline __attribute__((always_inline)) void jacobian_block(const EvalGrid& g, const EvalData<double>& a,
                                                          const PolynomialPart* poly, const double* in, double* out,
                                                          double* jac, std::size_t begin, std::size_t end,
                                                          double phase) {
  const Block<double> blk{g, a, poly, in, out, phase, true};
  const std::uint32_t* cb = g.begin.data();
  const double* __restrict sx = a.x.data();
  const double* __restrict sy = a.y.data();
  const double* __restrict sz = a.z.data();
  const double* __restrict ax = a.ax.data();
  const double* __restrict ay = a.ay.data();
  const double* __restrict az = a.az.data();
  constexpr std::size_t L = EvalGrid::kLanes;
  for (std::size_t i = begin; i < end; ++i) {
    float limit;
    const std::size_t cell = blk.cell_of(i, limit);
    double d[3] = {}, j[3][3] = {};
    if (cell != Block<double>::none) {
      const std::uint32_t b = cb[cell], e = a.trim(cb[cell], cb[cell + 1], limit);
      double t[3];
      blk.local(i, t);
      double acc[3][L] = {}, gj[3][3][L] = {};
      for (std::uint32_t q = b; q < e; q += L) {
#pragma omp simd
        for (std::size_t l = 0; l < L; ++l) {
          const double dx = t[0] - sx[q + l], dy = t[1] - sy[q + l], dz = t[2] - sz[q + l];
          const double rr = std::sqrt(dx * dx + dy * dy + dz * dz);
          const double r = rr < 1.0 ? rr : 1.0;
          const double f = phi<K, double>(r), h = dphi_over_r<K, double>(r);
          const double c[3] = {ax[q + l], ay[q + l], az[q + l]}, u[3] = {h * dx, h * dy, h * dz};
          for (std::size_t m = 0; m < 3; ++m) {
            acc[m][l] += f * c[m];
            for (std::size_t n = 0; n < 3; ++n) gj[m][n][l] += c[m] * u[n];
          }
        }
      }
      for (std::size_t m = 0; m < 3; ++m)
        for (std::size_t l = 0; l < L; ++l) {
          d[m] += acc[m][l];
          for (std::size_t n = 0; n < 3; ++n) j[m][n] += gj[m][n][l];
        }
    }
    blk.finish(i, d);
    // t is x / R: dd/dx is the sum over t divided by R; the polynomial's linear part is B^T / scale.
    for (std::size_t m = 0; m < 3; ++m)
      for (std::size_t n = 0; n < 3; ++n) {
        double v = j[m][n] * blk.inv_r;
        if (poly) v += poly->b[1 + n][m] * poly->inv_scale;
        jac[9 * i + 3 * m + n] = double(m == n) + phase * v;
      }
  }
}

}  // namespace
}  // namespace csrbf::detail
