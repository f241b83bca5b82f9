#include "sparse_solver.hpp"

#include "incomplete_cholesky.hpp"
#include "schwarz.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#ifdef CSRBF_HAVE_CHOLMOD
#include "cholmod_loader.hpp"
#include <Eigen/CholmodSupport>
#endif

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <span>
#include <utility>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

namespace csrbf::detail {

void KernelSolver::solve_in_place(RowMatrix& b, const RowMatrix* initial) {
  const SolveStatus s = solve(b, initial);
  if (!s.ok()) throw CgStagnated(s);
}

double kernel_matrix_bytes(const KernelMatrix& a) {
  return 12.0 * double(a.values().size()) + 8.0 * double(a.size() + 1);
}

double address_space_room() noexcept {
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY)
    return std::numeric_limits<double>::infinity();
  unsigned long long pages = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%llu", &pages) != 1) pages = 0;
    std::fclose(f);
  }
  return double(limit.rlim_cur) - double(pages) * double(::sysconf(_SC_PAGESIZE));
}

void check_address_space(double need, const char* what, const char* instead) {
  const double room = address_space_room();
  if (room >= need) return;
  std::ostringstream os;
  os.precision(3);
  os << "CHOLMOD needs about " << need / kGiB << " GiB of address space for " << what
     << ", and the address-space limit (ulimit -v) leaves " << std::max(room, 0.0) / kGiB
     << " GiB of it: raise that limit, or " << instead;
  throw ResourceLimit(os.str());
}

double envelope_factor_bytes(double off_diagonal, std::size_t n) {
  return 8.0 * (off_diagonal + double(n)) + 16.0 * double(n);  // 8-byte values, two 8-byte indices a row
}

double schwarz_share(std::size_t entries, std::size_t n) { return 12.0 * double(entries) + 320.0 * double(n); }

double cg_bytes(std::size_t entries, std::size_t n, bool schwarz, bool copy) {
  // Rows (8-byte offsets), columns (4 bytes) and values (8) where A is copied into CG's order, its
  // order (4 bytes a row); x, r, p, q and z of up to 8 right-hand sides; the incomplete Cholesky
  // factor (half the entries, in case a solve turns to it), or with `schwarz` the larger of it and
  // the Schwarz patches' share, and its copy of the points (24 bytes each) where it copies A; the
  // residual histories of the stagnation check and the probe.
  return (copy ? 12.0 * double(entries) + 8.0 * double(n + 1) : 0.0) + 4.0 * double(n + 1) + 5.0 * 8 * 8 * double(n) +
         (schwarz ? std::max(schwarz_share(entries, n), IncompleteCholesky::bytes(entries / 2, n)) +
                        (copy ? 24.0 * double(n) : 0.0)
                  : IncompleteCholesky::bytes(entries / 2, n)) +
         (8.0 + 128.0) * double(std::min<std::size_t>(kCgMaxIterations, 1u << 20));
}

namespace {

using Sparse = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// Lower triangle of A (diagonal included), column-compressed, with row and column k the source
// order[k] (the identity when order is empty).
Sparse lower_matrix(const KernelMatrix& m, std::span<const std::uint32_t> order = {}) {
  const std::size_t n = m.size();
  const AdjacencyGraph& g = m.pattern();
  std::vector<std::uint32_t> position(n);  // of each source
  for (std::size_t k = 0; k < n; ++k) position[order.empty() ? k : order[k]] = std::uint32_t(k);
  const auto source = [&](std::size_t k) { return order.empty() ? k : std::size_t(order[k]); };
  // The compressed arrays are written directly, each column sorted by row: Eigen's insert() shifts
  // the entries of a column at each out-of-order row (30-50 ms at N = 1e4 with 100 neighbours).
  std::vector<int> outer(n + 1, 0);
  for (std::size_t k = 0; k < n; ++k) {
    int c = 1;
    for (std::uint32_t i : g.neighbors_of(source(k))) c += position[i] > k;
    outer[k + 1] = outer[k] + c;
  }
  Sparse a{Eigen::Index(n), Eigen::Index(n)};
  a.resizeNonZeros(outer[n]);
  std::copy(outer.begin(), outer.end(), a.outerIndexPtr());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<std::pair<int, double>> column;
    for (std::size_t k = r.begin(); k < r.end(); ++k) {
      const std::size_t j = source(k);
      const auto nb = g.neighbors_of(j);
      const auto v = m.values_of(j);
      column.assign(1, {int(k), m.diagonal(j)});
      for (std::size_t e = 0; e < nb.size(); ++e)
        if (position[nb[e]] > k) column.emplace_back(int(position[nb[e]]), v[e]);
      std::sort(column.begin(), column.end());
      for (std::size_t e = 0; e < column.size(); ++e) {
        a.innerIndexPtr()[outer[k] + int(e)] = column[e].first;
        a.valuePtr()[outer[k] + int(e)] = column[e].second;
      }
    }
  });
  return a;
}

/// b (input order) = solve(b permuted into `order`), where solve works in place on a matrix of type M.
template <class M, class Solve>
void solve_permuted(RowMatrix& b, std::span<const std::uint32_t> order, Solve&& solve) {
  M bp(b.rows(), b.cols());
  for (Eigen::Index k = 0; k < b.rows(); ++k) bp.row(k) = b.row(Eigen::Index(order[std::size_t(k)]));
  solve(bp);
  for (Eigen::Index k = 0; k < b.rows(); ++k) b.row(Eigen::Index(order[std::size_t(k)])) = bp.row(k);
}

class Simplicial;  // Eigen's SimplicialLLT with its AMD ordering (below)
class Supernodal;  // CHOLMOD's supernodal LLT (below, where CHOLMOD is built in)

