// Where a morph fits and evaluates its mapping, and how the processes that morph one mesh agree.
// The default is this process alone (SpaceMap). csrbf::mpi supplies two others: one that spreads
// rank 0's controls and points over the MPI ranks, and one for a mesh decomposed over the ranks
// (each rank a processor folder of an OpenFOAM case), whose members are collective: every rank calls
// them in the same order, and a failure on one rank is a failure on all (agree).
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/fit_stats.hpp"
#include "csrbf/types.hpp"

#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

namespace csrbf::morph {

class VolumeFile;

/// A fitted mapping, as morph() uses it.
class FittedMapping {
 public:
  virtual ~FittedMapping() = default;
  /// out = in + phase d(in).
  virtual void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) = 0;
  /// out = d(in).
  virtual void displacements(std::span<const Vec3> in, std::span<Vec3> out) = 0;
  virtual FitStats stats() const = 0;
};

class MorphBackend {
 public:
  virtual ~MorphBackend() = default;
  /// The mapping of sources to targets. ids: a number a control for messages (the mesh's own).
  virtual std::unique_ptr<FittedMapping> fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                             const FitOptions& options, std::span<const std::uint64_t> ids);
  /// The points the next fit's mapping will be evaluated at (the mesh's), for a backend that
  /// spreads them over processes to balance; valid until that fit returns.
  virtual void balance(std::span<const Vec3> points) { (void)points; }
  /// True where this process holds a part of the mesh and other processes the rest: a patch may be
  /// empty here, and a displacements file name points of other parts.
  virtual bool part() const { return false; }
  /// True where the mappings of several fits stay usable together (a two-level fit sums two); a
  /// backend whose later fit replaces its earlier mapping says false.
  virtual bool keeps_mappings() const { return true; }
  /// The largest and the sum of a value over the processes that morph the mesh (the value itself
  /// where alone).
  virtual double max(double local) { return local; }
  virtual double sum(double local) { return local; }
  /// Every process's points, in rank order (the points themselves where alone).
  virtual std::vector<Vec3> gather(std::span<const Vec3> local) { return {local.begin(), local.end()}; }
  /// Each value replaced by its largest over the processes (unchanged where alone).
  virtual void max(std::span<double> values) { (void)values; }
  /// Rethrows local, or another process's failure, on every process.
  virtual void agree(std::exception_ptr local) {
    if (local) std::rethrow_exception(local);
  }
  /// The mesh this process opens for the job's mesh (a part: its processor folder).
  virtual std::filesystem::path mesh_path(const std::filesystem::path& mesh) { return mesh; }
  virtual void write_copy(const VolumeFile& file, std::span<const Vec3> points, const std::filesystem::path& out);
  virtual void write_in_place(const VolumeFile& file, std::span<const Vec3> points);
};

/// The default: SpaceMap in this process.
MorphBackend& local_backend();

/// f's exception, if it threw: what a process hands to MorphBackend::agree.
template <class F>
std::exception_ptr caught(F&& f) {
  try {
    f();
  } catch (...) {
    return std::current_exception();
  }
  return nullptr;
}

}  // namespace csrbf::morph
