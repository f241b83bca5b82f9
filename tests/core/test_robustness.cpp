// Near-duplicate sources and huge coordinates (issue: numerical robustness).
#include "csrbf/space_map.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "test_points.hpp"

#include <array>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <random>

using namespace csrbf;

namespace {

struct Problem {
  std::vector<Vec3> s, d;
};

/// 50 random sources in the unit cube plus one at eps * R from source 0, with its own destination.
Problem near_duplicate(double eps, double radius) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0, 1);
  Problem p;
  for (int i = 0; i < 50; ++i) {
    const Vec3 x(u(rng), u(rng), u(rng));
    p.s.push_back(x);
    p.d.push_back(x + Vec3(0, 0.01 * u(rng), 0));
  }
  p.s.push_back(p.s[0] + Vec3(eps * radius, 0, 0));
  p.d.push_back(p.s.back() + Vec3(0, 0.02, 0));
  return p;
}

double dense_condition(const std::vector<Vec3>& s, Kernel k, double radius) {
  const auto n = Eigen::Index(s.size());
  Eigen::MatrixXd a(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) a(i, j) = wendland(k, (s[std::size_t(i)] - s[std::size_t(j)]).norm() / radius);
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(a).eigenvalues();
  return ev.maxCoeff() / ev.minCoeff();
}

}  // namespace

TEST(Robustness, ConditionEstimateMatchesTheDenseEigenvalues) {
  for (double eps : {1e-1, 1e-2, 1e-3})
    for (Kernel k : {Kernel::C0, Kernel::C2, Kernel::C4}) {
      const Problem p = near_duplicate(eps, 0.3);
      const auto map = SpaceMap::fit(p.s, p.d, FitOptions{0.3, k});
      const double dense = dense_condition(p.s, k, 0.3);
      EXPECT_NEAR(map.condition_estimate() / dense, 1.0, 0.05) << "eps " << eps << " kernel " << int(k);
    }
}

TEST(Robustness, NearDuplicatesInterpolateWithinTheBoundOrSayWhyNot) {
  // From 1e-3 R down to 1e-9 R: each fit either keeps the documented bound (relative residual
  // <= kResidualLimit) or throws an error that names the problem. Never a silent bad fit.
  double last_condition = 0;
  for (double eps : {1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9})
    for (Kernel k : {Kernel::C0, Kernel::C2, Kernel::C6}) {
      const Problem p = near_duplicate(eps, 0.3);
      try {
        const auto map = SpaceMap::fit(p.s, p.d, FitOptions{0.3, k});
        EXPECT_LE(map.stats().residual_relative, kResidualLimit) << eps;
        for (std::size_t i = 0; i < p.s.size(); ++i)
          EXPECT_LT((map.map(p.s[i]) - p.d[i]).norm(), 1e-6 * 0.03 * 10) << eps << " control " << i;
        if (k == Kernel::C2) {
          EXPECT_GT(map.condition_estimate(), last_condition) << "the condition grows as the pair closes";
          last_condition = map.condition_estimate();
        }
      } catch (const IllConditioned& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("the closest sources, 0 and 50, are"), std::string::npos) << m;
        EXPECT_NE(m.find("condition estimate"), std::string::npos) << m;
        EXPECT_LE(eps, 1e-6) << "C2 at " << eps << " R is still well within the bound: " << m;
      } catch (const NotPositiveDefinite& e) {
        EXPECT_LE(eps, 1e-8) << e.what();  // a pivot lost to rounding: sources coincide to 8 digits
      }
    }
}

TEST(Robustness, HugeCoordinatesGiveTheCentredProblemsResults) {
  // A scene far from the origin: the same displacements as the same scene (the same represented
  // points, exactly translated) at the origin, relative to the largest displacement, at any offset.
  // Before issue 30 the double path took distances from absolute coordinates scaled by 1/R, which
  // kept only the digits the offset left: 6.2e-9 at 1e6.
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> s0, d0;
  for (int i = 0; i < 400; ++i) {
    const Vec3 p(u(rng), u(rng), u(rng));
    s0.push_back(p);
    d0.push_back(p + Vec3(0.01 * u(rng), 0.02, 0));
  }
  std::vector<double> x0;
  for (int i = 0; i < 3000; ++i)
    for (int c = 0; c < 3; ++c) x0.push_back(u(rng));
  for (const double o : {1e3, 1e6, 1e8, 1e10})
    for (Polynomial poly : {Polynomial::None, Polynomial::Linear}) {
      const Vec3 off(o, -o, 0.5 * o);
      // The far scene as a user has it, and its points translated back exactly (Sterbenz).
      std::vector<Vec3> so = s0, dof = d0, s = s0, d = d0;
      for (std::size_t i = 0; i < s0.size(); ++i) {
        so[i] += off, dof[i] += off;
        s[i] = so[i] - off, d[i] = dof[i] - off;
      }
      std::vector<double> xo = x0, x = x0;
      for (std::size_t i = 0; i < xo.size(); ++i) {
        xo[i] += off[Eigen::Index(i % 3)];
        x[i] = xo[i] - off[Eigen::Index(i % 3)];
      }
      const auto centred = SpaceMap::fit(s, d, FitOptions{0.3, Kernel::C2, poly});
      const auto far = SpaceMap::fit(so, dof, FitOptions{0.3, Kernel::C2, poly});
      std::vector<double> a(x.size()), b(x.size());
      centred.displacements(x.data(), a.data(), x.size() / 3);
      far.displacements(xo.data(), b.data(), x.size() / 3);
      double worst = 0, largest = 0;
      for (std::size_t i = 0; i < a.size(); ++i) {
        worst = std::max(worst, std::abs(a[i] - b[i]));
        largest = std::max(largest, std::abs(a[i]));
      }
      EXPECT_LT(worst / largest, 1e-12) << "offset " << o << ", polynomial " << int(poly);
      EXPECT_LT(far.stats().residual_relative, 1e-12);
      // Single precision far from 0 is refused by float_trusted() (an ulp of 1e6 in float is 0.06).
    }
}