[[noreturn]] void refuse_memory(const char* name, double bytes, const std::string& what, double memory_limit_bytes) {
  std::ostringstream os;
  os.precision(3);
  os << name << " needs about " << bytes / kGiB << " GiB for " << what << ", above the limit of "
     << memory_limit_bytes / kGiB
     << " GiB (FitOptions::memory_limit_bytes, `--memory-limit`). Use a smaller radius: the compact support "
        "is what keeps the system sparse";
  throw ResourceLimit(os.str());
}

/// A general sparse Cholesky in two steps: the constructor analyses (ordering, symbolic factorisation,
/// the memory check), factorise() computes; flops() in between is the analysis's count.
template <class Decomposition>
class EigenFactor final : public KernelSolver {
 public:
  /// order: row k of a is the source order[k] (empty: the input order).
  /// memory_limit_bytes: the factor's size, as the symbolic analysis predicts it, is checked before
  /// the numeric factorisation (ResourceLimit beyond it).
  /// held_bytes: what the fit holds beside (A, its neighbour graph). The factor is not alone: A's
  /// lower triangle here and the solver's permuted copy of it live as long, so they are counted,
  /// before the analysis (which makes the copy) and with the factor after it.
  /// a is taken by swap: Eigen 3.4's SparseMatrix has no move constructor, and its copies (one for
  /// the by-value parameter, one for a_) were two more triangles alive through the analysis (the
  /// fish with a control at every vertex, R = 0.5, peaked 11 % over --memory-limit 0.07).
  EigenFactor(Sparse&& a, const char* name, double memory_limit_bytes, std::vector<std::uint32_t> order = {},
              double held_bytes = 0)
      : order_(std::move(order)), name_(name) {
    a_.swap(a);
    const double copies = held_bytes + 2 * 12.0 * double(a_.nonZeros());
    const auto refuse = [&](double bytes, const std::string& what) {
      refuse_memory(name, bytes, what, memory_limit_bytes);
    };
    // (copies alone, beyond the limit, are refused by analyse_sparse before a_ is made.)
    // Eigen's own AMD ordering (Simplicial, given no order) holds A + A^T and its workspace while it
    // runs: 813 MB for 5.3e6 entries of A's lower triangle, measured (heaptrack) at 20000 sources.
    if constexpr (std::is_same_v<Decomposition, Simplicial>) {
      const double analysis = copies + 160.0 * double(a_.nonZeros());
      if (analysis > memory_limit_bytes)
        refuse(analysis, "its AMD ordering of A's " + std::to_string(a_.nonZeros()) + " entries");
    }
    init(a_);
    // CHOLMOD's numeric factorisation permutes A into two copies of its own (S = A(p,p) and its
    // transpose) beside a_: a control at each of the fish's vertices (R = 3) peaked 11.5 MB above the
    // count without them, over --memory-limit 0.08 by 18 %. Eigen's simplicial factorisation makes
    // one (A's upper triangle in its order): R = 0.5 under 0.07 peaked 11 % over without it.
    const double own = (std::is_same_v<Decomposition, Supernodal> ? 2 : 1) * 12.0 * double(a_.nonZeros());
    const double bytes = predicted_bytes() + copies + own;
    if (bytes > memory_limit_bytes) {
      std::ostringstream what;
      what.precision(3);
      what << "the " << predicted_entries() << " entries its analysis predicts in the factor, with A and its copies";
      refuse(bytes, what.str());
    }
    // Under an address-space limit (ulimit -v), the factor and CHOLMOD's copies are mapped before
    // OpenBLAS's first call maps its buffers, which then retries for ever where the limit refuses
    // them (windAroundBuildings, R = 10, under ulimit -v 600000): the factor is counted here too.
    if constexpr (std::is_same_v<Decomposition, Supernodal>) {
      check_address_space(kBlasAddressSpace + predicted_bytes() + own,
                          "its factor, its copies of A and OpenBLAS's buffers", "use a smaller radius");
    }
  }
  /// Flops of the numeric factorisation, from the analysis (the sum of L's column counts squared).
  double flops() const;
  void factorise() {
    llt_.factorize(a_);
    if (llt_.info() != Eigen::Success)
      throw NotPositiveDefinite(std::string("the interpolation matrix is not numerically positive definite (") + name_ +
                                " factorisation failed)");
    a_ = Sparse();
  }
  SolveStatus solve(RowMatrix& b, const RowMatrix* = nullptr) override {
    std::lock_guard lock(mutex_);  // CHOLMOD's workspace is shared by solves
    if (order_.empty()) {
      const Eigen::MatrixXd x = llt_.solve(Eigen::MatrixXd(b));
      b = x;
      return {};
    }
    solve_permuted<Eigen::MatrixXd>(b, order_, [&](Eigen::MatrixXd& bp) {
      const Eigen::MatrixXd x = llt_.solve(bp);
      bp = x;
    });
    return {};
  }
  std::size_t nonzeros() const override { return count(); }
  double held_bytes() const override { return 12.0 * double(count()) + 12.0 * double(a_.nonZeros()); }

 private:
  void init(const Sparse& a) { llt_.analyzePattern(a); }
  double predicted_entries() const;
  /// The factor's memory as the analysis predicts it: values and row indices of L.
  double predicted_bytes() const { return 12.0 * predicted_entries(); }
  std::size_t count() const;
  std::vector<std::uint32_t> order_;
  Sparse a_;  // until factorised
  const char* name_;
  mutable Decomposition llt_;
  mutable std::mutex mutex_;
};

template <class Decomposition>
class EigenAnalysis final : public SparseAnalysis {
 public:
  explicit EigenAnalysis(std::unique_ptr<EigenFactor<Decomposition>> f) : f_(std::move(f)) {}
  double flops() const override { return f_->flops(); }
  std::unique_ptr<KernelSolver> factorise() override {
    f_->factorise();
    return std::move(f_);
  }

