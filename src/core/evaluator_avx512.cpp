// The fast evaluation loop in AVX-512 (this file is compiled with -march=x86-64-v4 and called only
// when the CPU has it; see evaluate() in evaluator.cpp).
//
// Why by hand: the portable loop is bound by the square root. vsqrtpd on 8 doubles issues about
// once every 16-20 cycles on the CPUs we measured (AMD Zen 4), which is most of a candidate's cost.
// Here r = sqrt(r2) comes from vrsqrt14 (14 correct bits, pipelined like a multiply) and one
// polynomial correction (see root()). Several points share each block of the run (kGroup).
#include "eval_kernel.hpp"

#include <immintrin.h>

// GCC 12 warns on its own intrinsics headers (_mm512_undefined_pd in the reductions).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

namespace csrbf::detail {
namespace {

// r = sqrt(r2) from y = vrsqrt14(r2) (relative error below 2^-14) and one correction of third
// order: with r0 = r2 y and e = 1 - r0 y, sqrt(r2) = r0 (1 - e)^-1/2 = r0 (1 + e/2 + 3e^2/8 +
// 5e^3/16 + ...), whose first neglected term, 35e^4/128, is below 2^-54.
// r2 is clamped to [1e-300, 1] by the caller.
inline __attribute__((always_inline)) __m512d root(__m512d r2) {
  const __m512d y = _mm512_rsqrt14_pd(r2);
  const __m512d r0 = _mm512_mul_pd(r2, y);
  const __m512d e = _mm512_fnmadd_pd(r0, y, _mm512_set1_pd(1.0));
  __m512d c = _mm512_fmadd_pd(e, _mm512_set1_pd(5.0 / 16.0), _mm512_set1_pd(3.0 / 8.0));
  c = _mm512_fmadd_pd(c, e, _mm512_set1_pd(0.5));
  return _mm512_fmadd_pd(r0, _mm512_mul_pd(c, e), r0);
}
// float: the first-order correction, r0 (1 + e/2), leaves about 3e^2/8 < 2^-27.
inline __attribute__((always_inline)) __m256 root(__m256 r2) {
  const __m256 y = _mm256_rsqrt14_ps(r2);
  const __m256 r0 = _mm256_mul_ps(r2, y);
  const __m256 e = _mm256_fnmadd_ps(r0, y, _mm256_set1_ps(1.0f));
  return _mm256_fmadd_ps(r0, _mm256_mul_ps(e, _mm256_set1_ps(0.5f)), r0);
}

// 16 floats: as the 8 above.
inline __attribute__((always_inline)) __m512 root(__m512 r2) {
  const __m512 y = _mm512_rsqrt14_ps(r2);
  const __m512 r0 = _mm512_mul_ps(r2, y);
  const __m512 e = _mm512_fnmadd_ps(r0, y, _mm512_set1_ps(1.0f));
  return _mm512_fmadd_ps(r0, _mm512_mul_ps(e, _mm512_set1_ps(0.5f)), r0);
}
/// root() for the one-point-a-lane loop of normals_block: a full vector of float or double.
struct Avx512Root {
  template <class V>
  static inline __attribute__((always_inline)) V clipped_root(V r2) {
    if constexpr (sizeof(r2[0]) == sizeof(float))
      return V(detail::root(_mm512_min_ps(__m512(r2), _mm512_set1_ps(1.0f))));
    else
      return V(detail::root(_mm512_min_pd(__m512d(r2), _mm512_set1_pd(1.0))));
  }
  /// 1 / sqrt(b): in float the reciprocal root estimate (2^-14) after one Newton step (2^-27); in
  /// double correctly rounded.
  template <class V>
  static inline __attribute__((always_inline)) V inv_root(V b) {
    if constexpr (sizeof(b[0]) == sizeof(float)) {
      const __m512 y = _mm512_rsqrt14_ps(__m512(b));
      const __m512 e = _mm512_fnmadd_ps(_mm512_mul_ps(__m512(b), y), y, _mm512_set1_ps(1.0f));
      return V(_mm512_fmadd_ps(_mm512_mul_ps(y, e), _mm512_set1_ps(0.5f), y));
    } else {
      return V(_mm512_div_pd(_mm512_set1_pd(1.0), _mm512_sqrt_pd(__m512d(b))));
    }
  }
  template <class V>
  static inline __attribute__((always_inline)) V root(V a) {
    if constexpr (sizeof(a[0]) == sizeof(float))
      return V(_mm512_sqrt_ps(__m512(a)));
    else
      return V(_mm512_sqrt_pd(__m512d(a)));
  }
};

// The vector of 8 lanes for T, and its operations.
template <class T>
struct V8;
template <>
struct V8<double> {
  using v = __m512d;
  static v load(const double* p) { return _mm512_loadu_pd(p); }
  static v set1(double x) { return _mm512_set1_pd(x); }
  static v zero() { return _mm512_setzero_pd(); }
  static v sub(v a, v b) { return _mm512_sub_pd(a, b); }
  static v mul(v a, v b) { return _mm512_mul_pd(a, b); }
  static v fmadd(v a, v b, v c) { return _mm512_fmadd_pd(a, b, c); }
  static v min(v a, v b) { return _mm512_min_pd(a, b); }
  static v max(v a, v b) { return _mm512_max_pd(a, b); }
  static constexpr double tiny = 1e-300;
  static double hsum(v a) { return _mm512_reduce_add_pd(a); }
};
template <>
struct V8<float> {
  using v = __m256;
  static v load(const float* p) { return _mm256_loadu_ps(p); }
  static v set1(float x) { return _mm256_set1_ps(x); }
  static v zero() { return _mm256_setzero_ps(); }
  static v sub(v a, v b) { return _mm256_sub_ps(a, b); }
  static v mul(v a, v b) { return _mm256_mul_ps(a, b); }
  static v fmadd(v a, v b, v c) { return _mm256_fmadd_ps(a, b, c); }
  static v min(v a, v b) { return _mm256_min_ps(a, b); }
  static v max(v a, v b) { return _mm256_max_ps(a, b); }
  static constexpr float tiny = 1e-30f;
  static float hsum(v a) {
    __m128 s = _mm_add_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    s = _mm_add_ss(s, _mm_movehdup_ps(s));
    return _mm_cvtss_f32(s);
  }
};

/// The AVX-512 vector of T.
template <class T>
struct Zmm {
  using type = __m512d;
};
template <>
struct Zmm<float> {
  using type = __m512;
};

/// The permutes of Avx512Run::load3 and store3 for a full vector of T: index vectors for
/// permutex2var, whose indices 0 .. W-1 take the first operand and W .. 2W-1 the second.
template <class T>
struct Perm {
  static constexpr int W = 64 / sizeof(T);
  using v = typename Zmm<T>::type;
  struct Vec {
    static v load(const T* p) {
      if constexpr (std::is_same_v<T, float>)
        return _mm512_loadu_ps(p);
      else
        return _mm512_loadu_pd(p);
    }
    static void store(T* p, v a) {
      if constexpr (std::is_same_v<T, float>)
        _mm512_storeu_ps(p, a);
      else
        _mm512_storeu_pd(p, a);
    }
    static v permute2(v a, __m512i idx, v b) {
      if constexpr (std::is_same_v<T, float>)
        return _mm512_permutex2var_ps(a, idx, b);
      else
        return _mm512_permutex2var_pd(a, idx, b);
    }
  } vec;
  __m512i gather_ab[3], gather_c[3], scatter_xy[3], scatter_z[3];
  Perm() {
    for (int c = 0; c < 3; ++c) {
      alignas(64) std::int64_t i64[4][8];
      alignas(64) std::int32_t i32[4][16];
      for (int l = 0; l < W; ++l) {
        // Load: lane l of component c is element e = 3 l + c of the 3 W triples' values.
        const int e = 3 * l + c;
        const int ab = e < 2 * W ? e : l, cc = e < 2 * W ? l : W + (e - 2 * W);
        // Store: element e = k W + l of output vector k is lane e / 3 of component e % 3.
        const int f = c * W + l, lane = f / 3, comp = f % 3;
        const int xy = comp == 0 ? lane : comp == 1 ? W + lane : l, z = comp == 2 ? W + lane : l;
        const int idx[4] = {ab, cc, xy, z};
        for (int q = 0; q < 4; ++q) {
          if constexpr (W == 8)
            i64[q][l] = idx[q];
          else
            i32[q][l] = idx[q];
        }
      }
      __m512i* out[4] = {&gather_ab[c], &gather_c[c], &scatter_xy[c], &scatter_z[c]};
      for (int q = 0; q < 4; ++q) *out[q] = W == 8 ? _mm512_load_si512(i64[q]) : _mm512_load_si512(i32[q]);
    }
  }
};

struct Avx512Run : PortableRun {
  /// The CSRBF sums of P points over the run [b, e), left in one vector per point and component.
  template <Kernel K, class T, std::size_t P>
  static inline __attribute__((always_inline)) void accumulate(const EvalData<T>& a, std::uint32_t b, std::uint32_t e,
                                                               const T (&t)[P][3], typename V8<T>::v (&acc)[P][3]) {
    static_assert(EvalGrid::kLanes == 8, "one vector of 8 lanes a block");
    using O = V8<T>;
    using v = typename O::v;
    const v one = O::set1(T(1)), tiny = O::set1(O::tiny);
    v tx[P], ty[P], tz[P];
#pragma GCC unroll 4
    for (std::size_t p = 0; p < P; ++p) {
      tx[p] = O::set1(t[p][0]), ty[p] = O::set1(t[p][1]), tz[p] = O::set1(t[p][2]);
      acc[p][0] = acc[p][1] = acc[p][2] = O::zero();
    }
    for (std::uint32_t j = b; j < e; j += 8) {
      const v sx = O::load(a.x.data() + j), sy = O::load(a.y.data() + j), sz = O::load(a.z.data() + j);
      const v ax = O::load(a.ax.data() + j), ay = O::load(a.ay.data() + j), az = O::load(a.az.data() + j);
#pragma GCC unroll 4
      for (std::size_t p = 0; p < P; ++p) {
        const v ddx = O::sub(sx, tx[p]), ddy = O::sub(sy, ty[p]), ddz = O::sub(sz, tz[p]);
        const v r2 = O::fmadd(ddz, ddz, O::fmadd(ddy, ddy, O::mul(ddx, ddx)));
        // r2 = 0 (a point on a source) would make rsqrt infinite; beyond R, r = 1 up to rounding,
        // where phi is below 1e-30 of its peak.
        const v r = root(O::min(O::max(r2, tiny), one));
        const v f = phi<K, v, T>(r);
        acc[p][0] = O::fmadd(f, ax, acc[p][0]);
        acc[p][1] = O::fmadd(f, ay, acc[p][1]);
        acc[p][2] = O::fmadd(f, az, acc[p][2]);
      }
    }
  }

