#include "schwarz.hpp"

#include "csrbf/units.hpp"

#include "csrbf/errors.hpp"

#include <Eigen/Cholesky>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <type_traits>

namespace csrbf::detail {

namespace {

/// A node of the bisection tree: its box, its points perm[begin, end), and its children (-1: a leaf).
struct Node {
  Vec3 lo, hi;
  std::size_t begin = 0, end = 0;
  std::int64_t child[2] = {-1, -1};
};

struct Tree {
  std::vector<Node> nodes;
  std::vector<std::uint32_t> perm;
  std::vector<std::size_t> leaves;
};

/// Bisects the points' box until each leaf's box has sides of at most kSchwarzLeafSide R and holds
/// at most kSchwarzLeafPoints points. Points closer together than the doubles can split (duplicates with a
/// smoothing) are split by count instead, so that no leaf holds more than that.
Tree bisect(std::span<const Vec3> points, double radius) {
  Tree t;
  const std::size_t n = points.size();
  t.perm.resize(n);
  std::iota(t.perm.begin(), t.perm.end(), 0u);
  Node root;
  root.lo = root.hi = points[0];
  for (const Vec3& p : points) {
    root.lo = root.lo.cwiseMin(p);
    root.hi = root.hi.cwiseMax(p);
  }
  root.end = n;
  t.nodes.push_back(root);
  std::vector<std::size_t> todo{0};
  while (!todo.empty()) {
    const std::size_t i = todo.back();
    todo.pop_back();
    Node node = t.nodes[i];
    const std::size_t count = node.end - node.begin;
    int axis = 0;
    const Vec3 side = node.hi - node.lo;
    side.maxCoeff(&axis);
    const double longest = side[axis];
    if (count <= kSchwarzLeafPoints && longest <= kSchwarzLeafSide * radius) {
      t.leaves.push_back(i);
      continue;
    }
    Node a = node, b = node;
    const double mid = 0.5 * (node.lo[axis] + node.hi[axis]);
    auto first = t.perm.begin() + std::ptrdiff_t(node.begin), last = t.perm.begin() + std::ptrdiff_t(node.end);
    auto cut = first;
    if (!(longest > radius * 1e-9) || !(mid > node.lo[axis] && mid < node.hi[axis])) {
      // Points closer than the doubles can cut: halved by count (the box stays the same).
      if (count <= kSchwarzLeafPoints) {
        t.leaves.push_back(i);
        continue;
      }
      cut = first + std::ptrdiff_t(count / 2);
    } else {
      cut = std::partition(first, last, [&](std::uint32_t k) { return points[k][axis] < mid; });
      if (cut == first || cut == last) {
        // The points lie in one half: the other half is empty space, and the node shrinks to this one.
        if (cut == first)
          node.lo[axis] = mid;
        else
          node.hi[axis] = mid;
        t.nodes[i] = node;
        todo.push_back(i);
        continue;
      }
      a.hi[axis] = mid;
      b.lo[axis] = mid;
    }
    a.end = b.begin = node.begin + std::size_t(cut - first);
    t.nodes[i].child[0] = std::int64_t(t.nodes.size());
    t.nodes.push_back(a);
    t.nodes[i].child[1] = std::int64_t(t.nodes.size());
    t.nodes.push_back(b);
    todo.push_back(std::size_t(t.nodes[i].child[1]));
    todo.push_back(std::size_t(t.nodes[i].child[0]));
  }
  // Leaves in the tree's left-to-right order: neighbouring patches get neighbouring numbers.
  std::sort(t.leaves.begin(), t.leaves.end(),
            [&](std::size_t x, std::size_t y) { return t.nodes[x].begin < t.nodes[y].begin; });
  return t;
}

/// The points of `tree` (not in the leaf itself) inside the box [lo, hi], appended to `out`.
void points_in_box(const Tree& tree, std::span<const Vec3> points, const Vec3& lo, const Vec3& hi, std::size_t leaf,
                   std::vector<std::uint32_t>& out, std::vector<std::size_t>& stack) {
  stack.assign(1, 0);
  while (!stack.empty()) {
    const Node& node = tree.nodes[stack.back()];
    const std::size_t i = stack.back();
    stack.pop_back();
    if ((node.hi.array() < lo.array()).any() || (node.lo.array() > hi.array()).any() || i == leaf) continue;
    if (node.child[0] < 0) {
      for (std::size_t e = node.begin; e < node.end; ++e) {
        const std::uint32_t k = tree.perm[e];
        if ((points[k].array() >= lo.array()).all() && (points[k].array() <= hi.array()).all()) out.push_back(k);
      }
    } else {
      stack.push_back(std::size_t(node.child[0]));
      stack.push_back(std::size_t(node.child[1]));
    }
  }
}

/// The distance (largest over the axes) from p to the box [lo, hi].
double box_distance(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).maxCoeff();
}

}  // namespace

