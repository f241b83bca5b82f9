// The two ways `mpirun -np K csrbf deform|morph` spreads its work (K > 1):
// - ScatterBackend: rank 0 read a single file; the controls and points it fits and evaluates are
//   partitioned by recursive coordinate bisection and scattered, fitted and evaluated on every rank
//   (DistributedMap), and the moved points gathered back. The other ranks run serve() meanwhile.
//   Rank 0 holds every point and control (the file's), the others only their share.
// - DecomposedBackend: an OpenFOAM case decomposed by decomposePar, one processor folder a rank:
//   each rank reads, morphs and writes its own folder; the controls that processors share are
//   owned once; quality, inversion and the writes are agreed by all ranks.
#pragma once

#include "csrbf/morph/backend.hpp"
#include "csrbf/mpi/distributed.hpp"

#include <mpi.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace csrbf::mpi {

/// Rank 0's side. Every member runs on rank 0 only; serve() answers on the others.
class ScatterBackend final : public morph::MorphBackend {
 public:
  /// balance: the points that will be evaluated (the mesh), so that the first fit's partition
  /// balances them with the controls; may be empty (then the controls alone).
  ScatterBackend(MPI_Comm comm, DistributedSolver solver, std::span<const Vec3> balance = {});
  /// Ends the workers' service (finish(1) if not finished).
  ~ScatterBackend() override;
  bool keeps_mappings() const override { return false; }  // a later fit replaces the ranks' mapping
  ScatterBackend(const ScatterBackend&) = delete;
  ScatterBackend& operator=(const ScatterBackend&) = delete;

  std::unique_ptr<morph::FittedMapping> fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                            const FitOptions& options, std::span<const std::uint64_t> ids) override;
  /// Every rank's figures of the latest fit and evaluations (rank order), and the fit's.
  std::vector<RankStats> rank_stats();
  const DistributedStats& stats() const noexcept { return stats_; }
  /// Tells the workers to stop; they exit with exit_code. Idempotent.
  void finish(int exit_code) noexcept;

 private:
  friend class ScatterMapping;
  MPI_Comm comm_;
  DistributedSolver solver_;
  std::vector<Vec3> balance_;
  std::optional<Partition> partition_;
  std::optional<DistributedMap> map_;  // rank 0's share
  DistributedStats stats_;
  int generation_ = 0;
  bool finished_ = false;
};

/// The workers' side of a ScatterBackend: fits and evaluates as rank 0 asks, until it finishes;
/// returns the exit code it finished with.
int serve(MPI_Comm comm);

/// How a mesh is split into parts, one a rank: an OpenFOAM case's processor folders
/// (decomposePar), or the pieces a .pvtu file lists (each a .vtu).
struct Decomposition {
  enum class Kind { None, OpenFoam, Pvtu } kind = Kind::None;
  std::filesystem::path root;                ///< the case folder, or the .pvtu file
  std::vector<std::filesystem::path> parts;  ///< processor folders, or piece files, in rank order
  std::string pvtu_text;                     ///< the .pvtu file's own text
};
/// The decomposition of mesh: None where it is a single mesh. A .pvtu is read whole (it is small)
/// and its pieces' paths resolved against its folder; throws io::FileError for a broken one.
Decomposition find_decomposition(const std::filesystem::path& mesh);

/// One rank's part of a decomposed mesh. Collective: every rank runs the same job.
class DecomposedBackend final : public morph::MorphBackend {
 public:
  DecomposedBackend(MPI_Comm comm, DistributedSolver solver, Decomposition decomposition);
  std::unique_ptr<morph::FittedMapping> fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                            const FitOptions& options, std::span<const std::uint64_t> ids) override;
  bool part() const override { return true; }
  bool keeps_mappings() const override { return false; }  // a later fit replaces the ranks' mapping
  double max(double local) override;
  double sum(double local) override;
  std::vector<Vec3> gather(std::span<const Vec3> local) override;
  void max(std::span<double> values) override;
  void agree(std::exception_ptr local) override;
  std::filesystem::path mesh_path(const std::filesystem::path& mesh) override;
  void write_copy(const morph::VolumeFile& file, std::span<const Vec3> points,
                  const std::filesystem::path& out) override;
  void write_in_place(const morph::VolumeFile& file, std::span<const Vec3> points) override;
  /// Every rank's figures (rank order; collective).
  std::vector<RankStats> rank_stats();
  const DistributedStats& stats() const noexcept { return stats_; }

 private:
  void write_pieces_copy(const morph::VolumeFile& file, std::span<const Vec3> points, const std::filesystem::path& out);
  MPI_Comm comm_;
  DistributedSolver solver_;
  Decomposition d_;
  RankStats last_;  // the latest fit's figures, kept by its mapping
  DistributedStats stats_;
};

/// An exception's exit code: 2 for a usage error (csrbf::morph::JobError), 1 otherwise.
int exit_code_of(const std::exception_ptr& e);

}  // namespace csrbf::mpi
