#include "csrbf/kernel_matrix.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace csrbf {

KernelMatrix::KernelMatrix(AdjacencyGraph graph, Kernel kernel, double radius)
    : pattern_(std::move(graph)), kernel_(kernel), radius_(radius), diagonal_(wendland(kernel, 0.0)) {
  values_ = std::move(pattern_.dist2);
  pattern_.dist2 = {};
  const double inv_r = 1.0 / radius;
  const auto entries = [&](std::size_t b, std::size_t e) {
    for (; b < e; ++b) values_[b] = wendland(kernel, std::sqrt(values_[b]) * inv_r);
  };
  // A small matrix in the calling thread: TBB's first use starts its threads (milliseconds, which
  // csrbf info reported as the fish's assembly).
  constexpr std::size_t grain = std::size_t(1) << 16;
  if (values_.size() <= grain)
    entries(0, values_.size());
  else
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, values_.size(), grain),
                      [&](const tbb::blocked_range<std::size_t>& r) { entries(r.begin(), r.end()); });
}

RowMatrix KernelMatrix::operator*(const RowMatrix& x) const {
  const std::size_t n = size();
  const auto m = x.cols();
  RowMatrix y(x.rows(), m);
  const auto rows = [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const auto k = Eigen::Index(i);
      y.row(k) = diagonal(i) * x.row(k);
      const auto nb = pattern_.neighbors_of(i);
      const auto v = values_of(i);
      for (std::size_t j = 0; j < nb.size(); ++j) y.row(k) += v[j] * x.row(Eigen::Index(nb[j]));
    }
  };
  constexpr std::size_t grain = 4096;
  if (n <= grain) {
    rows(0, n);
    return y;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                    [&](const tbb::blocked_range<std::size_t>& r) { rows(r.begin(), r.end()); });
  return y;
}

void KernelMatrix::add_to_diagonal(std::span<const double> shift) {
  if (shift.empty()) return;
  const std::size_t n = size();
  if (row_diagonal_.empty()) row_diagonal_.assign(n, diagonal_);
  for (std::size_t i = 0; i < n; ++i) row_diagonal_[i] += shift.size() == 1 ? shift[0] : shift[i];
}

std::pair<std::size_t, std::size_t> KernelMatrix::closest_pair() const noexcept {
  double best = -1;
  std::pair<std::size_t, std::size_t> pair{0, 0};
  for (std::size_t i = 0; i < size(); ++i) {
    const auto nb = pattern_.neighbors_of(i);
    const auto v = values_of(i);
    for (std::size_t e = 0; e < nb.size(); ++e)
      if (v[e] > best) {
        best = v[e];
        pair = {std::min<std::size_t>(i, nb[e]), std::max<std::size_t>(i, nb[e])};
      }
  }
  return pair;
}

EnvelopeMatrix envelope_matrix(const KernelMatrix& a, std::span<const std::uint32_t> order,
                               std::vector<std::size_t> first_columns) {
  const std::size_t n = a.size();
  std::vector<std::uint32_t> pos(n);
  for (std::size_t k = 0; k < n; ++k) pos[order[k]] = std::uint32_t(k);
  EnvelopeMatrix env(std::move(first_columns));
  for (std::size_t k = 0; k < n; ++k) {
    env.at(k, k) = a.diagonal(order[k]);
    const auto nb = a.pattern().neighbors_of(order[k]);
    const auto v = a.values_of(order[k]);
    for (std::size_t e = 0; e < nb.size(); ++e)
      if (pos[nb[e]] < k) env.at(k, pos[nb[e]]) = v[e];
  }
  return env;
}

EnvelopeMatrix kernel_matrix(const AdjacencyGraph& g, std::span<const std::uint32_t> order, Kernel kernel,
                             double radius) {
  return envelope_matrix(KernelMatrix(g, kernel, radius), order, envelope_first_columns(g, order));
}

}  // namespace csrbf
