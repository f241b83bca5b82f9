// csrbf::mpi's runtime: MPI and PETSc started and stopped once per process, and the one rule every
// distributed step follows: a failure on any rank is a failure on all of them, agreed collectively
// at the step's end, so that no rank waits forever in a collective the failed rank never reaches.
#pragma once

#include "csrbf/errors.hpp"

#include <mpi.h>

#include <cstddef>
#include <exception>
#include <stdexcept>
#include <string>

namespace csrbf::mpi {

/// The ranks of the job that started this process, read from the launcher's environment (Open
/// MPI's mpirun, PMIx, MPICH's Hydra); 0 when no launcher started it. The command line runs its
/// distributed path where this is > 1, and the serial program otherwise (no MPI is started).
int launched_ranks() noexcept;
/// This process's rank in that job, from the same environment; 0 when none.
int launched_rank() noexcept;

/// MPI (MPI_THREAD_FUNNELED: TBB's threads never call MPI) and PETSc, for the life of the object.
/// PETSc's error handler is replaced by one that returns the error to csrbf, which throws it.
class Runtime {
 public:
  Runtime(int* argc, char*** argv);
  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;
  MPI_Comm comm() const noexcept { return MPI_COMM_WORLD; }
  int rank() const noexcept { return rank_; }
  int size() const noexcept { return size_; }

 private:
  int rank_ = 0, size_ = 1;
};

/// An error agreed by every rank: the message of the lowest rank that failed, with its rank, and
/// the exit code it asked for (1: bad data or a failure; 2: a usage error).
class Failure : public csrbf::Error {
 public:
  Failure(const std::string& message, int rank, int exit_code)
      : csrbf::Error(message), rank_(rank), exit_code_(exit_code) {}
  int rank() const noexcept { return rank_; }
  int exit_code() const noexcept { return exit_code_; }

 private:
  int rank_, exit_code_;
};

/// Collective. Every rank passes its own outcome (null: success); if any rank failed, every rank
/// throws Failure carrying the lowest failing rank's message and exit code. `exit_code` maps an
/// exception to its code (default: 1; a Failure keeps its own).
void agree(MPI_Comm comm, std::exception_ptr local, int (*exit_code)(const std::exception_ptr&) = nullptr);

/// Runs f on every rank and agrees on the outcome: f's result where every rank succeeded.
template <class F>
auto collectively(MPI_Comm comm, F&& f) -> decltype(f()) {
  std::exception_ptr error;
  if constexpr (std::is_void_v<decltype(f())>) {
    try {
      f();
    } catch (...) {
      error = std::current_exception();
    }
    agree(comm, error);
  } else {
    decltype(f()) out{};
    try {
      out = f();
    } catch (...) {
      error = std::current_exception();
    }
    agree(comm, error);
    return out;
  }
}

/// This process's peak resident memory (bytes), from getrusage.
std::size_t peak_memory_bytes() noexcept;

/// Throws std::runtime_error naming `what` where a PETSc call returned an error.
void check_petsc(int code, const char* what);

}  // namespace csrbf::mpi
