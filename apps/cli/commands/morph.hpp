#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace csrbf::cli {

struct MorphArgs {
  std::string mesh, out, motion;
  std::string motion_series;  ///< --motion-series DIR
  std::string radius;         ///< R, "auto", or empty (the motion file's, else auto)
  std::optional<double> greedy;
  double greedy_budget = 0.2;
  std::string levels = "auto";
  std::string kernel, polynomial, solver = "auto";
  std::string time;  ///< OpenFOAM's -time: latest or a time
  double phase = 1.0;
  double memory_limit_gib = 4.0;
  bool json = false, force = false, in_place = false;
  bool quiet = false;  ///< no progress bars or notes on the terminal
};

/// Adds `csrbf morph` and its options to app.
CLI::App* add_morph_command(CLI::App& app, MorphArgs& a);

/// `csrbf morph`: returns the exit status; throws for bad input (the caller prints it and exits 1,
/// or 2 for a UsageError).
int run_morph(const MorphArgs& a);

#ifdef CSRBF_WITH_MPI
}  // namespace csrbf::cli
namespace csrbf::mpi {
class Runtime;
}
namespace csrbf::cli {
/// `mpirun -np K csrbf morph` (K > 1): a decomposed OpenFOAM case (processor folders, one a rank:
/// each rank morphs its own), or a single mesh that rank 0 reads and writes while the fit and the
/// evaluation are spread over the ranks. Every rank returns the same status.
int run_morph_distributed(const MorphArgs& a, mpi::Runtime& rt);
#endif

}  // namespace csrbf::cli