namespace {
/// Max |float path - double path| over points rounded to float first, and the largest displacement.
std::pair<double, double> float_error(const SpaceMap& m, const std::vector<Vec3>& pts) {
  std::vector<float> f(3 * pts.size()), fo(f.size());
  std::vector<double> d(f.size()), dout(f.size());
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      f[3 * i + std::size_t(c)] = float(pts[i][c]);
      d[3 * i + std::size_t(c)] = double(f[3 * i + std::size_t(c)]);
    }
  m.displacements(f.data(), fo.data(), pts.size());
  m.displacements(d.data(), dout.data(), pts.size());
  double err = 0, dmax = 0;
  for (std::size_t k = 0; k < f.size(); ++k) {
    err = std::max(err, std::abs(double(fo[k]) - dout[k]));
    dmax = std::max(dmax, std::abs(dout[k]));
  }
  return {err, dmax};
}
}  // namespace

TEST(Robustness, FloatEvaluationIsUsedOnlyWhereItCanBeTrusted) {
  // The fuzzers' cases: C6 through 167 sources with R 5 times the model, 3.3e4 from the origin,
  // displacements up to about 500 (float evaluation was off by 6.8e3); and near-duplicates at 1e-5 R
  // (off by 200 times the largest displacement). Now float inputs agree with double evaluation.
  std::mt19937 rng(167);
  std::uniform_real_distribution<double> u(0, 1), g(-300, 300);
  std::vector<Vec3> s, d;
  for (int i = 0; i < 167; ++i) {
    const Vec3 x = Vec3(u(rng), u(rng), u(rng)) + Vec3(3.3e4, 3.3e4, 0);
    s.push_back(x);
    d.push_back(x + Vec3(g(rng), g(rng), g(rng)));
  }
  int checked = 0;
  for (const double radius : {5.0, 2.0}) {
    try {
      const SpaceMap m = SpaceMap::fit(s, d, FitOptions{radius, Kernel::C6});
      const auto [err, dmax] = float_error(m, s);
      EXPECT_LE(err, kFloatTolerance * dmax) << "R = " << radius;
      ++checked;
    } catch (const IllConditioned&) {
      // refused outright: also a clean answer
    }
  }
  const Problem p = near_duplicate(1e-5, 0.3);
  const SpaceMap near = SpaceMap::fit(p.s, p.d, FitOptions{0.3, Kernel::C2});
  EXPECT_FALSE(near.float_trusted());
  const auto [err, dmax] = float_error(near, p.s);
  EXPECT_LE(err, kFloatTolerance * dmax);
  ++checked;
  EXPECT_GE(checked, 2);
  // A well-conditioned map keeps single precision (the fast path): float differs from double only
  // by rounding.
  const Problem ok = near_duplicate(0.5, 0.3);
  const SpaceMap good = SpaceMap::fit(ok.s, ok.d, FitOptions{0.3, Kernel::C2});
  EXPECT_TRUE(good.float_trusted());
  const auto [gerr, gmax] = float_error(good, ok.s);
  EXPECT_LE(gerr, 1e-5 * gmax + 1e-7);
}