 private:
  std::unique_ptr<EigenFactor<Decomposition>> f_;
};

/// SimplicialLLT, with the size of L that analyzePattern has computed (and reserved, untouched).
class Simplicial : public Eigen::SimplicialLLT<Sparse, Eigen::Lower, Eigen::AMDOrdering<int>> {
 public:
  Eigen::Index reserved() const { return m_matrix.nonZeros(); }
  /// The sum over L's columns of their entry counts squared, from the counts analyzePattern has
  /// reserved: the factorisation's flops as CHOLMOD's analysis counts them.
  double flops() const {
    double f = 0;
    for (Eigen::Index j = 0; j < m_matrix.outerSize(); ++j) {
      const double c = double(m_matrix.outerIndexPtr()[j + 1] - m_matrix.outerIndexPtr()[j]);
      f += c * c;
    }
    return f;
  }
};
template <>
double EigenFactor<Simplicial>::predicted_entries() const {
  return double(llt_.reserved());
}
template <>
double EigenFactor<Simplicial>::flops() const {
  return llt_.flops();
}
template <>
std::size_t EigenFactor<Simplicial>::count() const {
  return std::size_t(llt_.matrixL().nestedExpression().nonZeros());
}
#ifdef CSRBF_HAVE_CHOLMOD
/// CHOLMOD's supernodal LLT with its symbolic factor in view: a supernodal factor stores dense
/// blocks, L->xsize values, more than the lnz entries cholmod_analyze counts (a factor of 7.6 GiB
/// passed a limit of 4 GiB that lnz had been checked against).
class Supernodal : public Eigen::CholmodSupernodalLLT<Sparse, Eigen::Lower> {
 public:
  const cholmod_factor* symbolic() const { return this->m_cholmodFactor; }
};
/// CHOLMOD's analysis out of memory leaves no factor (and fl = lnz = -1) while Eigen reports success.
void check_cholmod_analysis(const cholmod_common& c) {
  if (c.status < CHOLMOD_OK || !(c.fl >= 0) || !(c.lnz >= 0)) {
    std::ostringstream os;
    os << "CHOLMOD's analysis failed (status " << c.status << ": out of memory)";
    throw ResourceLimit(os.str());
  }
}
template <>
void EigenFactor<Supernodal>::init(const Sparse& a) {
  llt_.cholmod().print = 0;  // csrbf reports a failed factorisation itself; no CHOLMOD lines on stderr
  // The matrix comes in csrbf's geometric nested dissection order (nested_dissection_order); CHOLMOD
  // keeps it (and postorders its elimination tree). Its own choices measured slower on the scale
  // sweep (docs/PERFORMANCE.md, N = 1e5 on the sphere): AMD's factor takes 60% more flops, METIS's
  // ordering alone costs about 0.9 s.
  llt_.cholmod().nmethods = 1;
  llt_.cholmod().method[0].ordering = CHOLMOD_NATURAL;
  llt_.cholmod().supernodal = CHOLMOD_SUPERNODAL;
  llt_.analyzePattern(a);
  check_cholmod_analysis(llt_.cholmod());
}
template <>
double EigenFactor<Supernodal>::predicted_entries() const {
  return llt_.cholmod().lnz;  // set by cholmod_analyze
}
template <>
double EigenFactor<Supernodal>::predicted_bytes() const {
  const cholmod_factor* l = llt_.symbolic();
  if (!l || !l->is_super) return 12.0 * predicted_entries();
  // The supernodes' values and their row indices, and the largest update matrix the numeric
  // factorisation works in.
  return 8.0 * double(l->xsize) + double(sizeof(int)) * double(l->ssize) + 8.0 * double(l->maxcsize);
}
template <>
double EigenFactor<Supernodal>::flops() const {
  return llt_.cholmod().fl;  // set by cholmod_analyze: the factorisation's floating-point operations
}
template <>
std::size_t EigenFactor<Supernodal>::count() const {
  // CHOLMOD's own count of the factor's entries (the supernodes' dense blocks).
  return std::size_t(llt_.cholmod().lnz);
}
#endif

