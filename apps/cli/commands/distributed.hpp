// deform and morph under mpirun with more than one rank (csrbf::mpi): csrbf-cli-mpi's alone, so
// that the serial programs compile the commands once without MPI.
#pragma once

#include "deform.hpp"
#include "morph.hpp"

namespace csrbf::mpi {
class Runtime;
}

namespace csrbf::cli {

/// `mpirun -np K csrbf deform` (K > 1): rank 0 reads the mesh and the controls, the fit and the
/// evaluation are spread over the ranks (csrbf::mpi::ScatterBackend), rank 0 writes. The other
/// ranks serve until rank 0 is done, and exit with its status.
int run_deform_distributed(mpi::Runtime& rt, const DeformArgs& a);

/// `mpirun -np K csrbf morph` (K > 1): a decomposed OpenFOAM case (processor folders, one a rank:
/// each rank morphs its own), or a single mesh that rank 0 reads and writes while the fit and the
/// evaluation are spread over the ranks. Every rank returns the same status.
int run_morph_distributed(const MorphArgs& a, mpi::Runtime& rt);

}  // namespace csrbf::cli
