// Evaluation of a fitted SpaceMap: through the neighbour grid's runs (evaluator.hpp), sorted by cell
// when the points come in no spatial order, or point by point through NeighborIndex; the Jacobian;
// float evaluation where it can be trusted.
#include "fit_state.hpp"

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <type_traits>

namespace csrbf {

void set_evaluation_loop(EvaluationLoop loop) {
  if (loop == EvaluationLoop::Avx512 && !detail::avx512_available())
    throw InvalidInput("evaluation loop 'avx512': this CPU or this build of csrbf has no AVX-512; use 'portable'");
  detail::set_eval_isa(loop == EvaluationLoop::Portable ? detail::EvalIsa::Portable : detail::EvalIsa::Avx512);
}

std::string_view evaluation_loop_name() noexcept {
  if (detail::eval_isa() == detail::EvalIsa::Avx512) return "avx512";
#if defined(__x86_64__) && defined(__GNUC__)
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "avx2";
#endif
  return "baseline";
}

Vec3 SpaceMap::displacement(const Vec3& x) const {
  const Structure& st = *s_->st;
  const double inv_r = 1.0 / st.options.radius;
  const Kernel k = st.options.kernel;
  Vec3 d = Vec3::Zero();
  const std::vector<Vec3>& alpha = s_->alpha_by_slot();
  st.index().for_each_slot_within(
      x, [&](std::size_t slot, double d2) { d += wendland(k, std::sqrt(d2) * inv_r) * alpha[slot]; });
  if (st.terms > 0) d += s_->polynomial_at(x);
  return d;
}

Eigen::Matrix3d SpaceMap::jacobian(const Vec3& x, double phase) const {
  const Structure& st = *s_->st;
  const double inv_r = 1.0 / st.options.radius;
  const Kernel k = st.options.kernel;
  Eigen::Matrix3d j = Eigen::Matrix3d::Zero();
  const NeighborIndex& index = st.index();
  const std::vector<Vec3>& alpha = s_->alpha_by_slot();
  index.for_each_slot_within(x, [&](std::size_t slot, double d2) {
    const double dist = std::sqrt(d2);
    if (dist == 0.0) return;  // grad phi(0) = 0 for C2+; the one-sided C0 cone has no gradient there
    const Vec3 grad = (wendland_derivative(k, dist * inv_r) * inv_r / dist) * (x - index.point(slot));
    j += alpha[slot] * grad.transpose();
  });
  if (st.terms == 4) j += s_->beta.bottomRows<3>().transpose() / st.scale;
  return Eigen::Matrix3d::Identity() + phase * j;
}

bool SpaceMap::float_trusted() const {
  std::call_once(s_->once_float_trust, [this] {
    // Single-precision evaluation sums terms of the coefficients' size: when they are far larger
    // than the displacements (an ill-conditioned fit) or the model sits far from the origin, the
    // float sum can be garbage although the double one is exact. Compare both on (a seeded sample
    // of) the sources, rounded to float first so that only the evaluation differs.
    // Measured on the sources and on as many points between them (each a sampled source moved by
    // up to 0.9 R in a random direction), where the sum's terms cancel most: the sources alone
    // passed maps whose float error elsewhere reached 2.2 times the tolerance (issue 30). A map is
    // trusted only within a quarter of the tolerance, the margin for points not sampled.
    const Structure& st = *s_->st;
    const std::size_t n = st.sources().size(), ms = std::min<std::size_t>(n, 4096), m = 2 * ms;
    std::mt19937_64 rng(20261201);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    std::vector<float> inf(3 * m), outf(3 * m);
    std::vector<double> ind(3 * m), outd(3 * m);
    double gmax = 0;
    if (s_->destinations.size() == n)
      for (std::size_t i = 0; i < n; ++i) gmax = std::max(gmax, (s_->destinations[i] - st.sources()[i]).norm());
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t i = ms == n ? k % n : std::size_t(rng() % n);
      Vec3 p = st.sources()[i];
      if (k >= ms) {
        Vec3 u;
        do u = Vec3(unit(rng), unit(rng), unit(rng));
        while (u.squaredNorm() > 1.0 || u.squaredNorm() < 1e-6);
        p += 0.9 * st.options.radius * u;
      }
      for (int c = 0; c < 3; ++c) {
        inf[3 * k + std::size_t(c)] = float(p[c]);
        ind[3 * k + std::size_t(c)] = double(inf[3 * k + std::size_t(c)]);
      }
    }
    apply_direct(inf.data(), outf.data(), m, 1.0, false);
    apply_direct(ind.data(), outd.data(), m, 1.0, false);
    if (s_->destinations.size() != n)  // from_solution: the displacements at the sample stand in
      for (std::size_t k = 0; k < m; ++k)
        gmax = std::max(gmax, Vec3(outd[3 * k], outd[3 * k + 1], outd[3 * k + 2]).norm());
    double err = 0;
    for (std::size_t k = 0; k < 3 * m; ++k) {
      const double e = std::abs(double(outf[k]) - outd[k]);
      err = std::isnan(e) ? std::numeric_limits<double>::infinity() : std::max(err, e);
    }
    s_->float_error = err;
    s_->float_ok = gmax == 0 ? err == 0 : err <= 0.25 * kFloatTolerance * gmax;
  });
  return s_->float_ok;
}

