// `csrbf bench`: the benchmark scenarios of docs/PERFORMANCE.md, timed in this process. A program of
// its own, csrbf-bench (bench_main.cpp), which the launcher runs for `csrbf bench`.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace csrbf::cli {

/// `csrbf bench`'s line in `csrbf --help` (csrbf-cli lists it) and its --help's first line.
inline constexpr const char* kBenchDescription = "Run a benchmark scenario and print medians (docs/PERFORMANCE.md)";

struct BenchOptions {
  std::string scenario;          ///< fish, face, ball, scale, solvers, peers, all
  bool json = false;             ///< one JSON object a line instead of a table
  bool quick = false;            ///< smaller sweeps (for tests and slow machines)
  std::vector<double> controls;  ///< solvers: only these N (empty: the whole sweep)
  std::string geometry;          ///< solvers: only "sphere" or "cube" (empty: both)
  int threads = 0;               ///< 0: each scenario's own choice (1 for fish/face/ball, 1 and all for scale)
  double seconds = 0.3;          ///< time spent on each measured quantity
  std::string loop = "auto";     ///< evaluation loop: auto, portable or avx512 (set_evaluation_loop)
  std::string data_dir;          ///< where fish.obj, face.obj and their controls are (default: bundled)
};

/// Runs the scenario(s), printing rows to stdout. Throws on bad options or missing data.
void run_bench(const BenchOptions& options);

/// The scenario names, "all" excluded.
const std::vector<std::string>& bench_scenarios();

/// `csrbf bench` and its options, into o.
CLI::App* add_bench_command(CLI::App& app, BenchOptions& o);

}  // namespace csrbf::cli