  template <Kernel K, class T, std::size_t P>
  static inline __attribute__((always_inline)) void sum(const EvalData<T>& a, std::uint32_t b, std::uint32_t e,
                                                        const T (&t)[P][3], T (&d)[P][3]) {
    typename V8<T>::v acc[P][3];
    accumulate<K, T, P>(a, b, e, t, acc);
#pragma GCC unroll 4
    for (std::size_t p = 0; p < P; ++p)
      for (std::size_t c = 0; c < 3; ++c) d[p][c] += V8<T>::hsum(acc[p][c]);
  }

  /// The cells and limits of points first .. first + n - 1: 8 at a time in vectors, with the same
  /// arithmetic as Block::cell_of (which takes the rest).
  template <class T>
  static inline __attribute__((always_inline)) void cells(const Block<T>& k, std::size_t first, std::size_t n,
                                                          std::size_t* cell, float* limit) {
    const EvalGrid& g = k.g;
    const __m512d ox = _mm512_set1_pd(g.origin.x()), oy = _mm512_set1_pd(g.origin.y()),
                  oz = _mm512_set1_pd(g.origin.z()), ih = _mm512_set1_pd(g.inv_h), zero = _mm512_setzero_pd();
    const __m512d nx = _mm512_set1_pd(double(g.nx)), ny = _mm512_set1_pd(double(g.ny)),
                  nz = _mm512_set1_pd(double(g.nz));
    const __m512i inx = _mm512_set1_epi64(g.nx), iny = _mm512_set1_epi64(g.ny),
                  outside = _mm512_set1_epi64(std::int64_t(Block<T>::none));
    // x y z of 8 points from 24 interleaved values v0 | v1 | v2: two permutes each.
    const __m512i x01 = _mm512_setr_epi64(0, 3, 6, 9, 12, 15, 0, 0), x2 = _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 10, 13);
    const __m512i y01 = _mm512_setr_epi64(1, 4, 7, 10, 13, 0, 0, 0), y2 = _mm512_setr_epi64(0, 1, 2, 3, 4, 8, 11, 14);
    const __m512i z01 = _mm512_setr_epi64(2, 5, 8, 11, 14, 0, 0, 0), z2 = _mm512_setr_epi64(0, 1, 2, 3, 4, 9, 12, 15);
    constexpr int down = _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC;
    const __m512d half = _mm512_set1_pd(0.5), h_over_r = _mm512_set1_pd(k.h_over_r),
                  slack = _mm512_set1_pd(Block<T>::kLimitSlack);
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
      const T* p = k.in + 3 * (first + i);
      __m512d v0, v1, v2;
      if constexpr (std::is_same_v<T, double>) {
        v0 = _mm512_loadu_pd(p), v1 = _mm512_loadu_pd(p + 8), v2 = _mm512_loadu_pd(p + 16);
      } else {
        v0 = _mm512_cvtps_pd(_mm256_loadu_ps(p)), v1 = _mm512_cvtps_pd(_mm256_loadu_ps(p + 8));
        v2 = _mm512_cvtps_pd(_mm256_loadu_ps(p + 16));
      }
      const __m512d x = _mm512_permutex2var_pd(_mm512_permutex2var_pd(v0, x01, v1), x2, v2);
      const __m512d y = _mm512_permutex2var_pd(_mm512_permutex2var_pd(v0, y01, v1), y2, v2);
      const __m512d z = _mm512_permutex2var_pd(_mm512_permutex2var_pd(v0, z01, v1), z2, v2);
      const __m512d ux = _mm512_mul_pd(_mm512_sub_pd(x, ox), ih), uy = _mm512_mul_pd(_mm512_sub_pd(y, oy), ih),
                    uz = _mm512_mul_pd(_mm512_sub_pd(z, oz), ih);
      const __m512d fx = _mm512_roundscale_pd(ux, down), fy = _mm512_roundscale_pd(uy, down),
                    fz = _mm512_roundscale_pd(uz, down);
      const __m512d dx = _mm512_sub_pd(_mm512_sub_pd(ux, fx), half), dy = _mm512_sub_pd(_mm512_sub_pd(uy, fy), half),
                    dz = _mm512_sub_pd(_mm512_sub_pd(uz, fz), half);
      const __m512d d2 =
          _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
      _mm256_storeu_ps(limit + i, _mm512_cvtpd_ps(_mm512_add_pd(_mm512_mul_pd(_mm512_sqrt_pd(d2), h_over_r), slack)));
      // Ordered comparisons: false for NaN.
      __mmask8 in = _mm512_cmp_pd_mask(fx, zero, _CMP_GE_OQ);
      in = _mm512_mask_cmp_pd_mask(in, fy, zero, _CMP_GE_OQ);
      in = _mm512_mask_cmp_pd_mask(in, fz, zero, _CMP_GE_OQ);
      in = _mm512_mask_cmp_pd_mask(in, fx, nx, _CMP_LT_OQ);
      in = _mm512_mask_cmp_pd_mask(in, fy, ny, _CMP_LT_OQ);
      in = _mm512_mask_cmp_pd_mask(in, fz, nz, _CMP_LT_OQ);
      const __m512i c = _mm512_add_epi64(
          _mm512_mullo_epi64(
              _mm512_add_epi64(_mm512_mullo_epi64(_mm512_cvttpd_epi64(fz), iny), _mm512_cvttpd_epi64(fy)), inx),
          _mm512_cvttpd_epi64(fx));
      static_assert(sizeof(std::size_t) == 8, "cells are stored as 64-bit lanes");
      _mm512_storeu_si512(cell + i, _mm512_mask_mov_epi64(outside, in, c));
    }
    for (; i < n; ++i) cell[i] = k.cell_of(first + i, limit[i]);
  }

