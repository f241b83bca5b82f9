// csrbf-morph: `csrbf morph` of an OpenFOAM case, in a program that loads none of VTK's, CGNS's,
// Gmsh's, assimp's or the renderer's libraries (csrbf-cli loads about 110, and spent 80 ms of
// every morph loading them: docs/PERFORMANCE.md). csrbf's launcher runs it for `csrbf morph` on
// one process; for any other mesh (a file) it runs csrbf-cli in its place, with the same argv.
// It links csrbf::morph without csrbf::morph_formats: the readers of those formats are not in it.
#include "commands/morph.hpp"
#include "program.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "csrbf/morph/volume_file.hpp"
#include "csrbf/io/atomic_file.hpp"

#include <filesystem>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  csrbf::cli::start_program(argv);
  std::vector<std::string> kept(argv, argv + argc);  // before the spellings are rewritten
  CLI::App app{"csrbf: real-time 3D deformation by compactly supported radial basis functions (Wendland CSRBF)"};
  app.require_subcommand(1);
  csrbf::cli::MorphArgs args;
  auto* morph = csrbf::cli::add_morph_command(app, args);
  double time_limit = 0;
  csrbf::cli::add_time_limit(morph, time_limit);
  csrbf::cli::openfoam_spellings(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return csrbf::cli::parse_failed(app, e, false);
  }
  // A mesh file, not a case folder: the whole program's. (A folder that is not a case is refused
  // here as there.)
  std::error_code ec;
  if (!std::filesystem::is_directory(args.mesh, ec)) {
    std::vector<char*> again;
    for (std::string& a : kept) again.push_back(a.data());
    again.push_back(nullptr);
    std::exit(csrbf::cli::run_sibling("csrbf-cli", again.data()));  // it reads every format
  }
  csrbf::io::limit_time(time_limit, true);
  return csrbf::cli::run_command([&] { return csrbf::cli::run_morph(args); });
}
