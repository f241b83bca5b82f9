// Issue 32: the engine API (csrbf/engine.hpp) and SpaceMap::apply_with_normals: strided, interleaved
// vertex buffers in float and double, normals exact through the Jacobian (against finite differences
// of the map itself), and failures as status codes naming what was wrong.
#include "csrbf/engine.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/space_map.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <string>
#include <vector>

#include "test_points.hpp"

using namespace csrbf;
using csrbf::test::random_points;

namespace {

struct Controls {
  std::vector<Vec3> s, d;
  std::vector<double> s_flat, d_flat;
};

/// n controls in the unit cube moved by a smooth field up to 0.1.
Controls controls(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  Controls c;
  c.s = random_points(n, rng);
  for (const Vec3& p : c.s) {
    c.d.push_back(p + 0.1 * Vec3(std::sin(3 * p.y()), std::cos(2 * p.z()), std::sin(4 * p.x())));
    for (int k = 0; k < 3; ++k) {
      c.s_flat.push_back(p[k]);
      c.d_flat.push_back(c.d.back()[k]);
    }
  }
  return c;
}

/// The deformed normal by finite differences of T itself: two tangents t1, t2 of n at x, each
/// mapped by central differences, and their cross product.
Vec3 finite_difference_normal(const SpaceMap& m, const Vec3& x, const Vec3& n, double phase) {
  const Vec3 a = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 t1 = n.cross(a).normalized(), t2 = n.cross(t1).normalized();
  const double h = 1e-6;
  const Vec3 u = m.map(x + h * t1, phase) - m.map(x - h * t1, phase);
  const Vec3 v = m.map(x + h * t2, phase) - m.map(x - h * t2, phase);
  Vec3 w = u.cross(v);  // t1 x t2 = n x (n x a)... oriented as n: check below
  if (w.dot(m.jacobian(x, phase).inverse().transpose() * n) < 0) w = -w;
  return w.normalized();
}

double angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

}  // namespace

TEST(Engine, FastJacobiansEqualTheSimplePathForEveryKernelAndPolynomial) {
  const Controls c = controls(400, 501);
  std::mt19937 rng(502);
  const auto pts = random_points(3000, rng, -0.2, 1.2);
  std::vector<double> in, out(3 * pts.size()), jac(9 * pts.size());
  for (const Vec3& p : pts) in.insert(in.end(), {p.x(), p.y(), p.z()});
  for (Kernel k : {Kernel::C0, Kernel::C2, Kernel::C4, Kernel::C6})
    for (Polynomial poly : {Polynomial::None, Polynomial::Linear}) {
      FitOptions o{0.25, k, poly};
      const SpaceMap m = SpaceMap::fit(c.s, c.d, o);
      m.apply_with_normals(in.data(), out.data(), pts.size(), 0.7, nullptr, nullptr, jac.data());
      double worst_pos = 0, worst_jac = 0;
      for (std::size_t i = 0; i < pts.size(); ++i) {
        worst_pos = std::max(worst_pos, (Vec3(out[3 * i], out[3 * i + 1], out[3 * i + 2]) - m.map(pts[i], 0.7)).norm());
        const Eigen::Matrix3d j = m.jacobian(pts[i], 0.7);
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) worst_jac = std::max(worst_jac, std::abs(jac[9 * i + 3 * a + b] - j(a, b)));
      }
      EXPECT_LT(worst_pos, 1e-12) << kernel_name(k);
      EXPECT_LT(worst_jac, 1e-9) << kernel_name(k) << " " << polynomial_name(poly);
    }
}