/// A in compressed rows, both triangles, row k the source order[k]: the product runs over rows in
/// parallel, m right-hand sides at once.
class BatchedCg final : public KernelSolver {
 public:
  BatchedCg(const KernelMatrix& a, std::vector<std::uint32_t> order, double tolerance, std::size_t max_iterations,
            CgProbe probe, CgPreconditioner preconditioner)
      : order_(std::move(order)), tolerance_(tolerance), max_iterations_(max_iterations), probe_(std::move(probe)) {
    // A's rows copied into `order`, their columns renumbered: the entries are A's, not recomputed.
    const std::size_t n = a.size();
    std::vector<std::uint32_t> position(n);
    for (std::size_t k = 0; k < n; ++k) position[order_[k]] = std::uint32_t(k);
    bool identity = true;
    for (std::size_t k = 0; k < n && identity; ++k) identity = order_[k] == k;
    if (!preconditioner.points.empty()) {
      // The points in CG's order: the caller's where that is their order, else a copy.
      if (identity) {
        points_ = preconditioner.points;
      } else {
        own_points_.resize(n);
        for (std::size_t k = 0; k < n; ++k) own_points_[k] = preconditioner.points[order_[k]];
        points_ = own_points_;
      }
      radius_ = a.radius();
    }
    diagonal_ = a.diagonal();
    if (!a.constant_diagonal()) {
      row_diagonal_.resize(n);
      for (std::size_t k = 0; k < n; ++k) row_diagonal_[k] = a.diagonal(order_[k]);
    }
    if (identity) {
      // A's rows are already in CG's order (the interpolator's points, sorted into the Schwarz
      // patches' order before their graph was built): read in place, not copied (1e5 points in 2-D
      // at 40 neighbours: 48 MB fewer, and 60 ms fewer of a fit on a virtual machine where fresh
      // pages are slow). A outlives this solver (SpaceMap::Structure holds both, the solver freed first).
      row_ = a.pattern().offsets;
      col_ = a.pattern().neighbors;
      val_ = a.values();
      return;
    }
    own_row_.assign(n + 1, 0);
    for (std::size_t k = 0; k < n; ++k) own_row_[k + 1] = own_row_[k] + a.pattern().degree(order_[k]);
    own_col_.resize(own_row_[n]);
    own_val_.resize(own_row_[n]);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t k = r.begin(); k < r.end(); ++k) {
        const auto nb = a.pattern().neighbors_of(order_[k]);
        const auto v = a.values_of(order_[k]);
        for (std::size_t e = 0; e < nb.size(); ++e) {
          own_col_[own_row_[k] + e] = position[nb[e]];
          own_val_[own_row_[k] + e] = v[e];
        }
      }
    });
    row_ = own_row_;
    col_ = own_col_;
    val_ = own_val_;
  }

  SolveStatus solve(RowMatrix& b, const RowMatrix* initial = nullptr) override {
    std::lock_guard lock(mutex_);  // iterations_ and residual_ describe one solve
    if (released_)
      return {SystemInfo::NoConvergence, std::numeric_limits<double>::infinity(), 0,
              "conjugate gradients gave way to another solver"};
    // 3 right-hand sides (the displacements), 4 (the polynomial block) or 1 (the condition estimate).
    if (b.cols() > 8) throw InvalidInput("conjugate gradients: at most 8 right-hand sides at once");
    if (initial && (initial->rows() != b.rows() || initial->cols() != b.cols()))
      throw InvalidInput("conjugate gradients: the initial guess has another shape than the right-hand sides");
    // Isolated: a thread waiting in the parallel loops below must not take another task that would
    // lock mutex_ again (with_destinations called from the caller's own TBB tasks).
    return tbb::this_task_arena::isolate([&] { return solve_columns(b, initial); });
  }
  bool iterative() const override { return true; }
  std::size_t nonzeros() const override { return order_.size() + val_.size(); }
  /// Its copy of A's rows, its preconditioner and the vectors of a solve of up to 8 right-hand sides.
  double held_bytes() const override {
    return released_ ? 0.0 : cg_bytes(val_.size(), order_.size(), !points_.empty(), !own_row_.empty());
  }
  void stop_probing() const override { probing_ = false; }
  void release() override {
    std::lock_guard lock(mutex_);
    released_ = true;
    row_ = {};
    col_ = {};
    val_ = {};
    decltype(own_row_)().swap(own_row_);
    decltype(own_col_)().swap(own_col_);
    decltype(own_val_)().swap(own_val_);
    points_ = {};
    decltype(own_points_)().swap(own_points_);
    ic_.reset();
    schwarz_.reset();
  }
  std::size_t iterations() const override { return iterations_; }
  double residual() const override { return residual_; }

 private:
  using Sums = std::array<double, 16>;
  /// q = A p (n x m, solver order), and p . q per column, in one parallel pass.
  template <class Reduce>
  Sums times_a(const FillVector<double>& p, FillVector<double>& q, std::size_t m, const Reduce& reduce) const {
    // The column count fixed at compile time for the usual 1, 3 and 4: the inner loops unroll.
    switch (m) {
      case 1:
        return times_a_fixed<1>(p, q, m, reduce);
      case 3:
        return times_a_fixed<3>(p, q, m, reduce);
      case 4:
        return times_a_fixed<4>(p, q, m, reduce);
      default:
        return times_a_fixed<0>(p, q, m, reduce);
    }
  }
  template <std::size_t M, class Reduce>
  Sums times_a_fixed(const FillVector<double>& p, FillVector<double>& q, std::size_t m_run,
                     const Reduce& reduce) const {
    const std::size_t m = M ? M : m_run;
    return reduce([&](const tbb::blocked_range<std::size_t>& range, Sums& s) {
      for (std::size_t k = range.begin(); k < range.end(); ++k) {
        double acc[8];
        const double d = row_diagonal_.empty() ? diagonal_ : row_diagonal_[k];
        for (std::size_t c = 0; c < m; ++c) acc[c] = d * p[k * m + c];
        for (std::size_t e = row_[k]; e < row_[k + 1]; ++e) {
          const double a = val_[e];
          const double* pj = &p[std::size_t(col_[e]) * m];
          for (std::size_t c = 0; c < m; ++c) acc[c] += a * pj[c];
        }
        for (std::size_t c = 0; c < m; ++c) {
          q[k * m + c] = acc[c];
          s[c] += p[k * m + c] * acc[c];
        }
      }
    });
  }

  /// Each column of r (n x m, row-major) divided by a power of two near its largest magnitude, which
  /// is returned (1 for a zero or non-finite column).
  static std::array<double, 8> scale_columns(FillVector<double>& r, std::size_t n, std::size_t m) {
    // Exact: the same steps and bits. Squares of values near 1e-160 underflowed to 0 and read as a
    // zero right-hand side, whose solution is 0 (an interpolant of such values was 0 everywhere).
    std::array<double, 8> unit;
    unit.fill(1.0);
    for (std::size_t c = 0; c < m; ++c) {
      double largest = 0;
      for (std::size_t k = 0; k < n; ++k) largest = std::max(largest, std::abs(r[k * m + c]));
      if (largest > 0 && std::isfinite(largest)) unit[c] = std::ldexp(1.0, std::ilogb(largest));
    }
    for (std::size_t k = 0; k < n; ++k)
      for (std::size_t c = 0; c < m; ++c) r[k * m + c] /= unit[c];
    return unit;
  }

  /// Stagnation at step `it`: the smallest residual so far (the worst column's) has not fallen 10x in
  /// the last kCgStagnationWindow steps (SystemInfo::NoConvergence; else Success). CG that still converges falls much
  /// faster than that. rr_best and lowest (lowest[k]: the worst column's smallest squared relative residual up to step
  /// k) are brought up to this step.
  SolveStatus check_stagnation(std::size_t it, std::size_t m, const Sums& rr, const Sums& rr0,
                               const std::array<bool, 8>& done, Sums& rr_best, std::vector<double>& lowest) const {
    double worst_low = 0;
    for (std::size_t c = 0; c < m; ++c) {
      rr_best[c] = std::min(rr_best[c], rr[c]);
      if (!done[c] && rr0[c] > 0) worst_low = std::max(worst_low, rr_best[c] / rr0[c]);
    }
    lowest.push_back(worst_low);
    if (it >= kCgStagnationWindow && !(worst_low < 1e-2 * lowest[it - kCgStagnationWindow])) {
      iterations_ = it;
      residual_ = std::sqrt(worst_low);
      std::ostringstream os;
      os << "conjugate gradients stagnated: the relative residual (" << std::sqrt(worst_low)
         << ") has not fallen 10x in the last " << kCgStagnationWindow << " of " << it
         << " steps (the matrix is too ill-conditioned for them: a smaller radius, or a direct solver, "
            "--solver envelope or cholmod, can solve it)";
      return {SystemInfo::NoConvergence, std::numeric_limits<double>::infinity(), it, os.str()};
    }
    return {};
  }

  /// Auto's probe at step `it` (a multiple of probe_.steps): SystemInfo::GaveWay where the steps this
  /// solve needs in all, were the residual to keep falling at its recent rate, are not worth it.
  /// best[k]: the smallest residuals up to step k; rr_best: the smallest so far.
  SolveStatus check_probe(std::size_t it, std::size_t m, const std::vector<Sums>& best, const Sums& rr_best,
                          const Sums& rr0, const std::array<bool, 8>& done) const {
    const std::size_t mark = it / 3;
    double predicted = double(it);
    for (std::size_t c = 0; c < m; ++c) {
      if (done[c]) continue;
      const double fell = std::sqrt(rr_best[c] / best[mark][c]), need = tolerance_ * std::sqrt(rr0[c] / rr_best[c]);
      predicted = std::max(predicted, fell < 1 ? double(it) + double(it - mark) * std::log(need) / std::log(fell)
                                               : std::numeric_limits<double>::infinity());
    }
    // Preconditioned steps cost about twice a plain one (A's pass, then L's two): counted in plain ones.
    if (preconditioned()) predicted = double(it) + kIcStepCost * (predicted - double(it));
    if (!probe_.worth_it(predicted, double(it))) {
      iterations_ = it;
      std::ostringstream os;
      os << "conjugate gradients would need about " << predicted << " steps (after " << it << ")";
      return {SystemInfo::GaveWay, predicted, it, os.str()};
    }
    return {};
  }

  /// After `it` steps: the iterations and worst relative residual recorded, NoConvergence where the
  /// solve fell short, else x (solver order, scaled by unit) written into b (input order).
  SolveStatus finish_columns(RowMatrix& b, const FillVector<double>& x, const Sums& rr, const Sums& rr0,
                             const std::array<double, 8>& unit, std::size_t it, bool all_done) const {
    const std::size_t n = order_.size(), m = std::size_t(b.cols());
    double worst = 0;
    for (std::size_t c = 0; c < m; ++c)
      if (rr0[c] > 0) worst = std::max(worst, std::sqrt(rr[c] / rr0[c]));
    iterations_ = it;
    residual_ = worst;
    // At the step limit short of the tolerance, a residual that the fit's own check accepts by far
    // is kept (20000 controls in a cube reached 3.9e-11 in 3000 steps, and were refused).
    if (!std::isfinite(worst) || (!all_done && !(worst <= kCgGoodEnough))) {
      std::ostringstream os;
      os << "conjugate gradients stopped at a relative residual of " << worst << " after " << it
         << " steps (their limit; a smaller radius, or a direct solver, --solver envelope or cholmod, can solve "
            "it)";
      return {SystemInfo::NoConvergence, std::numeric_limits<double>::infinity(), it, os.str()};
    }
    for (std::size_t k = 0; k < n; ++k)
      for (std::size_t c = 0; c < m; ++c) b(Eigen::Index(order_[k]), Eigen::Index(c)) = x[k * m + c] * unit[c];
    return {};
  }

  /// b (n x m, m <= 8, input order) becomes A^-1 b, starting from `initial` (or 0); unchanged where
  /// the status is not Success.
  SolveStatus solve_columns(RowMatrix& b, const RowMatrix* initial) const {
    const std::size_t n = order_.size(), m = std::size_t(b.cols());
    // Work in the solver's row order: x, r, p, q are n x m, row-major (one row's m values together).
    // Every entry is written before it is read: r and x below, p = r, q in the first product.
    FillVector<double> x(n * m), r(n * m), p(n * m), q(n * m), z;
    for (std::size_t k = 0; k < n; ++k)
      for (std::size_t c = 0; c < m; ++c) r[k * m + c] = b(Eigen::Index(order_[k]), Eigen::Index(c));
    const auto reduce = [&](auto&& body) {
      return tbb::parallel_reduce(
          tbb::blocked_range<std::size_t>(0, n, 8192), Sums{},
          [&](const tbb::blocked_range<std::size_t>& range, Sums s) {
            body(range, s);
            return s;
          },
          [m](Sums a, const Sums& b2) {
            for (std::size_t c = 0; c < m; ++c) {
              a[c] += b2[c];
              a[8 + c] += b2[8 + c];
            }
            return a;
          });
    };
    const auto squares = [&](const FillVector<double>& v) {
      return reduce([&](const tbb::blocked_range<std::size_t>& range, Sums& s) {
        for (std::size_t k = range.begin(); k < range.end(); ++k)
          for (std::size_t c = 0; c < m; ++c) s[c] += v[k * m + c] * v[k * m + c];
      });
    };
    const std::array<double, 8> unit = scale_columns(r, n, m);
    const Sums rr0 = squares(r);  // ||b||^2 per column: the residual is relative to it
    if (initial) {
      // Warm start: x = the guess, r = b - A x. A guess near the solution leaves a small r, and
      // the same tolerance relative to ||b|| is reached in fewer steps.
      for (std::size_t k = 0; k < n; ++k)
        for (std::size_t c = 0; c < m; ++c)  // a zero right-hand side has the solution 0, whatever the guess
          x[k * m + c] = rr0[c] > 0 ? (*initial)(Eigen::Index(order_[k]), Eigen::Index(c)) / unit[c] : 0.0;
      times_a(x, q, m, reduce);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n * m, 1 << 15),
                        [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t e = range.begin(); e < range.end(); ++e) r[e] -= q[e];
                        });
    } else {
      std::fill(x.begin(), x.end(), 0.0);
    }
    // z = M^-1 r (or r itself without a preconditioner), and r . z per column.
    const auto precondition = [&]() -> Sums {
      if (!preconditioned()) return squares(r);
      if (schwarz_)
        schwarz_->apply(r.data(), z.data(), m);
      else
        ic_->apply(r.data(), z.data(), m);
      return reduce([&](const tbb::blocked_range<std::size_t>& range, Sums& s) {
        for (std::size_t k = range.begin(); k < range.end(); ++k)
          for (std::size_t c = 0; c < m; ++c) s[c] += r[k * m + c] * z[k * m + c];
      });
    };
    // Scattered points (Schwarz patches) begin preconditioned: plain CG on them is slow from its first
    // step (1e5 random 2-D points: 12 plain steps were 10% of the fit).
    if (!points_.empty() && !preconditioned()) make_preconditioner();
    if (preconditioned()) z.resize(n * m);
    Sums rz = precondition();
    p = preconditioned() ? z : r;
    // CG begins plain (a step is then half the work) and turns to the preconditioner when, after
    // kIcProbeSteps steps, the rate its residual falls at predicts more than kIcSwitchSteps steps in
    // all: the sphere's 1e6 controls converge in 40 plain steps (28 preconditioned, each twice the
    // work); the cube's take 1805 plain and 166 preconditioned. The recurrence restarts from x.
    const auto turn_to_preconditioner = [&] {
      make_preconditioner();
      z.resize(n * m);
      rz = precondition();
      p = z;
    };
    Sums rr = initial ? squares(r) : rr0;
    const Sums rr_start = rr;
    std::array<double, 8> alpha{}, beta{};
    std::array<bool, 8> done{};
    for (std::size_t c = 0; c < m; ++c) done[c] = rr[c] <= tolerance_ * tolerance_ * rr0[c];
    std::size_t it = 0;
    const auto all_done = [&] {
      for (std::size_t c = 0; c < m; ++c)
        if (!done[c]) return false;
      return true;
    };
    // Auto's probe: every probe_.steps steps, the rate at which the residual fell over the last two
    // thirds of the steps taken predicts the steps still needed. CG slows down as it goes (its first steps
    // remove the easy components), so the recent rate is the better guide. CG's residual is not
    // monotonic: the probe judges by the smallest seen so far.
    const bool probe = probe_.steps > 0 && probing_.load();
    std::vector<Sums> best;  // best[k]: the smallest residuals up to step k
    if (probe) best.reserve(max_iterations_ + 1);
    Sums rr_best = rr_start;     // the smallest residuals so far, per column
    std::vector<double> lowest;  // lowest[k]: the worst column's smallest squared relative residual up to step k
    lowest.reserve(std::min<std::size_t>(max_iterations_, 1u << 20) + 1);
    for (; !all_done() && it < max_iterations_; ++it) {
      if (SolveStatus s = check_stagnation(it, m, rr, rr0, done, rr_best, lowest); !s.ok()) return s;
      if (!preconditioned() && it == kIcProbeSteps && !all_done()) {
        const std::size_t mark = it / 3;
        const double fell = std::sqrt(lowest[it] / lowest[mark]), need = tolerance_ / std::sqrt(lowest[it]);
        const double predicted = fell < 1 ? double(it) + double(it - mark) * std::log(need) / std::log(fell)
                                          : std::numeric_limits<double>::infinity();
        if (predicted > double(kIcSwitchSteps)) turn_to_preconditioner();
      }
      if (probe) best.push_back(rr_best);
      if (probe && it > 0 && it % probe_.steps == 0)
        if (SolveStatus s = check_probe(it, m, best, rr_best, rr0, done); !s.ok()) return s;
      const Sums pq = times_a(p, q, m, reduce);
      for (std::size_t c = 0; c < m; ++c) alpha[c] = done[c] || !(pq[c] > 0) ? 0.0 : rz[c] / pq[c];
      // x += alpha p, r -= alpha q, and r . r per column.
      const Sums rr_new = reduce([&](const tbb::blocked_range<std::size_t>& range, Sums& s) {
        for (std::size_t k = range.begin(); k < range.end(); ++k)
          for (std::size_t c = 0; c < m; ++c) {
            x[k * m + c] += alpha[c] * p[k * m + c];
            r[k * m + c] -= alpha[c] * q[k * m + c];
            s[c] += r[k * m + c] * r[k * m + c];
          }
      });
      const Sums rz_new = preconditioned() ? precondition() : rr_new;
      for (std::size_t c = 0; c < m; ++c) {
        if (done[c]) continue;
        beta[c] = rz[c] > 0 ? rz_new[c] / rz[c] : 0.0;
        rz[c] = rz_new[c];
        rr[c] = rr_new[c];

        if (rr[c] <= tolerance_ * tolerance_ * rr0[c] || !std::isfinite(rr[c])) done[c] = true;
      }
      const FillVector<double>& w = preconditioned() ? z : r;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192), [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t k = range.begin(); k < range.end(); ++k)
          for (std::size_t c = 0; c < m; ++c) p[k * m + c] = w[k * m + c] + beta[c] * p[k * m + c];
      });
    }
    return finish_columns(b, x, rr, rr0, unit, it, all_done());
  }

  std::vector<std::uint32_t> order_;
  // A's rows in CG's order: A's own arrays where `order` is the identity, else the copy own_*.
  std::span<const std::size_t> row_;
  std::span<const std::uint32_t> col_;
  std::span<const double> val_;
  std::vector<std::size_t> own_row_;
  FillVector<std::uint32_t> own_col_;
  FillVector<double> own_val_;
  bool preconditioned() const noexcept { return ic_ || schwarz_; }
  /// Schwarz where the points are given and its patches fit their share, else the incomplete Cholesky.
  void make_preconditioner() const {
    const std::size_t n = order_.size();
    if (!points_.empty()) {
      try {
        schwarz_.emplace(points_, radius_, row_, col_, val_, diagonal_, row_diagonal_, schwarz_share(val_.size(), n));
        return;
      } catch (const ResourceLimit&) {
        // Patches too large for their share (many neighbours): the incomplete Cholesky instead.
        schwarz_.reset();
      }
    }
    ic_.emplace(row_, col_, val_, diagonal_, row_diagonal_, n);
  }

  mutable std::optional<IncompleteCholesky> ic_;          // CG's preconditioner, once a solve needed it
  mutable std::optional<SchwarzPreconditioner> schwarz_;  // or this one, where points_ are given
  std::span<const Vec3> points_;  // the sources in `order` (Schwarz's patches): the caller's, or own_points_
  std::vector<Vec3> own_points_;
  double radius_ = 1.0;
  double diagonal_ = 1.0, tolerance_;
  std::vector<double> row_diagonal_;  // in `order`, where A's diagonal is not constant
  std::size_t max_iterations_;
  CgProbe probe_;
  mutable std::atomic<bool> probing_{true};
  std::atomic<bool> released_{false};
  mutable std::size_t iterations_ = 0;
  mutable double residual_ = 0;
  mutable std::mutex mutex_;
};

}  // namespace

