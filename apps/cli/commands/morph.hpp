#pragma once

#include "csrbf/errors.hpp"
#include "csrbf/morph/job.hpp"

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

// Shared with the distributed run (distributed.cpp):

/// The job of the options; distributed refuses what runs in one process only (UsageError).
morph::MorphJob job_of(const MorphArgs& a, bool distributed);

/// The exit status of an outcome: 1 where the morph inverts cells and nothing was written (said on
/// stderr if speak).
int report_inversion(const MorphArgs& a, const morph::MorphOutcome& o, bool speak);

/// f(), its JobError (contradicting options) a usage error.
template <class F>
auto usage_errors(F&& f) {
  try {
    return f();
  } catch (const morph::JobError& e) {
    throw UsageError(std::string("morph: ") + e.what());
  }
}

}  // namespace csrbf::cli