// The one-point-a-lane normals loop (eval_kernel.hpp's normals_block): full groups of 16 floats
// or 8 doubles (points in a lattice, many to a cell, as a mesh gives them), partial groups, the
// lattice shuffled (gathered by cell), points outside the grid and NaN, in both loops and both
// precisions, against SpaceMap::map and SpaceMap::jacobian point by point.
TEST(Engine, NormalsLoopEqualsThePointByPointPathInEveryLoopPrecisionAndOrder) {
  const Controls c = controls(300, 510);
  std::vector<Vec3> pts;
  for (int i = 0; i < 48; ++i)
    for (int j = 0; j < 48; ++j)
      for (int k = 0; k < 48; ++k)
        pts.emplace_back(-0.1 + 1.2 * i / 47.0, -0.1 + 1.2 * j / 47.0, -0.1 + 1.2 * k / 47.0);
  pts.emplace_back(5.0, 5.0, 5.0);  // beyond every source: J = I (or the polynomial's)
  std::mt19937 rng(511);
  std::vector<Vec3> shuffled = pts;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  const Vec3 n0 = Vec3(0.3, -0.5, 0.8);  // |n0| = 0.99: kept unless unit
  std::vector<EvaluationLoop> loops{EvaluationLoop::Portable};
  try {
    set_evaluation_loop(EvaluationLoop::Avx512);  // refused where the CPU or the build has none
    loops.push_back(EvaluationLoop::Avx512);
  } catch (const InvalidInput&) {
  }
  for (EvaluationLoop loop : loops)
    for (Kernel k : {Kernel::C0, Kernel::C2, Kernel::C6})
      for (Polynomial poly : {Polynomial::None, Polynomial::Linear}) {
        set_evaluation_loop(loop);
        const SpaceMap m = SpaceMap::fit(c.s, c.d, FitOptions{0.2, k, poly});
        for (const std::vector<Vec3>* set : {&pts, &shuffled}) {
          const std::size_t n = set->size();
          const auto check = [&](auto zero, double pos_tol, double jac_tol, double rad_tol) {
            using T = decltype(zero);
            std::vector<T> p, nm, jac(9 * n);
            for (const Vec3& x : *set) p.insert(p.end(), {T(x.x()), T(x.y()), T(x.z())});
            for (std::size_t i = 0; i < n; ++i) nm.insert(nm.end(), {T(n0.x()), T(n0.y()), T(n0.z())});
            std::vector<T> unit_p = p, unit_nm = nm;
            m.apply_with_normals(p.data(), p.data(), n, 0.8, nm.data(), nm.data(), jac.data());
            m.apply_with_normals(unit_p.data(), unit_p.data(), n, 0.8, unit_nm.data(), unit_nm.data(), nullptr, true);
            double worst_pos = 0, worst_jac = 0, worst_angle = 0, worst_len = 0;
            for (std::size_t i = 0; i < n; i += 7) {
              const Vec3 x(double(T((*set)[i].x())), double(T((*set)[i].y())), double(T((*set)[i].z())));
              const Vec3 y(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
              worst_pos = std::max(worst_pos, (y - m.map(x, 0.8)).norm());
              EXPECT_EQ(p[3 * i], unit_p[3 * i]);
              const Eigen::Matrix3d j = m.jacobian(x, 0.8);
              for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                  worst_jac = std::max(worst_jac, std::abs(double(jac[9 * i + 3 * a + b]) - j(a, b)));
              const Vec3 want = j.inverse().transpose() * n0;
              const Vec3 got(nm[3 * i], nm[3 * i + 1], nm[3 * i + 2]),
                  got_unit(unit_nm[3 * i], unit_nm[3 * i + 1], unit_nm[3 * i + 2]);
              worst_angle = std::max({worst_angle, angle(got, want), angle(got_unit, want)});
              worst_len = std::max({worst_len, std::abs(got.norm() - n0.norm()), std::abs(got_unit.norm() - 1.0)});
            }
            const std::string what = std::string(kernel_name(k)) + " " + std::string(polynomial_name(poly)) +
                                     (sizeof(T) == 4 ? " float" : " double") + (set == &pts ? "" : " shuffled") +
                                     (loop == EvaluationLoop::Avx512 ? " avx512" : " portable");
            EXPECT_LT(worst_pos, pos_tol) << what;
            EXPECT_LT(worst_jac, jac_tol) << what;
            EXPECT_LT(worst_angle, rad_tol) << what;
            EXPECT_LT(worst_len, 10 * rad_tol) << what;
          };
          check(0.0, 1e-12, 1e-9, 1e-9);
          // C0's cone turns its gradient by the float rounding of the point itself near a source
          // (6e-8 |x| / r rad): 1.8e-5 rad measured on the lattice; the smooth kernels within 1e-5.
          check(0.0f, 1e-5, 2e-4, k == Kernel::C0 ? 1e-4 : 1e-5);
        }
      }
  set_evaluation_loop(EvaluationLoop::Auto);
  // A NaN point gives NaN, not a crash or a neighbour's value; its neighbours in the group are exact.
  const SpaceMap m = SpaceMap::fit(c.s, c.d, FitOptions{0.2});
  std::vector<float> p(3 * 32, 0.5f), nm(3 * 32, 0.0f);
  for (std::size_t i = 0; i < 32; ++i) nm[3 * i + 2] = 1.0f;
  p[3 * 5] = std::nanf("");
  m.apply_with_normals(p.data(), p.data(), 32, 1.0, nm.data(), nm.data());
  EXPECT_TRUE(std::isnan(p[3 * 5]));
  const Vec3 y = m.map(Vec3(0.5, 0.5, 0.5));
  EXPECT_NEAR(p[3 * 6], y.x(), 1e-5);
  EXPECT_NEAR(p[3 * 6 + 2], y.z(), 1e-5);
}

// Found by the attacker: normals of extreme length (area-weighted normals of tiny or huge triangles)
// came out unscaled or a few percent off, where the squared length of cof(J) n over- or underflowed.
// Every length now comes out unit (or its own), in a group of one and of 16, in float and double.
TEST(Engine, NormalsOfAnyLengthAreScaledExactly) {
  const Controls c = controls(200, 512);
  const SpaceMap m = SpaceMap::fit(c.s, c.d, FitOptions{0.3, Kernel::C2, Polynomial::Linear});
  const Vec3 want = (m.jacobian(Vec3(0.5, 0.5, 0.5)).inverse().transpose() * Vec3(0.6, 0.0, 0.8)).normalized();
  const auto run = [&](auto len, std::size_t n, bool unit) {
    using T = decltype(len);
    std::vector<T> p(3 * n, T(0.5)), nm;
    for (std::size_t i = 0; i < n; ++i) nm.insert(nm.end(), {T(0.6) * len, T(0), T(0.8) * len});
    m.apply_with_normals(p.data(), p.data(), n, 1.0, nm.data(), nm.data(), nullptr, unit);
    const Vec3 got{double(nm[0]), double(nm[1]), double(nm[2])};
    const double expect_len = unit ? 1.0 : double(len);
    // (stableNorm: the squares of 1e300 and 1e-300 leave double's range here too.)
    EXPECT_NEAR(got.stableNorm() / expect_len, 1.0, sizeof(T) == 4 ? 1e-5 : 1e-12)
        << double(len) << " " << n << " " << unit;
    EXPECT_LT(angle(got / got.stableNorm(), want), sizeof(T) == 4 ? 1e-5 : 1e-9) << double(len) << " " << n;
  };
  for (const std::size_t n : {std::size_t(1), std::size_t(16)})
    for (const bool unit : {true, false}) {
      for (const float len : {1e-30f, 1e-22f, 1e-19f, 1.0f, 1e20f, 1e37f}) run(len, n, unit);
      for (const double len : {1e-300, 1e-170, 1.0, 1e170, 1e300}) run(len, n, unit);
    }
}

TEST(Engine, InterleavedFloatAndDoubleBuffersDeformPositionsAndExactNormals) {
  const Controls c = controls(300, 503);
  engine::Settings settings;
  settings.radius = 0.3;
  engine::Deformer d;
  const engine::Result fit = engine::Deformer::fit(c.s_flat.data(), c.d_flat.data(), c.s.size(), settings, d);
  ASSERT_TRUE(fit) << fit.message;
  EXPECT_EQ(d.size(), 300u);
  const SpaceMap m = SpaceMap::fit(c.s, c.d, FitOptions{0.3});
  std::mt19937 rng(504);
  const auto pts = random_points(20000, rng, -0.1, 1.1);
  std::normal_distribution<double> g;
  // A game vertex: position, a colour, a normal, texture coordinates (48 bytes, float).
  struct VertexF {
    float pos[3];
    std::uint32_t rgba;
    float normal[3];
    float uv[2];
    float pad[3];
  };
  struct VertexD {
    double uv[2];
    double pos[3];
    double normal[3];
  };
  std::vector<VertexF> vf(pts.size());
  std::vector<VertexD> vd(pts.size());
  std::vector<Vec3> normals(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    normals[i] = Vec3(g(rng), g(rng), g(rng)).normalized();
    for (int k = 0; k < 3; ++k) {
      vf[i].pos[k] = float(pts[i][k]);
      vf[i].normal[k] = float(normals[i][k]);
      vd[i].pos[k] = pts[i][k];
      vd[i].normal[k] = normals[i][k];
    }
    vf[i].rgba = 0xdeadbeef;
    vf[i].uv[0] = vf[i].uv[1] = 0.5f;
  }
  const engine::VertexBuffer bf{vf.data(),
                                vf.size(),
                                sizeof(VertexF),
                                offsetof(VertexF, pos),
                                offsetof(VertexF, normal),
                                engine::Scalar::Float32};
  const engine::VertexBuffer bd{vd.data(),
                                vd.size(),
                                sizeof(VertexD),
                                offsetof(VertexD, pos),
                                offsetof(VertexD, normal),
                                engine::Scalar::Float64};
  const double phase = 0.8;
  ASSERT_TRUE(d.deform(bf, bf, phase));  // in place
  std::vector<VertexD> rest = vd;
  const engine::VertexBuffer br{rest.data(),
                                rest.size(),
                                sizeof(VertexD),
                                offsetof(VertexD, pos),
                                offsetof(VertexD, normal),
                                engine::Scalar::Float64};
  ASSERT_TRUE(d.deform(br, bd, phase));  // from the rest pose into another buffer
  double worst_angle = 0, worst_pos_d = 0, worst_pos_f = 0, worst_angle_f = 0;
  std::size_t moved = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec3 want = m.map(pts[i], phase);
    const Vec3 got_d(vd[i].pos[0], vd[i].pos[1], vd[i].pos[2]), got_f(vf[i].pos[0], vf[i].pos[1], vf[i].pos[2]);
    worst_pos_d = std::max(worst_pos_d, (got_d - want).norm());
    worst_pos_f = std::max(worst_pos_f, (got_f - want).norm());
    EXPECT_EQ(vf[i].rgba, 0xdeadbeefu);  // the rest of the vertex is untouched
    EXPECT_EQ(vf[i].uv[0], 0.5f);
    const Vec3 nd(vd[i].normal[0], vd[i].normal[1], vd[i].normal[2]);
    const Vec3 nf(vf[i].normal[0], vf[i].normal[1], vf[i].normal[2]);
    EXPECT_NEAR(nd.norm(), 1.0, 1e-12);
    if (i % 10 == 0) {
      const Vec3 ref = finite_difference_normal(m, pts[i], normals[i], phase);
      worst_angle = std::max(worst_angle, angle(nd, ref));
      worst_angle_f = std::max(worst_angle_f, angle(nf, ref));
      moved += angle(normals[i], ref) > 1e-3;
    }
  }
  EXPECT_LT(worst_pos_d, 1e-12);
  EXPECT_LT(worst_pos_f, 1e-6);
  EXPECT_LT(worst_angle, 1e-5);    // the bound, in double
  EXPECT_LT(worst_angle_f, 1e-5);  // and in float
  EXPECT_GT(moved, 500u);          // the normals did turn: the test is not vacuous
}

