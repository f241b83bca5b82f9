#include "incomplete_cholesky.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

namespace csrbf::detail {

std::size_t ic_blocks(std::size_t n) noexcept {
  return std::clamp<std::size_t>((n + kIcBlockRows - 1) / kIcBlockRows, 1, kIcMaxBlocks);
}

IncompleteCholesky::IncompleteCholesky(std::span<const std::size_t> row, std::span<const std::uint32_t> col,
                                       std::span<const double> val, double diagonal,
                                       std::span<const double> row_diagonal, std::size_t n) {
  const std::size_t nb = n == 0 ? 1 : ic_blocks(n);
  block_start_.resize(nb + 1);
  for (std::size_t b = 0; b <= nb; ++b) block_start_[b] = n * b / nb;
  // L's pattern: the entries of A's row k with columns in [start of k's block, k).
  row_.assign(n + 1, 0);
  for (std::size_t b = 0; b < nb; ++b) {
    const std::size_t first = block_start_[b];
    for (std::size_t k = first; k < block_start_[b + 1]; ++k) {
      std::size_t count = 0;
      for (std::size_t e = row[k]; e < row[k + 1]; ++e) count += col[e] >= first && col[e] < k;
      row_[k + 1] = row_[k] + count;
    }
  }
  col_.resize(row_[n]);
  val_.resize(row_[n]);
  inv_diagonal_.resize(n);
  std::vector<double> shifts(nb, 0.0);
  tbb::parallel_for(std::size_t(0), nb, [&](std::size_t b) {
    const std::size_t first = block_start_[b], last = block_start_[b + 1];
    // A's lower entries of the block, columns ascending, in double; L is computed over them.
    std::vector<std::pair<std::uint32_t, double>> entries;
    for (std::size_t k = first; k < last; ++k) {
      entries.clear();
      for (std::size_t e = row[k]; e < row[k + 1]; ++e)
        if (col[e] >= first && col[e] < k) entries.emplace_back(col[e], val[e]);
      std::sort(entries.begin(), entries.end());
      for (std::size_t e = 0; e < entries.size(); ++e) col_[row_[k] + e] = entries[e].first;
    }
    // position[j - first]: where column j sits in the row being factorised, or -1.
    std::vector<std::int64_t> position(last - first, -1);
    std::vector<double> lrow;
    for (double alpha = 0;; alpha = alpha == 0 ? 1e-3 : 2 * alpha) {
      const double scale = 1 + alpha;
      bool broke = false;
      for (std::size_t k = first; k < last && !broke; ++k) {
        const std::size_t begin = row_[k], end = row_[k + 1];
        lrow.assign(end - begin, 0.0);
        for (std::size_t e = row[k]; e < row[k + 1]; ++e)
          if (col[e] >= first && col[e] < k) {
            const auto at =
                std::lower_bound(col_.begin() + std::ptrdiff_t(begin), col_.begin() + std::ptrdiff_t(end), col[e]) -
                col_.begin();
            lrow[std::size_t(at) - begin] = val[e];
          }
        for (std::size_t e = begin; e < end; ++e) position[col_[e] - first] = std::int64_t(e - begin);
        // Row k of L, left to right: L_kj = (A_kj - sum_{i<j} L_ki L_ji) / L_jj, over the pattern.
        double sum_squares = 0;
        for (std::size_t e = begin; e < end; ++e) {
          const std::size_t j = col_[e];
          double s = lrow[e - begin];
          for (std::size_t f = row_[j]; f < row_[j + 1]; ++f) {
            const std::int64_t at = position[col_[f] - first];
            if (at >= 0 && std::size_t(at) < e - begin) s -= lrow[std::size_t(at)] * double(val_[f]);
          }
          const float l = float(s * inv_diagonal_[j]);
          val_[e] = l;
          lrow[e - begin] = double(l);
          sum_squares += double(l) * double(l);
        }
        for (std::size_t e = begin; e < end; ++e) position[col_[e] - first] = -1;
        const double d = (row_diagonal.empty() ? diagonal : row_diagonal[k]) * scale;
        const double pivot = d - sum_squares;
        // A pivot that vanishes against the diagonal (or worse) makes M near singular: shift again.
        if (!(pivot > 1e-6 * d)) {
          broke = true;
          break;
        }
        inv_diagonal_[k] = 1.0 / std::sqrt(pivot);
      }
      if (!broke) {
        shifts[b] = alpha;
        break;
      }
      if (alpha > 1e6) {  // A + 1e6 diag(A) is diagonally dominant: unreachable for a finite A
        for (std::size_t k = first; k < last; ++k) {
          for (std::size_t e = row_[k]; e < row_[k + 1]; ++e) val_[e] = 0;
          inv_diagonal_[k] = 1.0 / std::sqrt(row_diagonal.empty() ? diagonal : row_diagonal[k]);
        }
        shifts[b] = std::numeric_limits<double>::infinity();
        break;
      }
    }
  });
  shift_ = *std::max_element(shifts.begin(), shifts.end());
}

namespace {
/// The two triangular solves of one block for M right-hand sides (M = 0: m of them, known at run
/// time; 1, 3 and 4 are compiled for: the condition estimate, the displacements, the polynomial).
template <std::size_t M>
void solve_block(std::size_t first, std::size_t last, const std::size_t* row, const std::uint32_t* col,
                 const float* val, const double* inv_diagonal, const double* r, double* z, std::size_t m_run) {
  const std::size_t m = M ? M : m_run;
  // L y = r, row by row.
  for (std::size_t k = first; k < last; ++k) {
    double t[8];
    for (std::size_t c = 0; c < m; ++c) t[c] = r[k * m + c];
    for (std::size_t e = row[k]; e < row[k + 1]; ++e) {
      const double l = double(val[e]);
      const double* y = z + std::size_t(col[e]) * m;
      for (std::size_t c = 0; c < m; ++c) t[c] -= l * y[c];
    }
    for (std::size_t c = 0; c < m; ++c) z[k * m + c] = t[c] * inv_diagonal[k];
  }
  // L^T z = y in place, last row first: row k's x_k is final once the rows after it have given
  // their parts, and it then gives its own to its columns.
  for (std::size_t k = last; k-- > first;) {
    double x[8];
    for (std::size_t c = 0; c < m; ++c) x[c] = z[k * m + c] * inv_diagonal[k];
    for (std::size_t c = 0; c < m; ++c) z[k * m + c] = x[c];
    for (std::size_t e = row[k]; e < row[k + 1]; ++e) {
      const double l = double(val[e]);
      double* y = z + std::size_t(col[e]) * m;
      for (std::size_t c = 0; c < m; ++c) y[c] -= l * x[c];
    }
  }
}
}  // namespace

void IncompleteCholesky::apply(const double* r, double* z, std::size_t m) const {
  tbb::parallel_for(std::size_t(0), blocks(), [&](std::size_t b) {
    const std::size_t first = block_start_[b], last = block_start_[b + 1];
    const auto run = [&](auto fixed) {
      solve_block<decltype(fixed)::value>(first, last, row_.data(), col_.data(), val_.data(), inv_diagonal_.data(), r,
                                          z, m);
    };
    switch (m) {
      case 1:
        return run(std::integral_constant<std::size_t, 1>{});
      case 3:
        return run(std::integral_constant<std::size_t, 3>{});
      case 4:
        return run(std::integral_constant<std::size_t, 4>{});
      default:
        return run(std::integral_constant<std::size_t, 0>{});
    }
  });
}

}  // namespace csrbf::detail