std::unique_ptr<KernelSolver> conjugate_gradients(const KernelMatrix& a, std::vector<std::uint32_t> order,
                                                  double tolerance, std::size_t max_iterations, CgProbe probe,
                                                  CgPreconditioner preconditioner) {
  return std::make_unique<BatchedCg>(a, std::move(order), tolerance, max_iterations, std::move(probe),
                                     std::move(preconditioner));
}

std::pair<double, double> lanczos_extremes(const KernelMatrix& a, unsigned seed) {
  const std::size_t n = a.size();
  const auto en = Eigen::Index(n);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RowMatrix v(en, 1), prev = RowMatrix::Zero(en, 1);
  for (Eigen::Index i = 0; i < en; ++i) v(i, 0) = u(rng);
  v /= v.norm();
  std::vector<double> alpha, beta;
  double lo = a.diagonal(), hi = a.diagonal(), last_lo = 0, last_hi = 0;
  const std::size_t steps = std::min<std::size_t>(n, 300);
  // The Lanczos vectors are kept, and each new one made orthogonal to them all, where they take
  // at most 80 MB: without it, rounding lets the smallest Ritz value stall (5x too large on the fish).
  const bool keep = double(n) * double(steps) <= 1e7;
  Eigen::MatrixXd kept(keep ? en : 0, keep ? Eigen::Index(steps) : 0);
  for (std::size_t k = 0; k < steps; ++k) {
    if (keep) kept.col(Eigen::Index(k)) = v.col(0);
    RowMatrix w = a * v;
    const double al = w.col(0).dot(v.col(0));
    w -= al * v + (beta.empty() ? 0.0 : beta.back()) * prev;
    if (keep)
      for (int pass = 0; pass < 2; ++pass) {
        const auto basis = kept.leftCols(Eigen::Index(k + 1));
        const Eigen::VectorXd c = basis.transpose() * w.col(0);
        w.col(0) -= basis * c;
      }
    alpha.push_back(al);
    const double b = w.norm();
    if ((k + 1) % 10 == 0 || k + 1 == steps || !(b > 1e-14 * std::abs(al))) {
      Eigen::VectorXd d = Eigen::Map<Eigen::VectorXd>(alpha.data(), Eigen::Index(alpha.size()));
      Eigen::VectorXd e = Eigen::Map<Eigen::VectorXd>(beta.data(), Eigen::Index(beta.size()));
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> t;
      t.computeFromTridiagonal(d, e, Eigen::EigenvaluesOnly);
      lo = t.eigenvalues().minCoeff();
      hi = t.eigenvalues().maxCoeff();
      // The smallest Ritz value settles last, and can pause before it moves again: stop only when
      // it has held to 1e-6 over 10 steps, after 50.
      if (k >= 49 && std::abs(lo - last_lo) <= 1e-6 * std::abs(lo) && std::abs(hi - last_hi) <= 1e-6 * hi) break;
      last_lo = lo, last_hi = hi;
    }
    if (!(b > 1e-14 * std::abs(al))) break;  // an invariant subspace: the Ritz values are eigenvalues
    beta.push_back(b);
    prev = v;
    v = w / b;
  }
  return {lo, hi};
}

