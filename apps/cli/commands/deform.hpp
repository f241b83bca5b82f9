// `csrbf deform`: a mesh moved by the space mapping of controls or a deformation file; under mpirun
// with more than one rank, fitted and evaluated across the ranks (csrbf::mpi).
#pragma once

#include "fit_input.hpp"

#include <CLI/CLI.hpp>

#include <string>

#ifdef CSRBF_WITH_MPI
#include "csrbf/mpi/runtime.hpp"
#endif

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
#ifdef CSRBF_WITH_MPI
/// `mpirun -np K csrbf deform` (K > 1): rank 0 reads the mesh and the controls, the fit and the
/// evaluation are spread over the ranks (csrbf::mpi::ScatterBackend), rank 0 writes. The other
/// ranks serve until rank 0 is done, and exit with its status.
int run_deform_distributed(mpi::Runtime& rt, const DeformArgs& a);
#endif

}  // namespace csrbf::cli