bool SpaceMap::float_normals_trusted() const {
  if (!float_trusted()) return false;
  std::call_once(s_->once_normals_trust, [this] {
    // The Jacobian's float sums lose more than the displacement's where the coefficients are large
    // (C6, ill-conditioned fits: 3e-5 rad where double is exact). The sample of float_trusted
    // (sources, and sources moved up to 0.9 R), each with a normal of its own, in both precisions.
    const Structure& st = *s_->st;
    const detail::EvalGrid& grid = st.grid();
    if (!grid.usable) return;  // point by point, in double anyway
    const std::size_t n = st.sources().size(), ms = std::min<std::size_t>(n, 4096), m = 2 * ms;
    std::mt19937_64 rng(20261204);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    std::vector<float> pf(3 * m), nf(3 * m);
    std::vector<double> pd(3 * m), nd(3 * m);
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t i = ms == n ? k % n : std::size_t(rng() % n);
      Vec3 p = st.sources()[i], u;
      do u = Vec3(unit(rng), unit(rng), unit(rng));
      while (u.squaredNorm() > 1.0 || u.squaredNorm() < 1e-6);
      if (k >= ms) p += 0.9 * st.options.radius * u;
      u.normalize();
      for (int c = 0; c < 3; ++c) {
        const std::size_t at = 3 * k + std::size_t(c);
        pf[at] = float(p[c]), nf[at] = float(u[c]);
        pd[at] = double(pf[at]), nd[at] = double(nf[at]);
      }
    }
    const detail::PolynomialPart* poly = st.terms > 0 ? &s_->poly : nullptr;
    const Kernel k = st.options.kernel;
    detail::evaluate_normals(grid, s_->template eval_data<float>(), k, poly,
                             detail::NormalsJob<float>{pf.data(), pf.data(), nf.data(), nf.data()}, 0, m);
    detail::evaluate_normals(grid, s_->template eval_data<double>(), k, poly,
                             detail::NormalsJob<double>{pd.data(), pd.data(), nd.data(), nd.data()}, 0, m);
    double worst = 0;
    for (std::size_t i = 0; i < m; ++i) {
      const Vec3 a(nf[3 * i], nf[3 * i + 1], nf[3 * i + 2]), b(nd[3 * i], nd[3 * i + 1], nd[3 * i + 2]);
      const double angle = std::atan2(a.cross(b).norm(), a.dot(b));
      worst = std::isnan(angle) ? std::numeric_limits<double>::infinity() : std::max(worst, angle);
    }
    s_->float_normals_ok = worst <= 0.25 * kFloatNormalRadians;
  });
  return s_->float_normals_ok;
}

template <class T>
void SpaceMap::apply_impl(const T* in, T* out, std::size_t n, double phase, bool add_point) const {
  check_phase(phase);
  if constexpr (std::is_same_v<T, float>) {
    if (!float_trusted()) {
      // Evaluated in double, in blocks, and rounded once at the end.
      constexpr std::size_t block = 1 << 16;
      std::vector<double> a(3 * std::min(n, block)), b(a.size());
      for (std::size_t i0 = 0; i0 < n; i0 += block) {
        const std::size_t m = std::min(block, n - i0);
        for (std::size_t k = 0; k < 3 * m; ++k) a[k] = double(in[3 * i0 + k]);
        apply_direct(a.data(), b.data(), m, phase, add_point);
        for (std::size_t k = 0; k < 3 * m; ++k) out[3 * i0 + k] = float(b[k]);
      }
      return;
    }
  }
  apply_direct(in, out, n, phase, add_point);
}