namespace {
class EnvelopeFactor final : public KernelSolver {
 public:
  EnvelopeFactor(const KernelMatrix& a, std::vector<std::uint32_t> order, double memory_limit_bytes,
                 std::string_view ordering, double held_bytes)
      : order_(std::move(order)) {
    std::vector<std::size_t> first = envelope_first_columns(a.pattern(), order_);
    check_envelope_size(first, memory_limit_bytes, ordering, held_bytes);
    factor_ = envelope_matrix(a, order_, std::move(first));
    envelope_cholesky(factor_, order_);
  }
  SolveStatus solve(RowMatrix& b, const RowMatrix* = nullptr) override {
    solve_permuted<RowMatrix>(b, order_, [&](RowMatrix& bp) { factor_.solve_in_place(bp); });
    return {};
  }
  std::size_t nonzeros() const override { return factor_.envelope_entries() + order_.size(); }
  double held_bytes() const override { return double(factor_.storage_bytes()) + 4.0 * double(order_.size()); }

 private:
  std::vector<std::uint32_t> order_;
  EnvelopeMatrix factor_;
};
}  // namespace

void check_envelope_size(std::span<const std::size_t> first_columns, double memory_limit_bytes,
                         std::string_view ordering, double held_bytes) {
  double entries = double(first_columns.size());
  for (std::size_t k = 0; k < first_columns.size(); ++k) entries += double(k - first_columns[k]);
  const double bytes = envelope_factor_bytes(entries - double(first_columns.size()), first_columns.size());
  if (bytes + held_bytes > memory_limit_bytes) {
    std::ostringstream os;
    os.precision(3);
    os << "the envelope of the " << ordering << " ordering holds " << std::llround(entries) << " entries, about "
       << bytes / kGiB << " GiB";
    if (held_bytes > 0) os << " (with A and what the fit holds beside it, " << (bytes + held_bytes) / kGiB << " GiB)";
    os << ", above the limit of " << memory_limit_bytes / kGiB
       << " GiB (FitOptions::memory_limit_bytes, `--memory-limit`). Use another ordering or solver, or a smaller "
          "radius";
    throw ResourceLimit(os.str());
  }
}