// Issue 30, point 4: float_trusted() measured only at the sources, and 2 of 64 maps went past the
// documented bound between them (11 of 395 in a wider sweep, up to 2.2x). Random maps (2 to 63
// sources, every kernel and polynomial, radii of 0.1 to 3 times the model, offsets up to 1e3), each
// evaluated at 2000 points in and around its sources' box: the float path (or its fall-back to double)
// stays within kFloatTolerance of the largest control displacement, and most maps keep float.
TEST(Robustness, TheFloatPathKeepsItsBoundBetweenTheSources) {
  std::mt19937 rng(30);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> gauss(0, 1);
  int maps = 0, trusted = 0;
  double worst = 0;
  for (int c = 0; c < 256; ++c) {
    const int n = 2 + int(u(rng) * 62);
    const double offset = u(rng) < 0.5 ? 0.0 : std::pow(10.0, std::floor(u(rng) * 4));
    const double scale = std::pow(10.0, u(rng) * 6 - 3);
    std::vector<Vec3> s(static_cast<std::size_t>(n)), d(static_cast<std::size_t>(n));
    double gmax = 0;
    for (int i = 0; i < n; ++i) {
      s[std::size_t(i)] = Vec3::Constant(offset) + scale * Vec3(u(rng), u(rng), u(rng));
      const Vec3 dv = 0.05 * scale * Vec3(gauss(rng), gauss(rng), gauss(rng));
      d[std::size_t(i)] = s[std::size_t(i)] + dv;
      gmax = std::max(gmax, dv.norm());
    }
    FitOptions o;
    o.radius = scale * std::pow(10.0, u(rng) * 1.5 - 1);
    o.kernel = std::array{Kernel::C0, Kernel::C2, Kernel::C4, Kernel::C6}[std::size_t(u(rng) * 4) % 4];
    o.polynomial = std::array{Polynomial::None, Polynomial::Constant, Polynomial::Linear}[std::size_t(u(rng) * 3) % 3];
    std::vector<Vec3> pts(2000);
    for (auto& p : pts) p = Vec3::Constant(offset) + scale * (1.4 * Vec3(u(rng), u(rng), u(rng)) - Vec3::Constant(0.2));
    try {
      const SpaceMap m = SpaceMap::fit(s, d, o);
      const double err = float_error(m, pts).first;
      worst = std::max(worst, err / gmax);
      EXPECT_LE(err, kFloatTolerance * gmax) << "map " << c << ": " << n << " sources, offset " << offset << ", "
                                             << kernel_name(o.kernel) << ", " << polynomial_name(o.polynomial);
      ++maps;
      trusted += m.float_trusted();
    } catch (const Error&) {
      // refused (coplanar sources with a linear polynomial, ill-conditioned): a clean answer
    }
  }
  EXPECT_GE(maps, 200);
  EXPECT_GE(trusted, maps / 2) << "the float path is kept where it holds";
  // The examples keep the fast single-precision path.
  for (const auto& [name, radius] : {std::pair{"fish", 0.3}, {"face", 0.2}, {"bunny", 2.5}}) {
    std::ifstream in(std::string(CSRBF_SOURCE_DIR) + "/examples/" + name + ".controls");
    std::vector<Vec3> src, dst;
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream row(line);
      Vec3 a, b;
      if (row >> a.x() >> a.y() >> a.z() >> b.x() >> b.y() >> b.z()) src.push_back(a), dst.push_back(b);
    }
    ASSERT_GT(src.size(), 10u) << name;
    EXPECT_TRUE(SpaceMap::fit(src, dst, FitOptions{radius, Kernel::C2}).float_trusted()) << name;
  }
  std::printf("float path: %d maps, %d in float, largest error %.3g of the largest displacement\n", maps, trusted,
              worst);
}

TEST(Robustness, MemoryLimitCountsWhatTheSolverWillHold) {
  // 20000 random sources in a cube with R = 0.15: about 140 neighbours each, so the graph and the
  // matrix fit in 0.2 GiB, but the factor's fill does not. Each solver refuses before factorising,
  // from its own analysis; the envelope of the identity ordering is refused from its exact size.
  std::mt19937 rng(20000);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> s(20000), d;
  for (auto& x : s) x = Vec3(u(rng), u(rng), u(rng));
  for (const auto& x : s) d.push_back(x + Vec3(0, 0, 0.01));
  const std::vector<std::pair<FitOptions, std::string>> cases{
      {FitOptions{0.15, Kernel::C2, Polynomial::None, Ordering::Auto, Solver::Cholmod}, "CHOLMOD needs about"},
      {FitOptions{0.15, Kernel::C2, Polynomial::None, Ordering::Auto, Solver::Eigen},
       "Eigen SimplicialLLT needs about"},
      {FitOptions{0.15, Kernel::C2, Polynomial::None, Ordering::Identity, Solver::Envelope},
       "the envelope of the identity ordering"},
  };
  for (auto [o, words] : cases) {
    if (o.solver == Solver::Cholmod && !cholmod_available()) continue;
    o.memory_limit_bytes = 0.2 * double(1ull << 30);
    try {
      SpaceMap::fit(s, d, o);
      ADD_FAILURE() << words << ": accepted";
    } catch (const ResourceLimit& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("above the limit of 0.2 GiB"), std::string::npos) << e.what();
    }
  }
  FitOptions nan_limit{0.15};
  nan_limit.memory_limit_bytes = NAN;
  EXPECT_THROW(SpaceMap::fit(s, d, nan_limit), InvalidInput);
}

TEST(Robustness, PhaseIsBounded) {
  const std::vector<Vec3> s{Vec3(0, 0, 0)}, d{Vec3(0, 0, 1)};
  const SpaceMap m = SpaceMap::fit(s, d, FitOptions{1.0});
  EXPECT_THROW(m.map(Vec3(0, 0, 0), 1.7e308), InvalidInput);
  EXPECT_THROW(m.map(Vec3(0, 0, 0), NAN), InvalidInput);
  EXPECT_DOUBLE_EQ(m.map(Vec3(0, 0, 0), 1e6).z(), 1e6);
}