template <class T>
void SpaceMap::apply_direct(const T* in, T* out, std::size_t n, double phase, bool add_point) const {
  const Structure& st = *s_->st;
  const detail::EvalGrid& grid = st.grid();
  if (grid.usable) {
    const detail::PolynomialPart* poly = st.terms > 0 ? &s_->poly : nullptr;
    const Kernel k = st.options.kernel;
    const detail::EvalData<T>& data = s_->template eval_data<T>();
    // Small batches in the calling thread: a task switch costs more than a game mesh's evaluation.
    constexpr std::size_t grain = 4096;
    if (n <= grain) {
      detail::evaluate(grid, data, k, poly, in, out, 0, n, phase, add_point);
      return;
    }
    if (n < (std::size_t(1) << 32) && detail::incoherent(grid, in, n)) {
      // Points in no spatial order: gathered by cell, evaluated in place, and written back in the
      // caller's order (in may be out: every point is read before any is written). The buffers stay
      // with the calling thread for its next batch.
      thread_local detail::CellOrder<T> scratch;
      detail::order_by_cell(grid, in, n, scratch);
      const std::uint32_t* order = scratch.order.data();
      scratch.points.resize(3 * n);
      T* points = scratch.points.data();
      // The gather and the scatter touch the caller's arrays at random: prefetched a few points
      // ahead, so that several misses are in flight at once.
      constexpr std::size_t ahead = 16;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t j = r.begin(); j < r.end(); ++j) {
          if (j + ahead < n) __builtin_prefetch(in + 3 * std::size_t(order[j + ahead]));
          for (int c = 0; c < 3; ++c) points[3 * j + c] = in[3 * std::size_t(order[j]) + c];
        }
        detail::evaluate(grid, data, k, poly, points, points, r.begin(), r.end(), phase, add_point);
      });
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t j = r.begin(); j < r.end(); ++j) {
          if (j + ahead < n) __builtin_prefetch(out + 3 * std::size_t(order[j + ahead]), 1);
          for (int c = 0; c < 3; ++c) out[3 * std::size_t(order[j]) + c] = points[3 * j + c];
        }
      });
      return;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
      detail::evaluate(grid, data, k, poly, in, out, r.begin(), r.end(), phase, add_point);
    });
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 2048), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const Vec3 x{double(in[3 * i]), double(in[3 * i + 1]), double(in[3 * i + 2])};
      const Vec3 d = displacement(x);
      if (add_point) {
        out[3 * i] = T(x.x() + phase * d.x());
        out[3 * i + 1] = T(x.y() + phase * d.y());
        out[3 * i + 2] = T(x.z() + phase * d.z());
      } else {
        out[3 * i] = T(d.x());
        out[3 * i + 1] = T(d.y());
        out[3 * i + 2] = T(d.z());
      }
    }
  });
}

void SpaceMap::apply(const double* in, double* out, std::size_t n, double phase) const {
  apply_impl(in, out, n, phase, true);
}
void SpaceMap::apply(const float* in, float* out, std::size_t n, double phase) const {
  apply_impl(in, out, n, phase, true);
}
void SpaceMap::apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) const {
  if (in.size() != out.size()) throw InvalidInput("apply: input and output sizes differ");
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three packed doubles");
  apply_impl(in.data()->data(), out.data()->data(), in.size(), phase, true);
}
namespace {
/// n' = J^-T n, scaled to |n|: the cofactor matrix of J (det J times J^-T) times n, its sign
/// det J's, so that a normal keeps its side of the surface where the map folds it over.
void transform_normal(const double* j, const double* n, bool unit, double* out) {
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> jm(j);
  Eigen::Matrix3d cof;
  cof.col(0) = jm.col(1).cross(jm.col(2));
  cof.col(1) = jm.col(2).cross(jm.col(0));
  cof.col(2) = jm.col(0).cross(jm.col(1));
  // J^-1's rows are (j1 x j2, j2 x j0, j0 x j1) / det for J's columns j0, j1, j2: cof = det(J) J^-T.
  const double det = jm.col(0).dot(cof.col(0));
  const Vec3 v(n[0], n[1], n[2]);
  Vec3 w = cof * v;
  // Scaled first: a huge Jacobian's cofactors overflow the squared norm (1e157 a component).
  const double big = w.cwiseAbs().maxCoeff();
  if (big > 0 && std::isfinite(big)) w /= big;
  const double len = w.norm(), want = unit ? 1.0 : v.norm();
  if (len > 0 && std::isfinite(len)) w *= (det < 0 ? -want : want) / len;
  out[0] = w.x();
  out[1] = w.y();
  out[2] = w.z();
}
}  // namespace