TEST(Engine, FailuresAreStatusCodesNamingTheFieldAndValue) {
  const Controls c = controls(50, 505);
  engine::Settings settings;
  engine::Deformer d;
  settings.radius = -1;
  engine::Result r = engine::Deformer::fit(c.s_flat.data(), c.d_flat.data(), 50, settings, d);
  EXPECT_EQ(r.status, engine::Status::InvalidInput);
  EXPECT_NE(std::string(r.message).find("radius"), std::string::npos) << r.message;
  EXPECT_FALSE(d.fitted());
  settings.radius = 0.5;
  std::vector<double> dup = c.s_flat;
  for (int k = 0; k < 3; ++k) dup[3 + std::size_t(k)] = dup[std::size_t(k)];
  r = engine::Deformer::fit(dup.data(), c.d_flat.data(), 50, settings, d);
  EXPECT_EQ(r.status, engine::Status::DuplicateSource) << r.message;
  settings.memory_limit_gib = 1e-9;
  r = engine::Deformer::fit(c.s_flat.data(), c.d_flat.data(), 50, settings, d);
  EXPECT_EQ(r.status, engine::Status::ResourceLimit) << r.message;
  settings.memory_limit_gib = 4;
  ASSERT_TRUE(engine::Deformer::fit(c.s_flat.data(), c.d_flat.data(), 50, settings, d));

  float v[6] = {0.1f, 0.2f, 0.3f, 0, 0, 1};
  engine::VertexBuffer b{v, 1, 8, 0, engine::kNoNormal, engine::Scalar::Float32};  // stride too short
  r = d.deform(b, b);
  EXPECT_EQ(r.status, engine::Status::InvalidInput);
  EXPECT_NE(std::string(r.message).find("in.position_offset is 0: three scalars there do not fit in a stride of 8"),
            std::string::npos)
      << r.message;
  b.stride = 24;
  engine::VertexBuffer o = b;
  o.normal_offset = 12;
  r = d.deform(b, o);
  EXPECT_NE(std::string(r.message).find("out has normals but in has none"), std::string::npos) << r.message;
  r = d.deform(b, b, std::nan(""));
  EXPECT_NE(std::string(r.message).find("phase"), std::string::npos) << r.message;
  // An unfitted deformer is the identity; a refit needs a fit.
  engine::Deformer none;
  b.normal_offset = 12;
  ASSERT_TRUE(none.deform(b, b));
  EXPECT_EQ(v[0], 0.1f);
  EXPECT_EQ(v[5], 1.0f);
  engine::Deformer again;
  EXPECT_EQ(none.refit(c.d_flat.data(), again).status, engine::Status::InvalidInput);
  // A refit equals a fit to the new destinations.
  std::vector<double> d2 = c.s_flat;
  for (double& x : d2) x += 0.01;
  ASSERT_TRUE(d.refit(d2.data(), again));
  double p[3] = {c.s_flat[0], c.s_flat[1], c.s_flat[2]};
  engine::VertexBuffer one{p, 1, 24, 0, engine::kNoNormal, engine::Scalar::Float64};
  ASSERT_TRUE(again.deform(one, one));
  EXPECT_NEAR(p[0], c.s_flat[0] + 0.01, 1e-9);
}

