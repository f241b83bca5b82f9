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
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, values_.size(), 1 << 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t e = r.begin(); e < r.end(); ++e)
                        values_[e] = wendland(kernel, std::sqrt(values_[e]) * inv_r);
                    });
}

RowMatrix KernelMatrix::operator*(const RowMatrix& x) const {
  const std::size_t n = size();
  const auto m = x.cols();
  RowMatrix y(x.rows(), m);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const auto k = Eigen::Index(i);
      y.row(k) = diagonal_ * x.row(k);
      const auto nb = pattern_.neighbors_of(i);
      const auto v = values_of(i);
      for (std::size_t e = 0; e < nb.size(); ++e) y.row(k) += v[e] * x.row(Eigen::Index(nb[e]));
    }
  });
  return y;
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
    env.at(k, k) = a.diagonal();
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