template <class T>
void SpaceMap::normals_impl(const T* in, T* out, std::size_t n, double phase, const T* normals_in, T* normals_out,
                            T* jacobians, bool unit) const {
  check_phase(phase);
  if ((normals_in == nullptr) != (normals_out == nullptr))
    throw InvalidInput("apply_with_normals: normals_in and normals_out must both be given or both be null");
  if constexpr (std::is_same_v<T, float>) {
    if (!float_normals_trusted()) {
      // Evaluated in double and rounded once at the end: blocks of `block` points in parallel,
      // each converted in its task into the task's buffers (a block's own call runs in that thread).
      // Converting the whole batch up front in the calling thread took 10x the float path's time
      // (page faults and one core). Not thread_local: a thread waiting inside a block's call (the
      // point-by-point path runs its own parallel_for) may take another block of this loop.
      constexpr std::size_t block = 4096;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, block), [&](const tbb::blocked_range<std::size_t>& r) {
        std::vector<double> p, nm, jac;
        for (std::size_t i0 = r.begin(); i0 < r.end(); i0 += block) {
          const std::size_t m = std::min(block, r.end() - i0);
          p.resize(3 * block), nm.resize(normals_in ? 3 * block : 0), jac.resize(jacobians ? 9 * block : 0);
          for (std::size_t k = 0; k < 3 * m; ++k) p[k] = double(in[3 * i0 + k]);
          for (std::size_t k = 0; normals_in && k < 3 * m; ++k) nm[k] = double(normals_in[3 * i0 + k]);
          double* pn = normals_in ? nm.data() : nullptr;
          normals_impl<double>(p.data(), p.data(), m, phase, pn, pn, jacobians ? jac.data() : nullptr, unit);
          for (std::size_t k = 0; k < 3 * m; ++k) out[3 * i0 + k] = float(p[k]);
          for (std::size_t k = 0; normals_in && k < 3 * m; ++k) normals_out[3 * i0 + k] = float(nm[k]);
          for (std::size_t k = 0; jacobians && k < 9 * m; ++k) jacobians[9 * i0 + k] = float(jac[k]);
        }
      });
      return;
    }
  }
  const Structure& st = *s_->st;
  const detail::EvalGrid& grid = st.grid();
  constexpr std::size_t grain = 4096;
  if (!grid.usable) {
    // No dense grid (sources too sparse for their box): point by point through the NeighborIndex.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i < r.end(); ++i) {
        const Vec3 x{double(in[3 * i]), double(in[3 * i + 1]), double(in[3 * i + 2])};
        const Eigen::Matrix3d j = jacobian(x, phase);
        const Vec3 y = x + phase * displacement(x);
        for (int c = 0; c < 3; ++c) out[3 * i + std::size_t(c)] = T(y[c]);
        if (jacobians)
          for (int a = 0; a < 3; ++a)
            for (int c = 0; c < 3; ++c) jacobians[9 * i + std::size_t(3 * a + c)] = T(j(a, c));
        if (normals_in) {
          const double nv[3] = {double(normals_in[3 * i]), double(normals_in[3 * i + 1]),
                                double(normals_in[3 * i + 2])};
          double jr[9], w[3];
          Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>{jr} = j;
          transform_normal(jr, nv, unit, w);
          for (int c = 0; c < 3; ++c) normals_out[3 * i + std::size_t(c)] = T(w[c]);
        }
      }
    });
    return;
  }
  const detail::PolynomialPart* poly = st.terms > 0 ? &s_->poly : nullptr;
  const detail::EvalData<T>& data = s_->template eval_data<T>();
  const Kernel k = st.options.kernel;
  const detail::NormalsJob<T> job{in, out, normals_in, normals_out, jacobians, phase, unit};
  if (n <= grain) {  // a game mesh's batch: in the calling thread
    detail::evaluate_normals(grid, data, k, poly, job, 0, n);
    return;
  }
  if (n < (std::size_t(1) << 32) && detail::incoherent(grid, in, n)) {
    // As apply_direct: gathered by cell (points, normals), evaluated in place, and written back in
    // the caller's order, so that the points of a group share their cell (one a lane).
    thread_local detail::CellOrder<T> scratch;
    thread_local std::vector<T> normals, jac;
    detail::order_by_cell(grid, in, n, scratch);
    const std::uint32_t* order = scratch.order.data();
    scratch.points.resize(3 * n);
    normals.resize(normals_in ? 3 * n : 0);
    jac.resize(jacobians ? 9 * n : 0);
    // Pointers, not the thread_local names: inside the tasks those name each worker's own buffers.
    T* p = scratch.points.data();
    T* nm = normals_in ? normals.data() : nullptr;
    T* jm = jacobians ? jac.data() : nullptr;
    const detail::NormalsJob<T> gathered{p, p, nm, nm, jm, phase, unit};
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t j = r.begin(); j < r.end(); ++j)
        for (std::size_t c = 0; c < 3; ++c) {
          p[3 * j + c] = in[3 * std::size_t(order[j]) + c];
          if (nm) nm[3 * j + c] = normals_in[3 * std::size_t(order[j]) + c];
        }
      detail::evaluate_normals(grid, data, k, poly, gathered, r.begin(), r.end());
    });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t j = r.begin(); j < r.end(); ++j) {
        const std::size_t to = order[j];
        for (std::size_t c = 0; c < 3; ++c) {
          out[3 * to + c] = p[3 * j + c];
          if (nm) normals_out[3 * to + c] = nm[3 * j + c];
        }
        for (std::size_t c = 0; jm && c < 9; ++c) jacobians[9 * to + c] = jm[9 * j + c];
      }
    });
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
    detail::evaluate_normals(grid, data, k, poly, job, r.begin(), r.end());
  });
}

