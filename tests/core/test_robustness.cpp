// Near-duplicate sources and huge coordinates (issue: numerical robustness).
#include "csrbf/space_map.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "test_points.hpp"

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
  // A scene 1e6 units from the origin: the same displacements as at the origin, to the rounding of
  // the inputs themselves (an ulp of 1e6 is 1.2e-10).
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> s, d;
  for (int i = 0; i < 400; ++i) {
    const Vec3 p(u(rng), u(rng), u(rng));
    s.push_back(p);
    d.push_back(p + Vec3(0.01 * u(rng), 0.02, 0));
  }
  std::vector<double> x;
  for (int i = 0; i < 3000; ++i)
    for (int c = 0; c < 3; ++c) x.push_back(u(rng));
  for (Polynomial poly : {Polynomial::None, Polynomial::Linear}) {
    const Vec3 off(1e6, -1e6, 1e6);
    std::vector<Vec3> so = s, dof = d;
    for (auto& p : so) p += off;
    for (auto& p : dof) p += off;
    const auto centred = SpaceMap::fit(s, d, FitOptions{0.3, Kernel::C2, poly});
    const auto far = SpaceMap::fit(so, dof, FitOptions{0.3, Kernel::C2, poly});
    std::vector<double> xo = x;
    for (std::size_t i = 0; i < xo.size(); ++i) xo[i] += off[Eigen::Index(i % 3)];
    std::vector<double> a(x.size()), b(x.size());
    centred.displacements(x.data(), a.data(), x.size() / 3);
    far.displacements(xo.data(), b.data(), x.size() / 3);
    double worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
    EXPECT_LT(worst, 1e-9) << "polynomial " << int(poly);
    EXPECT_LT(far.stats().residual_relative, 1e-12);
  }
}