void envelope_cholesky(EnvelopeMatrix& env, std::span<const std::uint32_t> order) {
  try {
    env.cholesky_in_place();
  } catch (const NotPositiveDefinite& e) {
    throw NotPositiveDefinite(order[e.row()], e.pivot());
  }
}

std::unique_ptr<KernelSolver> envelope_factor(const KernelMatrix& a, std::vector<std::uint32_t> order,
                                              double memory_limit_bytes, std::string_view ordering, double held_bytes) {
  return std::make_unique<EnvelopeFactor>(a, std::move(order), memory_limit_bytes, ordering,
                                          kernel_matrix_bytes(a) + held_bytes);
}

std::unique_ptr<SparseAnalysis> analyse_sparse(const KernelMatrix& a, std::span<const Vec3> sources, Solver which,
                                               double memory_limit_bytes, double held_bytes) {
  const double held = kernel_matrix_bytes(a) + held_bytes;
  // A's lower triangle and the solver's copy of it, refused before the first is made.
  const std::size_t lower = a.values().size() / 2 + a.size();
  const char* name = which == Solver::Cholmod ? "CHOLMOD" : "Eigen SimplicialLLT";
  // CHOLMOD's analysis and factorisation make two permuted copies of their own (EigenFactor).
  const double copies = (which == Solver::Cholmod ? 4 : 2) * 12.0 * double(lower);
  if (held + copies > memory_limit_bytes)
    refuse_memory(name, held + copies, "A and its copies (" + std::to_string(lower) + " entries each)",
                  memory_limit_bytes);
  if (which == Solver::Cholmod) {
#ifdef CSRBF_HAVE_CHOLMOD
    // Opened first (cholmod_loader.cpp): the library and its BLAS take address space of their own,
    // which the room below must not count as free.
    if (!cholmod_available())
      throw InvalidInput("solver 'cholmod': " + cholmod_load_error() + "; use 'envelope' or 'eigen'");
#endif
    // CHOLMOD's supernodal factorisation runs OpenBLAS, whose first call maps its buffers; where an
    // address-space limit (ulimit -v) refuses them, OpenBLAS retries for ever (measured: fish, R = 5,
    // under ulimit -v 300000). Refused here instead, so that Auto turns to another solver.
    check_address_space(kBlasAddressSpace + 2 * 12.0 * double(lower), "OpenBLAS's buffers and A's copies",
                        "use --solver envelope or eigen");
  }
  if (which == Solver::Eigen)
    return std::make_unique<EigenAnalysis<Simplicial>>(std::make_unique<EigenFactor<Simplicial>>(
        lower_matrix(a), "Eigen SimplicialLLT", memory_limit_bytes, std::vector<std::uint32_t>{}, held));
#ifdef CSRBF_HAVE_CHOLMOD
  if (which == Solver::Cholmod) {
    std::vector<std::uint32_t> order = nested_dissection_order(a.pattern(), sources, a.radius());
    Sparse lower = lower_matrix(a, order);
    return std::make_unique<EigenAnalysis<Supernodal>>(std::make_unique<EigenFactor<Supernodal>>(
        std::move(lower), "CHOLMOD", memory_limit_bytes, std::move(order), held));
  }
#else
  (void)sources;
#endif
  throw InvalidInput(std::string("solver '") + std::string(solver_name(which)) +
                     "' is not available in this build of csrbf");
}

std::unique_ptr<KernelSolver> factor_sparse(const KernelMatrix& a, std::span<const Vec3> sources, Solver which,
                                            double memory_limit_bytes, double held_bytes) {
  return analyse_sparse(a, sources, which, memory_limit_bytes, held_bytes)->factorise();
}

}  // namespace csrbf::detail