  /// Interleaved triples to and from component-major lanes: a full vector of float or double (W
  /// = 16 or 8) as three loads or stores and two permutes a vector; partial groups as PortableRun.
  /// Lane l's component c is element 3 l + c of the triples, in vector (3 l + c) / W.
  template <class T, std::size_t W>
  static inline __attribute__((always_inline)) void load3(const T* p, std::size_t m, T (&o)[3][W]) {
    if constexpr (W * sizeof(T) != 64) {
      PortableRun::load3(p, m, o);
    } else {
      if (m != W) return PortableRun::load3(p, m, o);
      static const Perm<T> perm;
      const auto v = perm.vec;
      const typename Perm<T>::v in[3] = {v.load(p), v.load(p + W), v.load(p + 2 * W)};
      for (int c = 0; c < 3; ++c) {
        // Elements of the first two vectors, then those of the third over them.
        const auto t = v.permute2(in[0], perm.gather_ab[c], in[1]);
        v.store(o[c], v.permute2(t, perm.gather_c[c], in[2]));
      }
    }
  }
  template <class T, std::size_t W>
  static inline __attribute__((always_inline)) void store3(T* p, std::size_t m, const T (&o)[3][W]) {
    if constexpr (W * sizeof(T) != 64) {
      PortableRun::store3(p, m, o);
    } else {
      if (m != W) return PortableRun::store3(p, m, o);
      static const Perm<T> perm;
      const auto v = perm.vec;
      const typename Perm<T>::v x = v.load(o[0]), y = v.load(o[1]), z = v.load(o[2]);
      for (int k = 0; k < 3; ++k) {
        // x and y's elements first, then z's over them.
        const auto t = v.permute2(x, perm.scatter_xy[k], y);
        v.store(p + k * W, v.permute2(t, perm.scatter_z[k], z));
      }
    }
  }

