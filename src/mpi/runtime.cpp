#include "csrbf/mpi/runtime.hpp"

#include "csrbf/io/atomic_file.hpp"

#include <petscsys.h>
#include <csignal>
#include <unistd.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <cstdlib>
#include <string>
#include <vector>

namespace csrbf::mpi {

namespace {

/// PETSc's errors come back to csrbf as codes, which check_petsc throws, instead of its default
/// handler printing a trace on each rank.
PetscErrorCode quiet_handler(MPI_Comm, int, const char*, const char*, PetscErrorCode n, PetscErrorType, const char*,
                             void*) {
  return n;
}

int env_int(const char* name) {
  const char* v = std::getenv(name);
  if (!v || !*v) return 0;
  char* end = nullptr;
  const long n = std::strtol(v, &end, 10);
  return (end && *end == 0 && n > 0 && n < (1 << 24)) ? int(n) : 0;
}

/// mpirun answers a SIGTERM or SIGINT by sending its ranks SIGCONT at once, and SIGTERM only a
/// second later: time enough for a rank to finish and write its output. A SIGCONT from the
/// launcher (this process's parent) therefore announces the end: the partial files go at once and
/// no output may be committed any more. (A rank that ended itself now would have its launcher kill
/// the others at once, before the one writing had removed its partial.)
extern "C" void launcher_stops_us(int, siginfo_t* info, void*) {
  if (info && info->si_pid == ::getppid()) io::cancel_writes();
}

void end_on_launchers_sigcont() {
  struct sigaction sa {};
  sa.sa_sigaction = launcher_stops_us;
  sa.sa_flags = SA_SIGINFO | SA_RESTART;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGCONT, &sa, nullptr);
}

/// A rank whose launcher (mpirun, or its daemon) is gone would go on alone and write its output:
/// it ends itself as if it had been sent SIGTERM (partials removed, nothing written).
void watch_parent() {
  const pid_t parent = ::getppid();
  std::thread([parent] {
    while (::getppid() == parent) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    ::kill(::getpid(), SIGTERM);
  }).detach();
}

}  // namespace

int launched_ranks() noexcept {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE", "MPI_LOCALNRANKS"})
    if (const int n = env_int(name)) return n;
  return 0;
}

int launched_rank() noexcept {
  for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"}) {
    const char* v = std::getenv(name);
    if (v && *v) return env_int(name);
  }
  return 0;
}

Runtime::Runtime(int* argc, char*** argv) {
  // A rank draws nothing: Open MPI's hwloc must not open the X display (its GL component probes
  // it), as Xlib ends the process when that server closes later (a GUI test's Xvfb did so).
  const char* components = std::getenv("HWLOC_COMPONENTS");
  if (!components || !*components)
    ::setenv("HWLOC_COMPONENTS", "-gl", 1);
  else if (std::string(components).find("gl") == std::string::npos)
    ::setenv("HWLOC_COMPONENTS", (std::string(components) + ",-gl").c_str(), 1);
  ::unsetenv("DISPLAY");
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  // PETSc reads no options from the command line (csrbf's own are not PETSc's), nor from files.
  int zero = 0;
  char** none = nullptr;
  if (PetscInitialize(&zero, &none, nullptr, nullptr) != 0) {
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  PetscPushErrorHandler(quiet_handler, nullptr);
  // PETSc and Open MPI install signal handlers of their own: a SIGTERM or SIGINT from mpirun (a
  // Ctrl-C) must end the rank as it ends csrbf alone, its partial files removed and nothing
  // written.
  PetscPopSignalHandler();
  io::remove_partials_on_signals();
  end_on_launchers_sigcont();
  watch_parent();
}

Runtime::~Runtime() {
  PetscFinalize();
  MPI_Finalize();
}

void agree(MPI_Comm comm, std::exception_ptr local, int (*exit_code)(const std::exception_ptr&)) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  int failed_rank = local ? rank : size;
  int first = size;
  MPI_Allreduce(&failed_rank, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == size) return;
  // The lowest failing rank tells everyone its message and exit code.
  std::string message;
  int code = 1;
  if (rank == first) {
    try {
      std::rethrow_exception(local);
    } catch (const Failure& f) {
      message = f.what();
      code = f.exit_code();
    } catch (const std::exception& e) {
      message = e.what();
      code = exit_code ? exit_code(local) : 1;
    } catch (...) {
      message = "an unknown error";
      code = exit_code ? exit_code(local) : 1;
    }
  }
  long long length = static_cast<long long>(message.size());
  MPI_Bcast(&length, 1, MPI_LONG_LONG, first, comm);
  MPI_Bcast(&code, 1, MPI_INT, first, comm);
  message.resize(std::size_t(std::clamp<long long>(length, 0, 1 << 20)));
  if (!message.empty()) MPI_Bcast(message.data(), int(message.size()), MPI_CHAR, first, comm);
  throw Failure(message, first, code);
}

std::size_t peak_memory_bytes() noexcept {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return std::size_t(u.ru_maxrss) * 1024;
}

void check_petsc(int code, const char* what) {
  if (code == 0) return;
  const char* text = nullptr;
  PetscErrorMessage(code, &text, nullptr);
  throw csrbf::Error(std::string("PETSc: ") + what + " failed (error " + std::to_string(code) +
                     (text ? std::string(": ") + text : std::string()) + ")");
}

}  // namespace csrbf::mpi
