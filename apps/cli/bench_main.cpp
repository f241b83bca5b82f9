// csrbf-bench: `csrbf bench`, the benchmark scenarios of docs/PERFORMANCE.md, in a program of their
// own, so that csrbf-cli carries neither them nor the `peers` scenario's VTK. csrbf's launcher
// runs it for `csrbf bench` with the same argv (argv[1] is "bench"), so its options, --help and
// messages are those of `csrbf bench`. Exit 0 on success, 2 on a usage error, 1 on bad data.
#include "commands/bench.hpp"
#include "csrbf/version.hpp"
#include "program.hpp"

#include <CLI/CLI.hpp>

#include <string>

namespace cli = csrbf::cli;

int main(int argc, char** argv) {
  cli::start_program(argv);
  CLI::App app{"csrbf: real-time 3D deformation by compactly supported radial basis functions (Wendland CSRBF)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("csrbf ") + csrbf::kVersion);
  cli::BenchOptions args;
  cli::add_bench_command(app, args);
  cli::openfoam_spellings(argc, argv);  // as csrbf-cli reads every command's arguments
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return cli::parse_failed(app, e, false);
  }
  return cli::run_command([&] {
    cli::run_bench(args);
    return 0;
  });
}