  /// Double precision: the 12 sums of a group are reduced together (a transposed tree of shuffles,
  /// about a third of 12 separate reductions) into the layout of the output, x0 y0 z0 x1 ... z3,
  /// and finished as two vectors. Float takes the generic path.
  template <Kernel K, class Run, class T>
  static inline __attribute__((always_inline)) void group(const Block<T>& k, std::uint32_t b, std::uint32_t e,
                                                          std::size_t i) {
    if constexpr (!std::is_same_v<T, double>) {
      PortableRun::group<K, Run>(k, b, e, i);
    } else {
      static_assert(kGroup == 4, "12 sums: 4 points, 3 components");
      double t[kGroup][3];
      for (std::size_t p = 0; p < kGroup; ++p) k.local(i + p, t[p]);
      __m512d acc[kGroup][3];
      accumulate<K, double, kGroup>(k.a, b, e, t, acc);
      const __m512d* s = &acc[0][0];  // sum m of the output: s[m], m = 3 point + component
      // Step 1: pairs (a, b) -> 128-bit lanes [a', a'', b', b''] whose halves sum to a and b.
      const auto fold4 = [](__m512d a, __m512d b) {
        return _mm512_add_pd(_mm512_shuffle_f64x2(a, b, 0x44), _mm512_shuffle_f64x2(a, b, 0xEE));
      };
      // Step 2: two of those -> one 128-bit lane (2 partial sums) per output.
      const auto fold2 = [](__m512d a, __m512d b) {
        return _mm512_add_pd(_mm512_shuffle_f64x2(a, b, 0x88), _mm512_shuffle_f64x2(a, b, 0xDD));
      };
      const __m512d even = fold2(fold4(s[0], s[2]), fold4(s[4], s[6]));    // outputs 0 2 4 6
      const __m512d odd = fold2(fold4(s[1], s[3]), fold4(s[5], s[7]));     // outputs 1 3 5 7
      const __m512d last = fold2(fold4(s[8], s[9]), fold4(s[10], s[11]));  // outputs 8 9 10 11
      // Step 3: the pairs' halves; the first 8 outputs interleave into order.
      __m512d lo = _mm512_add_pd(_mm512_unpacklo_pd(even, odd), _mm512_unpackhi_pd(even, odd));
      __m512d hi = _mm512_permutexvar_pd(_mm512_setr_epi64(0, 2, 4, 6, 0, 2, 4, 6),
                                         _mm512_add_pd(last, _mm512_permute_pd(last, 0x55)));
      const double* in = k.in + 3 * i;
      const __m512d in_lo = _mm512_loadu_pd(in), in_hi = _mm512_castpd256_pd512(_mm256_loadu_pd(in + 8));
      if (k.poly) {
        // As Block::finish: b0 + u0 b1 + u1 b2 + u2 b3, u = (p - center) / scale, per output lane.
        const PolynomialPart& q = *k.poly;
        const __m512i comp_lo = _mm512_setr_epi64(0, 1, 2, 0, 1, 2, 0, 1),
                      comp_hi = _mm512_setr_epi64(2, 0, 1, 2, 2, 2, 2, 2);
        const __m512d is = _mm512_set1_pd(q.inv_scale);
        __m512d plo, phi_;
        for (int r = 0; r < 4; ++r) {
          const __m512d row = _mm512_castpd256_pd512(_mm256_setr_pd(q.b[r][0], q.b[r][1], q.b[r][2], 0.0));
          const __m512d blo = _mm512_permutexvar_pd(comp_lo, row), bhi = _mm512_permutexvar_pd(comp_hi, row);
          if (r == 0) {
            plo = blo, phi_ = bhi;
            continue;
          }
          const int c = r - 1;  // the coordinate that multiplies row r
          const __m512i ilo = _mm512_add_epi64(_mm512_setr_epi64(0, 0, 0, 3, 3, 3, 6, 6), _mm512_set1_epi64(c));
          const __m512i ihi = _mm512_add_epi64(_mm512_setr_epi64(6, 9, 9, 9, 9, 9, 9, 9), _mm512_set1_epi64(c));
          const __m512d ctr = _mm512_set1_pd(q.center[c]);
          const __m512d ulo = _mm512_mul_pd(_mm512_sub_pd(_mm512_permutex2var_pd(in_lo, ilo, in_hi), ctr), is);
          const __m512d uhi = _mm512_mul_pd(_mm512_sub_pd(_mm512_permutex2var_pd(in_lo, ihi, in_hi), ctr), is);
          plo = _mm512_add_pd(plo, _mm512_mul_pd(ulo, blo));
          phi_ = _mm512_add_pd(phi_, _mm512_mul_pd(uhi, bhi));
        }
        lo = _mm512_add_pd(lo, plo);
        hi = _mm512_add_pd(hi, phi_);
      }
      if (k.add_point) {
        const __m512d ph = _mm512_set1_pd(k.phase);
        lo = _mm512_add_pd(in_lo, _mm512_mul_pd(ph, lo));
        hi = _mm512_add_pd(in_hi, _mm512_mul_pd(ph, hi));
      }
      double* out = k.out + 3 * i;
      _mm512_storeu_pd(out, lo);
      _mm256_storeu_pd(out + 8, _mm512_castpd512_pd256(hi));
    }
  }
};

