// Jennings profile (envelope, "variable band") storage of a symmetric matrix and its in-place
// Cholesky factorisation (Jennings 1966, "A compact storage scheme for the solution of symmetric
// linear simultaneous equations"; George & Liu 1981, ch. 4).
//
// Row i stores columns first(i) .. i contiguously (the diagonal last). Everything left of first(i)
// is zero in A and stays zero in the factor L, so the factorisation needs no extra memory: the rows
// of L overwrite the rows of A.
#pragma once

#include "csrbf/errors.hpp"
#include "csrbf/types.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace csrbf {

class EnvelopeMatrix {
 public:
  EnvelopeMatrix() = default;
  /// first_column[i] <= i: the first column of row i's envelope. All stored entries start at zero.
  explicit EnvelopeMatrix(std::vector<std::size_t> first_column);

  std::size_t rows() const noexcept { return first_.size(); }
  std::size_t first_column(std::size_t i) const noexcept { return first_[i]; }
  /// Reference to the stored entry (i, j), first_column(i) <= j <= i.
  double& at(std::size_t i, std::size_t j) noexcept { return values_[start_[i] + (j - first_[i])]; }
  double at(std::size_t i, std::size_t j) const noexcept { return values_[start_[i] + (j - first_[i])]; }
  /// Entry (i, j) of the symmetric matrix (or of L once factorised, for j <= i); zero outside.
  double coeff(std::size_t i, std::size_t j) const noexcept;
  /// Row i's stored entries, columns first_column(i) .. i.
  std::span<const double> row(std::size_t i) const noexcept { return {values_.data() + start_[i], i - first_[i] + 1}; }

  std::size_t envelope_entries() const noexcept { return values_.size() - rows(); }  ///< off-diagonal
  std::size_t bandwidth() const noexcept;
  /// Bytes in the paper's accounting (section 4.2): 4-byte floats for the diagonal and the
  /// off-diagonal envelope plus one 4-byte first-column index per row. Compare dense_bytes().
  std::size_t paper_bytes() const noexcept { return 4 * (rows() + envelope_entries()) + 4 * rows(); }
  std::size_t dense_bytes() const noexcept { return 4 * rows() * rows(); }
  /// Bytes this object actually holds (doubles and size_t indices).
  std::size_t storage_bytes() const noexcept {
    return values_.size() * sizeof(double) + (first_.size() + start_.size()) * sizeof(std::size_t);
  }

  /// Overwrites the lower triangle with L, A = L L^T. Throws NotPositiveDefinite naming the row.
  void cholesky_in_place();
  bool factorized() const noexcept { return factorized_; }
  /// Solves A X = B for B (rows() x m, row-major) in place by forward and back substitution with L.
  void solve_in_place(RowMatrix& b) const;

  /// The whole symmetric matrix (or L, lower triangular, once factorised), for tests.
  Eigen::MatrixXd to_dense() const;

 private:
  std::vector<std::size_t> first_, start_;
  std::vector<double> values_;
  bool factorized_ = false;
};

}  // namespace csrbf
