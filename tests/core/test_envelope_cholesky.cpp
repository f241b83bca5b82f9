#include "csrbf/envelope_cholesky.hpp"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include <random>

using namespace csrbf;

namespace {

// A random symmetric positive definite matrix with a random variable-band profile.
EnvelopeMatrix random_spd(std::size_t n, unsigned seed, std::size_t max_band) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> band(0, max_band);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<std::size_t> first(n);
  for (std::size_t i = 0; i < n; ++i) first[i] = i - std::min(i, band(rng));
  EnvelopeMatrix a(first);
  std::vector<double> rowsum(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = first[i]; j < i; ++j) {
      const double v = u(rng);
      a.at(i, j) = v;
      rowsum[i] += std::abs(v);
      rowsum[j] += std::abs(v);
    }
  for (std::size_t i = 0; i < n; ++i) a.at(i, i) = rowsum[i] + 0.5 + std::abs(u(rng));  // diagonally dominant
  return a;
}

}  // namespace

TEST(EnvelopeCholesky, FactorMatchesEigenLLT) {
  for (std::size_t n : {1u, 2u, 5u, 40u, 300u}) {
    EnvelopeMatrix a = random_spd(n, unsigned(n), 12);
    const Eigen::MatrixXd dense = a.to_dense();
    a.cholesky_in_place();
    const Eigen::MatrixXd l_ref = Eigen::LLT<Eigen::MatrixXd>(dense).matrixL();
    const Eigen::MatrixXd l = a.to_dense();
    EXPECT_LT((l - l_ref).cwiseAbs().maxCoeff(), 1e-12) << "n=" << n;
    EXPECT_LT((l * l.transpose() - dense).cwiseAbs().maxCoeff(), 1e-12) << "n=" << n;
  }
}

TEST(EnvelopeCholesky, SolvesSeveralRightHandSides) {
  const std::size_t n = 500;
  EnvelopeMatrix a = random_spd(n, 7, 20);
  const Eigen::MatrixXd dense = a.to_dense();
  a.cholesky_in_place();
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int m : {1, 3, 7}) {
    RowMatrix b(n, m);
    for (Eigen::Index i = 0; i < b.size(); ++i) b.data()[i] = u(rng);
    RowMatrix x = b;
    a.solve_in_place(x);
    const Eigen::MatrixXd x_ref = Eigen::LLT<Eigen::MatrixXd>(dense).solve(Eigen::MatrixXd(b));
    EXPECT_LT((Eigen::MatrixXd(x) - x_ref).cwiseAbs().maxCoeff(), 1e-12) << "m=" << m;
    EXPECT_LT((dense * Eigen::MatrixXd(x) - Eigen::MatrixXd(b)).cwiseAbs().maxCoeff(), 1e-11);
  }
}

TEST(EnvelopeCholesky, ProfileAndPaperAccounting) {
  EnvelopeMatrix a(std::vector<std::size_t>{0, 0, 1, 3, 1});
  EXPECT_EQ(a.rows(), 5u);
  EXPECT_EQ(a.envelope_entries(), 0u + 1 + 1 + 0 + 3);
  EXPECT_EQ(a.bandwidth(), 3u);
  // 4-byte floats for diagonal and envelope plus a 4-byte index per row.
  EXPECT_EQ(a.paper_bytes(), 4u * (5 + 5) + 4u * 5);
  EXPECT_EQ(a.dense_bytes(), 100u);
  // The paper's figure-1 example: 32 points, 4096 bytes dense.
  EXPECT_EQ(EnvelopeMatrix(std::vector<std::size_t>(32, 0)).dense_bytes(), 4096u);
}

TEST(EnvelopeCholesky, EntriesOutsideTheEnvelopeAreZero) {
  EnvelopeMatrix a(std::vector<std::size_t>{0, 0, 2});
  a.at(1, 0) = 0.5;
  a.at(0, 0) = a.at(1, 1) = a.at(2, 2) = 2;
  EXPECT_EQ(a.coeff(2, 0), 0.0);
  EXPECT_EQ(a.coeff(0, 1), 0.5);
  a.cholesky_in_place();
  EXPECT_EQ(a.coeff(2, 0), 0.0);
  EXPECT_EQ(a.coeff(0, 1), 0.0);  // L is lower triangular
  EXPECT_NEAR(a.coeff(2, 2), std::sqrt(2.0), 1e-15);
}

TEST(EnvelopeCholesky, NonPositivePivotNamesTheRow) {
  EnvelopeMatrix a(std::vector<std::size_t>{0, 0, 0});
  // [[1, 1, 0], [1, 1, 0], [0, 0, 1]]: singular, the pivot of row 1 is 0.
  a.at(0, 0) = a.at(1, 0) = a.at(1, 1) = a.at(2, 2) = 1;
  try {
    a.cholesky_in_place();
    FAIL() << "expected NotPositiveDefinite";
  } catch (const NotPositiveDefinite& e) {
    EXPECT_EQ(e.row(), 1u);
    EXPECT_NE(std::string(e.what()).find("row 1"), std::string::npos);
  }
  EnvelopeMatrix neg(std::vector<std::size_t>{0});
  neg.at(0, 0) = -3;
  EXPECT_THROW(neg.cholesky_in_place(), NotPositiveDefinite);
}
