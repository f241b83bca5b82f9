// The CSRBF matrix A built once from the neighbour graph, against a dense matrix computed from the
// points (csrbf/kernel_matrix.hpp).
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/space_map.hpp"

#include <gtest/gtest.h>

#include "test_points.hpp"

#include <cmath>
#include <random>

using namespace csrbf;

TEST(KernelMatrix, EqualsTheDenseMatrixOfThePoints) {
  std::mt19937 rng(301);
  const auto pts = test::random_points(400, rng);
  const double r = 0.25;
  for (Kernel k : {Kernel::C0, Kernel::C2, Kernel::C4, Kernel::C6}) {
    const KernelMatrix a(AdjacencyGraph::brute_force(pts, r), k, r);
    ASSERT_EQ(a.size(), pts.size());
    EXPECT_TRUE(a.pattern().dist2.empty());  // the squared distances became the entries
    const auto n = Eigen::Index(pts.size());
    Eigen::MatrixXd dense(n, n);
    for (std::size_t i = 0; i < pts.size(); ++i)
      for (std::size_t j = 0; j < pts.size(); ++j)
        dense(Eigen::Index(i), Eigen::Index(j)) = wendland(k, (pts[i] - pts[j]).norm() / r);
    Eigen::MatrixXd from_a = Eigen::MatrixXd::Zero(dense.rows(), dense.cols());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      from_a(Eigen::Index(i), Eigen::Index(i)) = a.diagonal();
      const auto nb = a.pattern().neighbors_of(i);
      const auto v = a.values_of(i);
      for (std::size_t e = 0; e < nb.size(); ++e) from_a(Eigen::Index(i), Eigen::Index(nb[e])) = v[e];
    }
    EXPECT_LT((from_a - dense).cwiseAbs().maxCoeff(), 1e-14) << kernel_name(k);
    // The product, several columns at once.
    const RowMatrix x = RowMatrix::Random(n, 3);
    const Eigen::MatrixXd want = dense * Eigen::MatrixXd(x);
    EXPECT_LT((Eigen::MatrixXd(a * x) - want).cwiseAbs().maxCoeff(), 1e-12) << kernel_name(k);
    // The envelope form, in an ordering, holds the same entries.
    const auto order = reverse_cuthill_mckee_order(a.pattern());
    const EnvelopeMatrix env = envelope_matrix(a, order, envelope_first_columns(a.pattern(), order));
    for (std::size_t row = 0; row < pts.size(); ++row)
      for (std::size_t col = env.first_column(row); col <= row; ++col)
        EXPECT_NEAR(env.at(row, col), dense(Eigen::Index(order[row]), Eigen::Index(order[col])), 1e-14);
    // The closest pair, by brute force.
    double best = 1e300;
    std::size_t bi = 0, bj = 0;
    for (std::size_t i = 0; i < pts.size(); ++i)
      for (std::size_t j = i + 1; j < pts.size(); ++j)
        if ((pts[i] - pts[j]).norm() < best) best = (pts[i] - pts[j]).norm(), bi = i, bj = j;
    EXPECT_EQ(a.closest_pair(), std::make_pair(bi, bj));
  }
}

TEST(KernelMatrix, AFitSharesItsMatrix) {
  // The map's matrix is the one its residual was measured with: A alpha + p(s) = g at the controls.
  std::mt19937 rng(302);
  const auto s = test::random_points(700, rng);
  std::vector<Vec3> d = s;
  for (auto& p : d) p += Vec3(0.01 * p.y(), 0, -0.02 * p.x());
  const SpaceMap m = SpaceMap::fit(s, d, {0.2, Kernel::C4, Polynomial::None});
  const RowMatrix av = m.matrix() * RowMatrix(m.coefficients());
  for (std::size_t i = 0; i < s.size(); ++i)
    EXPECT_LT((av.row(Eigen::Index(i)).transpose() - (d[i] - s[i])).norm(), 1e-9);
  EXPECT_EQ(m.matrix().values().size(), 2 * m.stats().neighbor_pairs);
}