std::vector<std::uint32_t> schwarz_order(std::span<const Vec3> points, double radius) {
  if (points.empty()) return {};
  return bisect(points, radius).perm;
}

SchwarzPreconditioner::SchwarzPreconditioner(std::span<const Vec3> points, double radius,
                                             std::span<const std::size_t> row, std::span<const std::uint32_t> col,
                                             std::span<const double> val, double diagonal,
                                             std::span<const double> row_diagonal, double byte_limit) {
  const std::size_t n = points.size();
  patch_start_.assign(1, 0);
  factor_start_.assign(1, 0);
  slot_start_.assign(n + 1, 0);
  if (n == 0) return;
  const Tree tree = bisect(points, radius);
  // Each leaf's patch: its own points, then the others within its box grown by a quarter of R (or
  // of its longest side, where the leaf is smaller), the nearest first where there are too many.
  const std::size_t leaves = tree.leaves.size();
  std::vector<std::vector<std::uint32_t>> members(leaves);
  tbb::enumerable_thread_specific<std::pair<std::vector<std::size_t>, std::vector<std::pair<double, std::uint32_t>>>>
      scratch;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves, 64), [&](const tbb::blocked_range<std::size_t>& r) {
    auto& [stack, near] = scratch.local();
    for (std::size_t l = r.begin(); l < r.end(); ++l) {
      const Node& leaf = tree.nodes[tree.leaves[l]];
      std::vector<std::uint32_t>& m = members[l];
      m.assign(tree.perm.begin() + std::ptrdiff_t(leaf.begin), tree.perm.begin() + std::ptrdiff_t(leaf.end));
      const std::size_t own = m.size();
      const double grow = 0.25 * std::min(radius, (leaf.hi - leaf.lo).maxCoeff());
      const Vec3 lo = leaf.lo.array() - grow, hi = leaf.hi.array() + grow;
      points_in_box(tree, points, lo, hi, tree.leaves[l], m, stack);
      if (m.size() > std::max(kSchwarzPatchPoints, own)) {
        near.clear();
        for (std::size_t e = own; e < m.size(); ++e)
          near.emplace_back(box_distance(points[m[e]], leaf.lo, leaf.hi), m[e]);
        const std::size_t keep = kSchwarzPatchPoints > own ? kSchwarzPatchPoints - own : 0;
        std::nth_element(near.begin(), near.begin() + std::ptrdiff_t(keep), near.end());
        m.resize(own);
        for (std::size_t e = 0; e < keep; ++e) m.push_back(near[e].second);
        m.shrink_to_fit();  // the box's points are not held past the trim (200 000 points at one position: 3.2 GB)
      }
      std::sort(m.begin(), m.end());
    }
  });
  // The bytes are known before the factors are allocated.
  std::size_t total = 0;
  double factor_entries = 0;
  for (const auto& m : members) {
    total += m.size();
    factor_entries += 0.5 * double(m.size()) * double(m.size() + 1);
  }
  const double need = 4.0 * factor_entries + 16.0 * double(total) + 8.0 * 8.0 * double(total) +
                      8.0 * double(leaves + n) + 16.0 * double(leaves);
  if (!(need <= byte_limit)) {
    std::ostringstream os;
    os.precision(3);
    os << "the Schwarz preconditioner would take " << need / kGiB << " GiB, above its share of " << byte_limit / kGiB
       << " GiB";
    throw ResourceLimit(os.str());
  }
  patch_start_.resize(leaves + 1);
  factor_start_.resize(leaves + 1);
  for (std::size_t l = 0; l < leaves; ++l) {
    patch_start_[l + 1] = patch_start_[l] + members[l].size();
    factor_start_[l + 1] = factor_start_[l] + members[l].size() * (members[l].size() + 1) / 2;
  }
  member_.resize(total);
  for (std::size_t l = 0; l < leaves; ++l)
    std::copy(members[l].begin(), members[l].end(), member_.begin() + std::ptrdiff_t(patch_start_[l]));
  decltype(members)().swap(members);
  // Each row's slots: where its patches' results are (the sum that makes z's row).
  for (std::uint32_t k : member_) ++slot_start_[k + 1];
  for (std::size_t k = 0; k < n; ++k) slot_start_[k + 1] += slot_start_[k];
  slot_.resize(total);
  {
    std::vector<std::size_t> next(slot_start_.begin(), slot_start_.end() - 1);
    for (std::size_t s = 0; s < total; ++s) slot_[next[member_[s]]++] = std::uint32_t(s);
  }
  // Each patch's block of A, factorised; a block that rounding leaves not positive definite is
  // factorised again from A_pp + alpha diag(A_pp), alpha = 1e-3 and doubling.
  factor_.resize(factor_start_[leaves]);
  scale_.resize(total);
  tbb::enumerable_thread_specific<std::vector<std::int32_t>> local_index(
      [n] { return std::vector<std::int32_t>(n, -1); });
  tbb::enumerable_thread_specific<double> shifts(0.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves, 16), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<std::int32_t>& where = local_index.local();
    Eigen::MatrixXd a, l;
    for (std::size_t p = r.begin(); p < r.end(); ++p) {
      const std::uint32_t* m = member_.data() + patch_start_[p];
      const auto size = Eigen::Index(patch_start_[p + 1] - patch_start_[p]);
      for (Eigen::Index i = 0; i < size; ++i) where[m[i]] = std::int32_t(i);
      a.setZero(size, size);
      for (Eigen::Index i = 0; i < size; ++i) {
        const std::uint32_t k = m[i];
        a(i, i) = row_diagonal.empty() ? diagonal : row_diagonal[k];
        for (std::size_t e = row[k]; e < row[k + 1]; ++e)
          if (const std::int32_t j = where[col[e]]; j >= 0) a(i, j) = val[e];
      }
      for (Eigen::Index i = 0; i < size; ++i) where[m[i]] = -1;
      // Scaled to a unit diagonal (S A_pp S, S = diag(A_pp)^-1/2, S kept in double): L's entries
      // then fit a float whatever the smoothing (a diagonal of 1.2e77 made float(L_ii) infinite).
      double* scale = scale_.data() + patch_start_[p];
      for (Eigen::Index i = 0; i < size; ++i) scale[i] = 1.0 / std::sqrt(a(i, i));
      for (Eigen::Index j = 0; j < size; ++j)
        for (Eigen::Index i = 0; i < size; ++i) a(i, j) *= scale[i] * scale[j];
      Eigen::LLT<Eigen::MatrixXd> llt(a);
      double alpha = 0;
      while (llt.info() != Eigen::Success || !(llt.matrixLLT().diagonal().minCoeff() > 0)) {
        alpha = alpha == 0 ? 1e-3 : 2 * alpha;
        if (alpha > 1e6) throw NotPositiveDefinite("the Schwarz preconditioner: a patch of A is not positive definite");
        l = a;
        l.diagonal() *= 1 + alpha;
        llt.compute(l);
      }
      shifts.local() = std::max(shifts.local(), alpha);
      float* out = factor_.data() + factor_start_[p];
      const auto& lf = llt.matrixLLT();
      for (Eigen::Index i = 0; i < size; ++i)
        for (Eigen::Index j = 0; j <= i; ++j) *out++ = float(lf(i, j));
    }
  });
  for (double s : shifts) shift_ = std::max(shift_, s);
}

