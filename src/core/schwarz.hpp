// A preconditioner of csrbf's conjugate gradients for scattered points (private to csrbf::core):
// additive Schwarz over overlapping patches of the points. The points' box is bisected (its longest
// side at its middle) into leaves of side at most kSchwarzLeafSide R holding at most
// kSchwarzLeafPoints points; a leaf's patch is the points of its box grown by a quarter of R (of the
// leaf's side, where that is smaller) on every side, at most kSchwarzPatchPoints of them. Each patch's block of A is
// factorised densely (Cholesky in double of the block scaled to a unit diagonal, L kept in float) and
//   M^-1 r = sum over patches p of R_p^T A_pp^-1 R_p r,
// symmetric and positive definite, so CG may use it.
//
// Why: random points come in close pairs (1e5 uniform points in a square: two of them 2.3e-4 R
// apart), each a near-null direction e_i - e_j of A. IC(0) over the whole matrix took 652 steps on
// them (Franke's function, 40 neighbours); a patch holds both points of every pair closer than R / 4
// however the leaves cut the plane, and solves it exactly. In a prototype (cells of side R) that was
// 29 steps to 1e-10 at 1e4 and 1e5 points alike; without the overlap (block Jacobi over the cells)
// 450. Leaves of up to 1.5 R and 64 points: 30 steps to 1e-12 at 1e5 points in 2-D (46 with leaves
// of R and 32 points), 42 in 3-D (59) (tests/core/test_schwarz.cpp
// measures the count). Each fit took about the same time with either.
#pragma once

#include "csrbf/types.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace csrbf::detail {

inline constexpr double kSchwarzLeafSide = 1.5;
/// From this many points with at least this many neighbours on average, in 2-D or 3-D, an
/// interpolator's fit goes to CG without RCM and the envelope's count (fit.cpp).
inline constexpr std::size_t kSchwarzOnlyPoints = 20000;
inline constexpr double kSchwarzOnlyNeighbors = 6.0;
inline constexpr std::size_t kSchwarzLeafPoints = 64;
inline constexpr std::size_t kSchwarzPatchPoints = 160;

/// The points in the order of the leaves of that bisection (a spatial order: CG's rows where no
/// envelope ordering is needed, fit.cpp).
std::vector<std::uint32_t> schwarz_order(std::span<const Vec3> points, double radius);

class SchwarzPreconditioner {
 public:
  /// `points[k]` is row k of A in CG's order; A's rows as IncompleteCholesky takes them (off-diagonal
  /// columns col[row[k] .. row[k+1]) of both triangles, values beside them; the diagonal `diagonal`,
  /// or row_diagonal[k] where that is not empty). Throws ResourceLimit where the factors would take
  /// more than `byte_limit` (before they are allocated).
  SchwarzPreconditioner(std::span<const Vec3> points, double radius, std::span<const std::size_t> row,
                        std::span<const std::uint32_t> col, std::span<const double> val, double diagonal,
                        std::span<const double> row_diagonal, double byte_limit);

  /// z = M^-1 r for n x m values (row-major, m <= 8), patches in parallel. One call at a time (CG
  /// holds its lock): the patches' results share one buffer.
  void apply(const double* r, double* z, std::size_t m) const;

  std::size_t patches() const noexcept { return patch_start_.size() - 1; }
  /// Patch p's rows of A, ascending.
  std::span<const std::uint32_t> patch(std::size_t p) const noexcept {
    return {member_.data() + patch_start_[p], patch_start_[p + 1] - patch_start_[p]};
  }
  /// Points in all patches together (each point counts once for each patch that holds it).
  std::size_t patch_points() const noexcept { return member_.size(); }
  double bytes() const noexcept;
  /// The largest shift a patch needed (0: every patch factorised as it is).
  double shift() const noexcept { return shift_; }

 private:
  std::vector<std::size_t> patch_start_;   // patch p: member_[patch_start_[p] .. patch_start_[p + 1])
  std::vector<std::uint32_t> member_;      // rows of A, ascending within a patch
  std::vector<std::size_t> factor_start_;  // patch p's L, packed rows (row i: i + 1 entries)
  FillVector<float> factor_;               // of S A_pp S: unit diagonal
  FillVector<double> scale_;               // S = diag(A_pp)^-1/2, beside member_
  std::vector<std::size_t> slot_start_;    // row k's slots: slot_[slot_start_[k] .. slot_start_[k + 1])
  std::vector<std::uint32_t> slot_;        // positions in member_ (and in apply's patch results)
  mutable FillVector<double> work_;        // apply's patch results, m values a slot
  double shift_ = 0;
};

}  // namespace csrbf::detail
