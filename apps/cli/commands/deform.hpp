// `csrbf deform`: a mesh moved by the space mapping of controls or a deformation file; under mpirun
// with more than one rank, fitted and evaluated across the ranks (csrbf::mpi).
#pragma once

#include "fit_input.hpp"

#include <CLI/CLI.hpp>

#include <string>

namespace csrbf::cli {

struct DeformArgs {
  FitArgs fit;
  std::string mesh_in, mesh_out;
  double phase = 1.0;
  bool phase_given = false;  // else a deformation file's phase, where it has one
  bool json = false;
};

CLI::App* add_deform_command(CLI::App& app, DeformArgs& a);
int run_deform(DeformArgs& a);

/// -o: a new file of a format csrbf writes, not one of the inputs (UsageError; checked before
/// anything large is read). Shared with the distributed run (distributed.cpp).
void check_deform_output(const DeformArgs& a);

}  // namespace csrbf::cli
