// The preconditioner of csrbf's conjugate gradients (private to csrbf::core): a block incomplete
// Cholesky factorisation IC(0) of A in CG's row order, M = L L^T with L restricted to A's lower
// pattern inside each block of consecutive rows (block Jacobi across blocks: the blocks factorise and
// solve in parallel, as PETSc's bjacobi + icc does on the MPI path's ranks).
//
// IC(0) exists for M-matrices; the CSRBF matrix is positive definite but not one, so a pivot can
// vanish. A block where one does is factorised again from A + alpha diag(A), alpha = 1e-3 and
// doubling (Manteuffel's shifted incomplete Cholesky, as Eigen's IncompleteCholesky does). L's values
// are kept in float: M only has to be symmetric positive definite and close to A, and a float half
// the bytes of a step's pass over L.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "csrbf/types.hpp"

namespace csrbf::detail {

/// The number of blocks for N rows: fixed by N alone (not by the threads), so that a fit gives the
/// same bits on any machine. One block up to kIcBlockRows rows, at most kIcMaxBlocks.
inline constexpr std::size_t kIcBlockRows = 150000;
inline constexpr std::size_t kIcMaxBlocks = 8;
std::size_t ic_blocks(std::size_t n) noexcept;

class IncompleteCholesky {
 public:
  /// A's rows in CG's order: row k's off-diagonal columns col[row[k] .. row[k+1]) (any order within
  /// a row, both triangles) and values, and the diagonal: `diagonal` on every row, or row k's
  /// row_diagonal[k] where that is not empty.
  IncompleteCholesky(std::span<const std::size_t> row, std::span<const std::uint32_t> col, std::span<const double> val,
                     double diagonal, std::span<const double> row_diagonal, std::size_t n);

  /// z = M^-1 r for n x m values (row-major, m <= 8), blocks in parallel.
  void apply(const double* r, double* z, std::size_t m) const;

  std::size_t nonzeros() const noexcept { return col_.size() + inv_diagonal_.size(); }
  std::size_t blocks() const noexcept { return block_start_.size() - 1; }
  /// The largest shift any block needed (0: plain IC(0) everywhere).
  double shift() const noexcept { return shift_; }
  double bytes() const noexcept { return bytes(col_.size(), inv_diagonal_.size()); }
  /// Bytes of a factor with `lower` entries below the diagonal for N rows.
  static double bytes(std::size_t lower, std::size_t n) noexcept { return 8.0 * double(lower) + 16.0 * double(n + 1); }

 private:
  std::vector<std::size_t> block_start_;  // block b holds rows [block_start_[b], block_start_[b + 1])
  std::vector<std::size_t> row_;          // L's row k: col_/val_[row_[k] .. row_[k + 1]), columns ascending
  FillVector<std::uint32_t> col_;
  FillVector<float> val_;
  FillVector<double> inv_diagonal_;  // 1 / L_kk
  double shift_ = 0;
};

}  // namespace csrbf::detail