// Found by a new user: TBB hands apply_with_normals chunks far above its grain (7813 of 1e6 points
// on 2 threads), which overflowed the Jacobians' buffer on the stack. 1e6 points, no Jacobians asked.
TEST(Engine, ApplyWithNormalsTakesAnyChunkSize) {
  const Controls c = controls(500, 507);
  const SpaceMap m = SpaceMap::fit(c.s, c.d, FitOptions{0.2});
  std::mt19937 rng(508);
  const auto pts = random_points(1000000, rng);
  std::vector<double> p, nm(3 * pts.size(), 0.0);
  for (const Vec3& x : pts) p.insert(p.end(), {x.x(), x.y(), x.z()});
  for (std::size_t i = 0; i < pts.size(); ++i) nm[3 * i + 2] = 1.0;
  m.apply_with_normals(p.data(), p.data(), pts.size(), 1.0, nm.data(), nm.data());
  for (std::size_t i = 0; i < pts.size(); i += 4999) {
    EXPECT_LT((Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]) - m.map(pts[i])).norm(), 1e-12);
    const Vec3 want = (m.jacobian(pts[i]).inverse().transpose() * Vec3::UnitZ()).normalized();
    EXPECT_LT((Vec3(nm[3 * i], nm[3 * i + 1], nm[3 * i + 2]) - want).norm(), 1e-9);
  }
}

