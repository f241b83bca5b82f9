#include "sparse_solver.hpp"

#include "csrbf/errors.hpp"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#ifdef CSRBF_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif

#include <cmath>
#include <mutex>

namespace csrbf::detail {

namespace {

using Sparse = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// Lower triangle of A (diagonal included), column-compressed.
Sparse lower_matrix(const AdjacencyGraph& g, Kernel kernel, double radius) {
  const std::size_t n = g.size();
  const double inv_r = 1.0 / radius, phi0 = wendland(kernel, 0.0);
  const auto en = Eigen::Index(n);
  Sparse a(en, en);
  Eigen::VectorXi per_col(en);
  for (std::size_t j = 0; j < n; ++j) {
    int c = 1;
    for (std::uint32_t i : g.neighbors_of(j)) c += i > j;
    per_col(Eigen::Index(j)) = c;
  }
  a.reserve(per_col);
  for (std::size_t j = 0; j < n; ++j) {
    a.insert(Eigen::Index(j), Eigen::Index(j)) = phi0;
    const auto nb = g.neighbors_of(j);
    const auto d2 = g.dist2_of(j);
    for (std::size_t e = 0; e < nb.size(); ++e)
      if (nb[e] > j) a.insert(Eigen::Index(nb[e]), Eigen::Index(j)) = wendland(kernel, std::sqrt(d2[e]) * inv_r);
  }
  a.makeCompressed();
  return a;
}

// The correlation dimension of the sources, from the graph: pairs closer than R against pairs closer
// than R/2 is 2^d (4 on a surface, 8 in a volume).
double correlation_dimension(const AdjacencyGraph& g, double radius) {
  const double quarter = radius * radius / 4.0;
  std::size_t all = 0, near = 0;
  for (std::size_t i = 0; i < g.size(); ++i)
    for (double d2 : g.dist2_of(i)) {
      ++all;
      near += d2 < quarter;
    }
  return near > 0 ? std::log2(double(all) / double(near)) : 3.0;
}

template <class Decomposition>
class EigenFactor final : public SparseFactor {
 public:
  EigenFactor(const Sparse& a, const char* name, double dimension = 3.0) : dimension_(dimension) {
    init(a);
    if (llt_.info() != Eigen::Success)
      throw NotPositiveDefinite(std::string("the interpolation matrix is not numerically positive definite (") +
                                name + " factorisation failed)");
  }
  void solve_in_place(RowMatrix& b) const override {
    std::lock_guard lock(mutex_);  // CHOLMOD's workspace is shared by solves
    const Eigen::MatrixXd x = llt_.solve(Eigen::MatrixXd(b));
    b = x;
  }
  std::size_t nonzeros() const override { return count(); }

 private:
  void init(const Sparse& a) { llt_.compute(a); }
  std::size_t count() const;
  double dimension_;
  mutable Decomposition llt_;
  mutable std::mutex mutex_;
};

using Simplicial = Eigen::SimplicialLLT<Sparse, Eigen::Lower, Eigen::AMDOrdering<int>>;
template <>
std::size_t EigenFactor<Simplicial>::count() const {
  return std::size_t(llt_.matrixL().nestedExpression().nonZeros());
}
#ifdef CSRBF_HAVE_CHOLMOD
using Supernodal = Eigen::CholmodSupernodalLLT<Sparse, Eigen::Lower>;
template <>
void EigenFactor<Supernodal>::init(const Sparse& a) {
  llt_.cholmod().supernodal = CHOLMOD_SUPERNODAL;
  // One fill-reducing ordering, chosen by the shape of the sources, instead of CHOLMOD's default
  // (AMD, then METIS too when the fill is large, keeping the smaller fill). On control points that
  // lie on a surface (dimension about 2) AMD's factor is the faster one, on volumes METIS's; trying
  // both costs the second analysis (measured in docs/PERFORMANCE.md, N = 1e5: sphere 1.7 s with AMD
  // against 2.2 s by default, cube 3.6 s with METIS against 5.2 s).
  llt_.cholmod().nmethods = 1;
  llt_.cholmod().method[0].ordering = dimension_ < 2.5 ? CHOLMOD_AMD : CHOLMOD_METIS;
  llt_.compute(a);
}
template <>
std::size_t EigenFactor<Supernodal>::count() const {
  // CHOLMOD's own count of the factor's entries (the supernodes' dense blocks).
  return std::size_t(llt_.cholmod().lnz);
}
#endif

}  // namespace

std::unique_ptr<SparseFactor> factor_sparse(const AdjacencyGraph& g, Kernel kernel, double radius, Solver which) {
  const Sparse a = lower_matrix(g, kernel, radius);
  if (which == Solver::Eigen) return std::make_unique<EigenFactor<Simplicial>>(a, "Eigen SimplicialLLT");
#ifdef CSRBF_HAVE_CHOLMOD
  if (which == Solver::Cholmod)
    return std::make_unique<EigenFactor<Supernodal>>(a, "CHOLMOD", correlation_dimension(g, radius));
#endif
  throw InvalidInput(std::string("solver '") + std::string(solver_name(which)) +
                     "' is not available in this build of csrbf");
}

}  // namespace csrbf::detail
