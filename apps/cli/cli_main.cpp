// csrbf: the command-line program. Exit 0 on success, 2 on a usage error, 1 on bad data or failure.
// Each command is a file of commands/ with its options (add_*_command) and its run (run_*).
// `csrbf bench` is csrbf-bench's (bench_main.cpp): listed here, and handed over to it.
// csrbf-cli (main.cpp) and csrbf-cli-mpi (main_mpi.cpp) run it, the latter with its ranks.
#include "cli_main.hpp"

#include "commands.hpp"
#include "commands/animate.hpp"
#include "commands/bench.hpp"
#include "commands/deform.hpp"
#include "commands/export.hpp"
#include "commands/info.hpp"
#include "commands/morph.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/version.hpp"
#include "program.hpp"

#include <CLI/CLI.hpp>

#include <iostream>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::cli {

int cli_main(int argc, char** argv, Ranks* ranks) {
  start_program(argv);
  CLI::App app{"csrbf: real-time 3D deformation by compactly supported radial basis functions (Wendland CSRBF)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("csrbf ") + csrbf::kVersion);
  DeformArgs deform_args;
  auto* deform = add_deform_command(app, deform_args);
  // Its options are csrbf-bench's: any arguments are taken here, and passed over whole.
  auto* bench = app.add_subcommand("bench", kBenchDescription)->allow_extras()->prefix_command();
  bench->set_help_flag();
  ExportOptions export_args;
  auto* exporter = add_export_command(app, export_args);
  AnimateOptions animate_args;
  auto* animate = add_animate_command(app, animate_args);
  InfoArgs info_args;
  auto* info = add_info_command(app, info_args);
  MorphArgs morph_args;
  auto* morph = add_morph_command(app, morph_args);
  double time_limit = 0;
  for (CLI::App* cmd : {deform, info, morph, exporter, animate}) add_time_limit(cmd, time_limit);

  // Under mpirun with more than one rank: MPI starts first; every rank parses, rank 0 alone speaks,
  // and the others wait for it before they leave (else mpirun may end rank 0 before it has spoken).
  const bool distributed = ranks && ranks->start(&argc, &argv);
  const bool quiet = distributed && ranks->quiet();
  const auto leave = [&](int code) {
    if (distributed) ranks->barrier();
    return code;
  };
  std::vector<char*> given(argv, argv + argc + 1);  // for csrbf-bench, before the spellings are rewritten
  openfoam_spellings(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return leave(parse_failed(app, e, quiet));
  }
  csrbf::io::limit_time(time_limit, !quiet);
  if (distributed) {
    if (!*deform && !*morph) {
      if (!quiet)
        std::cerr << "csrbf: error: " << app.get_subcommands().front()->get_name()
                  << " runs on one process; under mpirun with more than one rank, csrbf runs deform and morph\n";
      return leave(2);
    }
    return leave(*deform ? ranks->deform(deform_args) : ranks->morph(morph_args));
  }
  if (*bench) return run_sibling("csrbf-bench", given.data());  // the launcher runs it itself

  return run_command([&]() -> int {
    if (*deform) return run_deform(deform_args);
    if (*morph) return run_morph(morph_args);
    if (*animate) return run_animate(animate_args);
    if (*exporter) return run_export(export_args);
    return run_info(info_args);
  });
}

}  // namespace csrbf::cli