template <class T>
void dispatch(const EvalGrid& g, const EvalData<T>& a, Kernel kernel, const PolynomialPart* poly, const T* in, T* out,
              std::size_t begin, std::size_t end, double phase, bool add_point) {
  switch (kernel) {
    case Kernel::C0:
      return evaluate_block<Kernel::C0, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C2:
      return evaluate_block<Kernel::C2, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C4:
      return evaluate_block<Kernel::C4, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C6:
      return evaluate_block<Kernel::C6, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
  }
}

/// A full AVX-512 vector a group: 16 points in float, 8 in double.
template <class T>
void normals_dispatch(const EvalGrid& g, const EvalData<T>& a, Kernel kernel, const PolynomialPart* poly,
                      const NormalsJob<T>& job, std::size_t begin, std::size_t end) {
  constexpr std::size_t W = 64 / sizeof(T);
  switch (kernel) {
    case Kernel::C0:
      return normals_block<Kernel::C0, T, W, Avx512Run, Avx512Root>(g, a, poly, job, begin, end);
    case Kernel::C2:
      return normals_block<Kernel::C2, T, W, Avx512Run, Avx512Root>(g, a, poly, job, begin, end);
    case Kernel::C4:
      return normals_block<Kernel::C4, T, W, Avx512Run, Avx512Root>(g, a, poly, job, begin, end);
    case Kernel::C6:
      return normals_block<Kernel::C6, T, W, Avx512Run, Avx512Root>(g, a, poly, job, begin, end);
  }
}

}  // namespace

void evaluate_normals_avx512(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly,
                             const NormalsJob<double>& job, std::size_t begin, std::size_t end) {
  normals_dispatch(g, a, kernel, poly, job, begin, end);
}
void evaluate_normals_avx512(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly,
                             const NormalsJob<float>& job, std::size_t begin, std::size_t end) {
  normals_dispatch(g, a, kernel, poly, job, begin, end);
}

void evaluate_avx512(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly,
                     const double* in, double* out, std::size_t begin, std::size_t end, double phase, bool add_point) {
  dispatch(g, a, kernel, poly, in, out, begin, end, phase, add_point);
}

void evaluate_avx512(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly,
                     const float* in, float* out, std::size_t begin, std::size_t end, double phase, bool add_point) {
  dispatch(g, a, kernel, poly, in, out, begin, end, phase, add_point);
}

}  // namespace csrbf::detail
