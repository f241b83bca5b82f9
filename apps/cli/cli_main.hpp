// The command-line program's body, shared by csrbf-cli (main.cpp) and csrbf-cli-mpi (main_mpi.cpp):
// the commands are compiled once, and only main_mpi.cpp and commands/distributed.cpp know MPI.
#pragma once

#include "commands/deform.hpp"
#include "commands/morph.hpp"

namespace csrbf::cli {

/// What csrbf-cli-mpi adds: under mpirun with more than one rank, deform and morph run across the
/// ranks, rank 0 alone speaks, and every rank waits for the others before it leaves.
class Ranks {
 public:
  virtual ~Ranks() = default;
  /// Starts MPI where more than one rank was launched (it may take its own arguments out of argv):
  /// true if so, and then every call below may be made.
  virtual bool start(int* argc, char*** argv) = 0;
  /// A rank other than rank 0: it prints nothing.
  virtual bool quiet() const = 0;
  /// Waits for every rank.
  virtual void barrier() = 0;
  virtual int deform(const DeformArgs& a) = 0;
  virtual int morph(const MorphArgs& a) = 0;
};

/// Parses argv and runs the command; the exit status. ranks: null in the serial program.
int cli_main(int argc, char** argv, Ranks* ranks);

}  // namespace csrbf::cli