void SpaceMap::apply_with_normals(const double* in, double* out, std::size_t n, double phase, const double* normals_in,
                                  double* normals_out, double* jacobians, bool unit_normals) const {
  normals_impl(in, out, n, phase, normals_in, normals_out, jacobians, unit_normals);
}
void SpaceMap::apply_with_normals(const float* in, float* out, std::size_t n, double phase, const float* normals_in,
                                  float* normals_out, float* jacobians, bool unit_normals) const {
  normals_impl(in, out, n, phase, normals_in, normals_out, jacobians, unit_normals);
}

void SpaceMap::displacements(const double* in, double* out, std::size_t n) const { apply_impl(in, out, n, 1.0, false); }
void SpaceMap::displacements(const float* in, float* out, std::size_t n) const { apply_impl(in, out, n, 1.0, false); }

std::size_t SpaceMap::size() const noexcept { return s_->st->sources().size(); }
double SpaceMap::radius() const noexcept { return s_->st->options.radius; }
Kernel SpaceMap::kernel() const noexcept { return s_->st->options.kernel; }
Polynomial SpaceMap::polynomial() const noexcept { return s_->st->options.polynomial; }
std::span<const Vec3> SpaceMap::sources() const noexcept { return s_->st->sources(); }
std::span<const Vec3> SpaceMap::destinations() const noexcept { return s_->destinations; }
const Eigen::Matrix<double, Eigen::Dynamic, 3>& SpaceMap::coefficients() const noexcept { return s_->alpha; }
std::span<const std::uint32_t> SpaceMap::order() const noexcept {
  return s_->st->system ? s_->st->system->order() : std::span<const std::uint32_t>();
}
const FitStats& SpaceMap::stats() const noexcept { return s_->stats; }
const NeighborIndex& SpaceMap::index() const { return s_->st->index(); }

Eigen::Matrix<double, 4, 3> SpaceMap::polynomial_coefficients() const noexcept {
  // p(x) = b0 + (x - c)^T B / s  =>  constant b0 - c^T B / s, linear part B / s.
  const Structure& st = *s_->st;
  Eigen::Matrix<double, 4, 3> out;
  const Eigen::Matrix3d lin = s_->beta.bottomRows<3>() / st.scale;
  out.row(0) = s_->beta.row(0) - st.center.transpose() * lin;
  out.bottomRows<3>() = lin;
  return out;
}

}  // namespace csrbf