double SchwarzPreconditioner::bytes() const noexcept {
  return 4.0 * double(factor_.size()) + 16.0 * double(member_.size()) + 8.0 * 8.0 * double(member_.size()) +
         8.0 * double(slot_start_.size() + patch_start_.size()) + 8.0 * double(factor_start_.size());
}

namespace {
/// One patch: y = A_pp^-1 R_p r through its packed float L, for M right-hand sides (M = 0: m of
/// them, known at run time).
template <std::size_t M>
void solve_patch(const std::uint32_t* member, std::size_t size, const float* l, const double* scale, const double* r,
                 double* y, std::size_t m_run) {
  const std::size_t m = M ? M : m_run;
  // A_pp^-1 = S (L L^T)^-1 S. L t = S R_p r, row by row (row i of L: i + 1 entries from l + i (i + 1) / 2).
  for (std::size_t i = 0; i < size; ++i) {
    const float* li = l + i * (i + 1) / 2;
    double t[8];
    for (std::size_t c = 0; c < m; ++c) t[c] = scale[i] * r[std::size_t(member[i]) * m + c];
    if constexpr (M == 1) {
      // One right-hand side: the row's dot product in four partial sums. One sum is a chain of
      // dependent subtractions (their latency, not the factor's bytes, bounded this loop: half of
      // the preconditioner's time, which is half of CG's).
      double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
      std::size_t j = 0;
      for (; j + 4 <= i; j += 4) {
        s0 += double(li[j]) * y[j];
        s1 += double(li[j + 1]) * y[j + 1];
        s2 += double(li[j + 2]) * y[j + 2];
        s3 += double(li[j + 3]) * y[j + 3];
      }
      for (; j < i; ++j) s0 += double(li[j]) * y[j];
      t[0] -= (s0 + s1) + (s2 + s3);
    } else {
      for (std::size_t j = 0; j < i; ++j)
        for (std::size_t c = 0; c < m; ++c) t[c] -= double(li[j]) * y[j * m + c];
    }
    const double d = 1.0 / double(li[i]);
    for (std::size_t c = 0; c < m; ++c) y[i * m + c] = t[c] * d;
  }
  // L^T y = t in place, last row first: y_i is final once the rows after it have given their parts.
  for (std::size_t i = size; i-- > 0;) {
    const float* li = l + i * (i + 1) / 2;
    const double d = 1.0 / double(li[i]);
    double x[8];
    for (std::size_t c = 0; c < m; ++c) x[c] = y[i * m + c] * d;
    for (std::size_t c = 0; c < m; ++c) y[i * m + c] = x[c];
    for (std::size_t j = 0; j < i; ++j)
      for (std::size_t c = 0; c < m; ++c) y[j * m + c] -= double(li[j]) * x[c];
  }
  for (std::size_t i = 0; i < size; ++i)
    for (std::size_t c = 0; c < m; ++c) y[i * m + c] *= scale[i];
}
}  // namespace

