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

// The vector of 8 lanes for T, and its operations.
template <class T> struct V8;
template <> struct V8<double> {
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
template <> struct V8<float> {
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

struct Avx512Run {
  template <Kernel K, class T, std::size_t P>
  static inline __attribute__((always_inline)) void sum(const EvalData<T>& a, std::uint32_t b, std::uint32_t e,
                                                        const T (&t)[P][3], T (&d)[P][3]) {
    static_assert(EvalGrid::kLanes == 8, "one vector of 8 lanes a block");
    using O = V8<T>;
    using v = typename O::v;
    const v one = O::set1(T(1)), tiny = O::set1(O::tiny);
    v tx[P], ty[P], tz[P], acc[P][3];
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
#pragma GCC unroll 4
    for (std::size_t p = 0; p < P; ++p)
      for (std::size_t c = 0; c < 3; ++c) d[p][c] += O::hsum(acc[p][c]);
  }
};

template <class T>
void dispatch(const EvalGrid& g, const EvalData<T>& a, Kernel kernel, const PolynomialPart* poly, const T* in,
              T* out, std::size_t begin, std::size_t end, double phase, bool add_point) {
  switch (kernel) {
    case Kernel::C0: return evaluate_block<Kernel::C0, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C2: return evaluate_block<Kernel::C2, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C4: return evaluate_block<Kernel::C4, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
    case Kernel::C6: return evaluate_block<Kernel::C6, T, Avx512Run>(g, a, poly, in, out, begin, end, phase, add_point);
  }
}

}  // namespace

void evaluate_avx512(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly,
                     const double* in, double* out, std::size_t begin, std::size_t end, double phase,
                     bool add_point) {
  dispatch(g, a, kernel, poly, in, out, begin, end, phase, add_point);
}

void evaluate_avx512(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly,
                     const float* in, float* out, std::size_t begin, std::size_t end, double phase,
                     bool add_point) {
  dispatch(g, a, kernel, poly, in, out, begin, end, phase, add_point);
}

}  // namespace csrbf::detail
