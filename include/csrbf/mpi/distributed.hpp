// The CSRBF fit and evaluation distributed over MPI ranks, on PETSc (docs/DISTRIBUTED.md).
//
// Each rank owns a share of the controls and of the points. No rank gathers them all:
// - halo: each rank's bounding box (of its controls, then of its points) goes to every rank, and each
//   rank sends the others the controls it owns within R of their box: for the matrix rows, sources;
//   for the evaluation, sources and coefficients;
// - matrix: the rows of a rank's controls, assembled there, as a PETSc parallel AIJ matrix (the
//   neighbour search over the owned and halo controls, csrbf's NeighborIndex);
// - solve: MUMPS's distributed Cholesky through PETSc, or PETSc's CG preconditioned by additive
//   Schwarz (one layer of overlap) with an incomplete Cholesky on each rank's block; the polynomial block by the Schur
//   complement, whose 4 x 4 blocks are summed over the ranks (MPI_Allreduce); the residual checked globally;
// - evaluation: each rank's points from its owned and halo (source, coefficient) pairs, through a
//   SpaceMap made from that solution (the serial grid and loops).
// Every member function is collective over the map's communicator.
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/types.hpp"

#include <mpi.h>

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace csrbf::mpi {

/// The distributed solver. Auto: MUMPS for small systems (kDirectBelow controls or fewer), else CG,
/// which gives way to MUMPS where its residual's rate predicts more than kMumpsCgSteps x (N / 1e5)
/// steps (measured here: MUMPS's factorisation cost 226-280 CG steps at N = 1e5-2e5), or where it
/// has not converged in kCgMaxIterations: the serial rule (fit_options.hpp) with MUMPS for the
/// direct solvers, the envelope solver having no distributed form.
enum class DistributedSolver { Auto, Mumps, Cg };
inline constexpr std::size_t kDirectBelow = 20000;
inline constexpr double kMumpsCgSteps = 250.0;
/// "auto", "mumps", "cg"; the serial solver names map to them: envelope, eigen and cholmod to mumps.
std::optional<DistributedSolver> parse_distributed_solver(const std::string& name) noexcept;
std::string distributed_solver_name(DistributedSolver s);

/// What one rank did, for --json.
struct RankStats {
  int rank = 0;
  std::size_t controls_owned = 0;    ///< rows of the matrix on this rank
  std::size_t controls_halo = 0;     ///< other ranks' controls within R of this rank's controls
  std::size_t controls_dropped = 0;  ///< this rank's controls another (lower) rank also had: owned there
  std::size_t eval_halo = 0;         ///< other ranks' controls within R of this rank's points (last apply)
  std::size_t points = 0;            ///< points evaluated here (all applies)
  std::size_t matrix_nonzeros = 0;   ///< of this rank's rows
  std::size_t bytes_sent = 0;        ///< by csrbf's own exchanges (halo, sums), not PETSc's inside the solve
  std::size_t peak_bytes = 0;        ///< peak resident memory of the process
  double seconds_halo = 0, seconds_assembly = 0, seconds_solve = 0, seconds_residual = 0, seconds_evaluate = 0;
};

/// The whole fit's figures (equal on every rank).
struct DistributedStats {
  std::size_t controls = 0, ranks = 0, iterations = 0;
  DistributedSolver solver = DistributedSolver::Mumps;  ///< the one that solved
  bool fell_back = false;                               ///< CG did not converge, MUMPS took over
  bool core_cg = false;  ///< one rank: CG was the core's own (the serial fit's), not PETSc's KSP
  double residual_relative = 0;
};

class DistributedMap {
 public:
  /// Collective. sources, destinations: this rank's controls (any number, 0 included; N >= 1 over
  /// all ranks). ids: a number for each control, used in messages (e.g. the mesh's point id; default
  /// the control's position in this rank's list). With dedupe, a control whose source another rank
  /// also has, bit for bit, is owned by the lowest such rank (the points a decomposed mesh shares
  /// between processors); their destinations must agree to 1e-12 of the largest displacement.
  /// Throws Failure (on every rank) for bad input, duplicate sources, a matrix that is not positive
  /// definite, a residual above kResidualLimit, or the memory limit.
  static DistributedMap fit(MPI_Comm comm, std::span<const Vec3> sources, std::span<const Vec3> destinations,
                            const FitOptions& options, DistributedSolver solver = DistributedSolver::Auto,
                            std::span<const std::uint64_t> ids = {}, bool dedupe = false);

  /// Collective. out = in + phase * d(in) for this rank's points (any number, 0 included).
  void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase = 1.0);
  /// Collective. d(in) for this rank's points.
  void displacements(std::span<const Vec3> in, std::span<Vec3> out);

  /// This rank's owned controls (after dedupe), their coefficients and the polynomial (u coordinates).
  std::span<const Vec3> sources() const noexcept { return sources_; }
  const Eigen::Matrix<double, Eigen::Dynamic, 3>& coefficients() const noexcept { return alpha_; }
  /// p(x) = b0 + B x in plain coordinates: row 0 is b0, rows 1-3 are B^T.
  Eigen::Matrix<double, 4, 3> polynomial_coefficients() const;
  /// The first global row of this rank's controls.
  std::size_t offset() const noexcept { return offset_; }
  const RankStats& rank_stats() const noexcept { return rank_stats_; }
  const DistributedStats& stats() const noexcept { return stats_; }
  RankStats& rank_stats() noexcept { return rank_stats_; }

 private:
  DistributedMap() = default;
  MPI_Comm comm_ = MPI_COMM_NULL;
  FitOptions options_;
  std::vector<Vec3> sources_;
  Eigen::Matrix<double, Eigen::Dynamic, 3> alpha_;
  Eigen::Matrix<double, 4, 3> beta_ = Eigen::Matrix<double, 4, 3>::Zero();
  Vec3 center_ = Vec3::Zero();
  double scale_ = 1.0;
  std::size_t offset_ = 0;
  RankStats rank_stats_;
  DistributedStats stats_;
};

/// Recursive coordinate bisection of a point set and a control set together into `parts` regions:
/// each cut halves the weight along the longest side of the region's box, a point weighing 1 and a
/// control weighing max(1, points / controls), so that both are spread evenly. Returns the part of
/// each point and of each control. Serial (rank 0, which read the file).
struct Partition {
  std::vector<int> point_part, control_part;
  /// The cuts, to place other points: node 0 is the root; a leaf has part >= 0.
  struct Node {
    int axis = 0;
    double cut = 0;  ///< a point with coordinate < cut goes left
    int left = -1, right = -1, part = -1;
  };
  std::vector<Node> tree;
  /// The part whose region holds x (points on a cut go right).
  int part_of(const Vec3& x) const;
};
Partition rcb_partition(std::span<const Vec3> points, std::span<const Vec3> controls, int parts);

}  // namespace csrbf::mpi
