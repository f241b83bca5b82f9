#include "csrbf/envelope_cholesky.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <sstream>

namespace csrbf {

namespace {
std::string pivot_message(std::size_t row, double pivot) {
  std::ostringstream os;
  os << "matrix is not positive definite: pivot " << pivot << " at row " << row;
  return os.str();
}

double dot(const double* a, const double* b, std::size_t n) noexcept {
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  std::size_t k = 0;
  for (; k + 4 <= n; k += 4) {
    s0 += a[k] * b[k];
    s1 += a[k + 1] * b[k + 1];
    s2 += a[k + 2] * b[k + 2];
    s3 += a[k + 3] * b[k + 3];
  }
  for (; k < n; ++k) s0 += a[k] * b[k];
  return (s0 + s1) + (s2 + s3);
}
}  // namespace

NotPositiveDefinite::NotPositiveDefinite(std::size_t row, double pivot)
    : Error(pivot_message(row, pivot)), row_(row), pivot_(pivot) {}
NotPositiveDefinite::NotPositiveDefinite(const std::string& message)
    : Error(message), row_(std::size_t(-1)), pivot_(std::numeric_limits<double>::quiet_NaN()) {}

EnvelopeMatrix::EnvelopeMatrix(std::vector<std::size_t> first_column) : first_(std::move(first_column)) {
  start_.resize(first_.size() + 1);
  start_[0] = 0;
  for (std::size_t i = 0; i < first_.size(); ++i) {
    assert(first_[i] <= i && "first_column(i) must be <= i");
    start_[i + 1] = start_[i] + (i - first_[i] + 1);
  }
  values_.assign(start_.back(), 0.0);
}

double EnvelopeMatrix::coeff(std::size_t i, std::size_t j) const noexcept {
  if (j > i) {
    if (factorized_) return 0.0;
    std::swap(i, j);
  }
  return j < first_[i] ? 0.0 : at(i, j);
}

std::size_t EnvelopeMatrix::bandwidth() const noexcept {
  std::size_t b = 0;
  for (std::size_t i = 0; i < first_.size(); ++i) b = std::max(b, i - first_[i]);
  return b;
}

void EnvelopeMatrix::cholesky_in_place() {
  assert(!factorized_ && "cholesky_in_place called twice");
  const std::size_t n = rows();
  constexpr double tiny = 64 * std::numeric_limits<double>::epsilon();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t fi = first_[i];
    double* li = values_.data() + start_[i];  // li[c - fi] = L(i, c)
    for (std::size_t j = fi; j < i; ++j) {
      const std::size_t lo = std::max(fi, first_[j]);
      const double* lj = values_.data() + start_[j];
      const double s = li[j - fi] - dot(li + (lo - fi), lj + (lo - first_[j]), j - lo);
      li[j - fi] = s / lj[j - first_[j]];
    }
    const double a = li[i - fi];
    const double d = a - dot(li, li, i - fi);
    if (!(d > tiny * std::abs(a))) throw NotPositiveDefinite(i, d);
    li[i - fi] = std::sqrt(d);
  }
  factorized_ = true;
}

void EnvelopeMatrix::solve_in_place(RowMatrix& b) const {
  assert(factorized_ && "call cholesky_in_place first");
  assert(std::size_t(b.rows()) == rows());
  const std::size_t n = rows();
  const Eigen::Index m = b.cols();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t fi = first_[i];
    const double* li = values_.data() + start_[i];
    double* bi = b.data() + i * m;
    for (std::size_t k = fi; k < i; ++k) {
      const double l = li[k - fi];
      const double* bk = b.data() + k * m;
      for (Eigen::Index c = 0; c < m; ++c) bi[c] -= l * bk[c];
    }
    const double inv = 1.0 / li[i - fi];
    for (Eigen::Index c = 0; c < m; ++c) bi[c] *= inv;
  }
  for (std::size_t i = n; i-- > 0;) {
    const std::size_t fi = first_[i];
    const double* li = values_.data() + start_[i];
    double* bi = b.data() + i * m;
    const double inv = 1.0 / li[i - fi];
    for (Eigen::Index c = 0; c < m; ++c) bi[c] *= inv;
    for (std::size_t k = fi; k < i; ++k) {
      const double l = li[k - fi];
      double* bk = b.data() + k * m;
      for (Eigen::Index c = 0; c < m; ++c) bk[c] -= l * bi[c];
    }
  }
}

Eigen::MatrixXd EnvelopeMatrix::to_dense() const {
  const auto n = Eigen::Index(rows());
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (std::size_t j = first_[i]; j <= std::size_t(i); ++j) {
      d(i, Eigen::Index(j)) = at(std::size_t(i), j);
      if (!factorized_) d(Eigen::Index(j), i) = at(std::size_t(i), j);
    }
  return d;
}

}  // namespace csrbf
