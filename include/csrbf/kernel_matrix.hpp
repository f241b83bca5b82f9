// The CSRBF matrix A = [phi(||s_i - s_j|| / R)] of a set of sources (paper eq. 2), sparse: phi(0) on
// the diagonal and one entry for each pair of sources closer than R, in the compressed rows of their
// neighbour graph. Its entries are computed once, when it is built, and serve every solver's
// assembly (envelope, CHOLMOD, Eigen, CG), the residual check and the condition estimate.
#pragma once

#include "csrbf/envelope_cholesky.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/ordering.hpp"
#include "csrbf/types.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace csrbf {

class KernelMatrix {
 public:
  KernelMatrix() = default;
  /// Takes the neighbour graph of the sources (input order): its squared distances become the
  /// entries, in place, so that A costs no memory beyond the graph.
  KernelMatrix(AdjacencyGraph graph, Kernel kernel, double radius);

  std::size_t size() const noexcept { return pattern_.size(); }
  Kernel kernel() const noexcept { return kernel_; }
  double radius() const noexcept { return radius_; }
  /// phi(0), the diagonal of the plain CSRBF matrix (every row's, unless add_to_diagonal changed it).
  double diagonal() const noexcept { return diagonal_; }
  /// Row i's diagonal entry: phi(0), plus its shift where add_to_diagonal gave one.
  double diagonal(std::size_t i) const noexcept { return row_diagonal_.empty() ? diagonal_ : row_diagonal_[i]; }
  /// Whether every row's diagonal is phi(0) (no shift).
  bool constant_diagonal() const noexcept { return row_diagonal_.empty(); }
  /// A + diag(shift): the smoothing of an approximation (csrbf::Interpolator), shift one value for
  /// every row or one a row, each >= 0 and finite (the matrix stays positive definite).
  void add_to_diagonal(std::span<const double> shift);
  /// The off-diagonal pattern: row i's columns, ascending (its dist2 is empty: the values hold them).
  const AdjacencyGraph& pattern() const noexcept { return pattern_; }
  /// Row i's off-diagonal entries, beside pattern().neighbors_of(i).
  std::span<const double> values_of(std::size_t i) const noexcept {
    return {values_.data() + pattern_.offsets[i], pattern_.degree(i)};
  }
  std::span<const double> values() const noexcept { return values_; }
  /// y = A x for x, y of n x m (rows in the input order of the sources), in parallel over rows.
  RowMatrix operator*(const RowMatrix& x) const;
  /// The two sources of the largest off-diagonal entry: the closest pair (phi decreases with the
  /// distance). {0, 0} when A is diagonal.
  std::pair<std::size_t, std::size_t> closest_pair() const noexcept;

 private:
  AdjacencyGraph pattern_;
  FillVector<double> values_;
  std::vector<double> row_diagonal_;  // empty: phi(0) on every row
  Kernel kernel_ = Kernel::C2;
  double radius_ = 1.0, diagonal_ = 1.0;
};

/// A in Jennings envelope form, row k being the source order[k] (unfactorised), with the first
/// columns of envelope_first_columns(a.pattern(), order).
EnvelopeMatrix envelope_matrix(const KernelMatrix& a, std::span<const std::uint32_t> order,
                               std::vector<std::size_t> first_columns);
/// The same from a neighbour graph with its squared distances.
EnvelopeMatrix kernel_matrix(const AdjacencyGraph& g, std::span<const std::uint32_t> order, Kernel kernel,
                             double radius);

}  // namespace csrbf