// Found by a new user: a normal placed over the position returned Ok and overwrote it.
TEST(Engine, OverlappingPositionAndNormalAreRefused) {
  const Controls c = controls(50, 509);
  engine::Settings settings;
  settings.radius = 0.5;
  engine::Deformer d;
  ASSERT_TRUE(engine::Deformer::fit(c.s_flat.data(), c.d_flat.data(), 50, settings, d));
  float v[8] = {};
  const engine::VertexBuffer b{v, 1, 32, 0, 4, engine::Scalar::Float32};
  const engine::Result r = d.deform(b, b);
  EXPECT_EQ(r.status, engine::Status::InvalidInput);
  EXPECT_NE(std::string(r.message).find("in.position_offset 0 and in.normal_offset 4 overlap"), std::string::npos)
      << r.message;
  engine::VertexBuffer ok = b;
  ok.stride = 24;
  ok.normal_offset = 12;
  EXPECT_TRUE(d.deform(ok, ok));
  EXPECT_NE(std::string(d.deform(ok, ok, 1e300).message).find("got 1e+300"), std::string::npos);
  // Found by the attacker: one buffer read with one stride and written with another raced; a stride
  // near SIZE_MAX wrapped around before the buffer.
  std::vector<float> big(3 * 1000);
  engine::VertexBuffer wide{big.data(), 500, 24, 0, engine::kNoNormal, engine::Scalar::Float32};
  engine::VertexBuffer narrow = wide;
  narrow.stride = 12;
  EXPECT_NE(std::string(d.deform(wide, narrow).message).find("in and out overlap"), std::string::npos);
  engine::VertexBuffer wrap{big.data(), 4, ~std::size_t(0) - 11, 0, engine::kNoNormal, engine::Scalar::Float32};
  EXPECT_NE(std::string(d.deform(wrap, wrap).message).find("pass the end of the address space"), std::string::npos)
      << d.deform(wrap, wrap).message;
}