void SchwarzPreconditioner::apply(const double* r, double* z, std::size_t m) const {
  const std::size_t n = slot_start_.size() - 1;
  // The patches' results side by side (slot s: m values), then each row's sum of its slots, in a
  // fixed order: the same bits whatever the threads.
  FillVector<double>& y = work_;
  y.resize(member_.size() * m);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, patches(), 16), [&](const tbb::blocked_range<std::size_t>& rg) {
    for (std::size_t p = rg.begin(); p < rg.end(); ++p) {
      const std::size_t first = patch_start_[p], size = patch_start_[p + 1] - first;
      const auto run = [&](auto fixed) {
        solve_patch<decltype(fixed)::value>(member_.data() + first, size, factor_.data() + factor_start_[p],
                                            scale_.data() + first, r, y.data() + first * m, m);
      };
      switch (m) {
        case 1:
          run(std::integral_constant<std::size_t, 1>{});
          break;
        case 3:
          run(std::integral_constant<std::size_t, 3>{});
          break;
        case 4:
          run(std::integral_constant<std::size_t, 4>{});
          break;
        default:
          run(std::integral_constant<std::size_t, 0>{});
      }
    }
  });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<std::size_t>& rg) {
    for (std::size_t k = rg.begin(); k < rg.end(); ++k) {
      double s[8] = {};
      for (std::size_t e = slot_start_[k]; e < slot_start_[k + 1]; ++e)
        for (std::size_t c = 0; c < m; ++c) s[c] += y[std::size_t(slot_[e]) * m + c];
      for (std::size_t c = 0; c < m; ++c) z[k * m + c] = s[c];
    }
  });
}

}  // namespace csrbf::detail