// The GPU layout of two deformers of different stages, held against brute force: the layout sorts
// them by stage, places each one's sources, coefficients and grid after the one before, and every
// cell lists exactly the sources within R of its box (the shader's neighbour search), by index into
// the shared sources. The texel-for-texel match with csrbf_deformation.js is tests/capi's.
TEST(Engine, GpuLayoutSortsByStageAndEveryCellListsExactlyTheSourcesWithinR) {
  const Controls a = controls(60, 11), b = controls(25, 12);
  engine::Settings s;
  s.radius = 0.3;
  engine::Deformer da, db;
  ASSERT_TRUE(engine::Deformer::fit(a.s_flat.data(), a.d_flat.data(), 60, s, da));
  s.radius = 0.45;
  s.polynomial = engine::Polynomial::Linear;
  ASSERT_TRUE(engine::Deformer::fit(b.s_flat.data(), b.d_flat.data(), 25, s, db));
  const engine::GpuDeformation d[2] = {{da.handle(), 0.5, 1}, {db.handle(), -2.0, 0}};
  engine::GpuLayout l{};
  ASSERT_TRUE(engine::gpu_size(d, 2, l));
  const std::size_t w = CSRBF_GPU_WIDTH;
  std::vector<float> sources(4 * w * l.sources_rows), coefficients(4 * w * l.coefficients_rows),
      deformations(4 * w * l.deformations_rows);
  std::vector<int> cells(2 * w * l.cells_rows), list(w * l.list_rows), groups(w * l.groups_rows, 7);
  l.sources = sources.data();
  l.coefficients = coefficients.data();
  l.deformations = deformations.data();
  l.cells = cells.data();
  l.list = list.data();
  l.groups = groups.data();
  ASSERT_TRUE(engine::gpu_fill(d, 2, l));
  EXPECT_EQ(std::count(groups.begin(), groups.end(), 0), std::ptrdiff_t(groups.size()));

  const SpaceMap ma = SpaceMap::fit(a.s, a.d, FitOptions{.radius = 0.3});
  const SpaceMap mb = SpaceMap::fit(b.s, b.d, FitOptions{.radius = 0.45, .polynomial = Polynomial::Linear});
  // Slot 0 is b (stage 0), slot 1 is a (stage 1).
  const struct {
    const SpaceMap* map;
    double weight, stage;
    std::size_t first_source;
  } slots[2] = {{&mb, -2.0, 0, 0}, {&ma, 0.5, 1, 25}};
  std::size_t cells_before = 0;
  for (std::size_t slot = 0; slot < 2; ++slot) {
    const auto& e = slots[slot];
    const float* t = &deformations[32 * slot];
    const double radius = e.map->radius();
    EXPECT_EQ(t[0], float(radius));
    EXPECT_EQ(t[1], 2.0f);  // C2
    EXPECT_EQ(t[2], float(e.stage));
    EXPECT_EQ(t[3], -1.0f);
    EXPECT_EQ(t[11], float(cells_before));
    EXPECT_EQ(t[15], 1.0f);  // a weight that is not 0
    for (std::size_t i = 0; i < e.map->size(); ++i)
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(sources[4 * (e.first_source + i) + std::size_t(k)], float(e.map->sources()[i][k]));
        EXPECT_EQ(coefficients[4 * (e.first_source + i) + std::size_t(k)],
                  float(e.weight * double(float(e.map->coefficients()(Eigen::Index(i), k)))));
      }
    if (e.map->polynomial() != Polynomial::None) {
      const Eigen::Matrix<double, 4, 3> pc = e.map->polynomial_coefficients();
      for (int r = 0; r < 4; ++r)
        for (int k = 0; k < 3; ++k) EXPECT_EQ(t[12 + 4 * r + k], float(e.weight * double(float(pc(r, k)))));
    }
    // Every cell's list against brute force over the float sources and the cell's box.
    const Vec3 origin(t[4], t[5], t[6]);
    const double h = 1.0 / double(t[7]);
    const std::size_t nx = std::size_t(t[8]), ny = std::size_t(t[9]), nz = std::size_t(t[10]);
    ASSERT_LE(nx * ny * nz, std::size_t(1) << 18);
    std::size_t listed = 0;
    for (std::size_t z = 0; z < nz; ++z)
      for (std::size_t y = 0; y < ny; ++y)
        for (std::size_t x = 0; x < nx; ++x) {
          const std::size_t c = cells_before + x + nx * (y + ny * z);
          std::vector<int> got(list.begin() + cells[2 * c], list.begin() + cells[2 * c] + cells[2 * c + 1]), want;
          for (std::size_t i = 0; i < e.map->size(); ++i) {
            double d2 = 0;
            for (int k = 0; k < 3; ++k) {
              const double p = float(e.map->sources()[i][k]);
              const double l = origin[k] + double(k == 0 ? x : k == 1 ? y : z) * h, u = l + h;
              const double g = p < l ? l - p : p > u ? p - u : 0;
              d2 += g * g;
            }
            // Box distances within 1e-4 R of R are left to rounding either way.
            if (std::abs(std::sqrt(d2) - radius) < 1e-4 * radius) {
              got.erase(std::remove(got.begin(), got.end(), int(e.first_source + i)), got.end());
              continue;
            }
            if (d2 < radius * radius) want.push_back(int(e.first_source + i));
          }
          EXPECT_EQ(got, want) << "slot " << slot << " cell " << x << " " << y << " " << z;
          listed += std::size_t(cells[2 * c + 1]);
        }
    EXPECT_GT(listed, e.map->size());  // sources near a cell's side are listed by its neighbours too
    cells_before += nx * ny * nz;
  }

  // A new frame: gpu_update gives what a fill at the new weights gives; a stage below 0 is refused.
  const engine::GpuDeformation next[2] = {{da.handle(), 0.0, 1}, {db.handle(), 1.0, 0}};
  ASSERT_TRUE(engine::gpu_update(next, 2, l));
  EXPECT_EQ(deformations[32 + 15], 0.0f);  // a (slot 1) at weight 0: skipped by the shader
  EXPECT_EQ(coefficients[4 * 25], 0.0f);
  EXPECT_EQ(coefficients[0], float(mb.coefficients()(0, 0)));
  const engine::GpuDeformation bad[1] = {{da.handle(), 1.0, -1}};
  const engine::Result r = engine::gpu_size(bad, 1, l);
  EXPECT_EQ(r.status, engine::Status::InvalidInput);
  EXPECT_NE(std::string(r.message).find("deformations[0].stage is -1"), std::string::npos) << r.message;
}
