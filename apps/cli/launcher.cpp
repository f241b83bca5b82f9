// `csrbf`: the command users run. It answers --version itself and runs the program that does the
// work: csrbf-cli, or under mpirun with more than one rank csrbf-cli-mpi, the same program built
// with MPI and PETSc; `csrbf morph` on one process runs csrbf-morph (morph_main.cpp). Those two
// libraries cost every command about 0.1 s to load (measured: 70-106 ms to dlopen them, of a 0.14 s
// start-up), so only a distributed run loads them. `csrbf bench` runs csrbf-bench (bench_main.cpp;
// under mpirun csrbf-cli-mpi refuses it). The programs live in LIBEXEC/csrbf beside BIN
// (build/libexec/csrbf in the build tree), found from this program's own path; the same argv goes over, argv[0]
// included, so every message and --help names `csrbf`.
#include "csrbf/version.hpp"
#include "process_limits.hpp"
#include "standard_streams.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

/// The ranks mpirun (Open MPI, MPICH, PMIx) started, from the environment it sets; 0 outside it.
int launched_ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE", "MPI_LOCALNRANKS"}) {
    const char* v = std::getenv(name);
    if (!v || !*v) continue;
    char* end = nullptr;
    const long n = std::strtol(v, &end, 10);
    if (end != v && *end == 0 && n > 0 && n < INT_MAX) return int(n);
  }
  return 0;
}

/// OpenBLAS (under CHOLMOD) starts its threads as it is loaded, each taking a 128 MiB buffer, and
/// libgomp likewise: under an address-space limit (ulimit -v) or a tight process limit they cannot,
/// and spin or end the process. Both read their thread counts only at load, so they are set here,
/// before the program that loads them starts.
void single_threads_under_limits() {
  if (!csrbf::cli::under_process_limits()) return;
  for (const char* v : {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"})
    if (!std::getenv(v)) ::setenv(v, "1", 1);
}

/// Large buffers on 2 MiB pages (transparent huge pages, where the kernel grants them on madvise):
/// glibc's malloc asks for them with this tunable, read only at the program's start. A 4e5-point
/// morph (pitzDaily x 4) spent a quarter of its time in page faults on 4 KiB pages, and took 1.02 s
/// against 0.50 s with it (docs/PERFORMANCE.md). A morph also grows its heap 64 MiB ahead and keeps
/// blocks below 32 MiB in it, so that the buffers it frees (the files' text once parsed) are used
/// again without new page faults: airFoil2D's morph 0.047 s -> 0.037 s, 3000 -> 700 page faults,
/// for 4 MiB more resident (20 MiB on pitzDaily x 4). Not under an address-space limit: there the
/// padding could not be reserved while the libraries load, and libgfortran's start-up then
/// recursed until the stack overflowed (ulimit -v 100000: exit 139). A tunable the caller set is
/// kept.
void large_pages(bool morph) {
  const char* had = std::getenv("GLIBC_TUNABLES");
  std::string v = had ? had : "";
  const auto add = [&](const char* name, const char* value) {
    if (v.find(name) != std::string::npos) return;
    // By appends: GCC 12 warns falsely on '"x" + string' (-Wrestrict, PR 105329).
    if (!v.empty()) v += ':';
    v += name;
    v += '=';
    v += value;
  };
  add("glibc.malloc.hugetlb", "1");
  if (morph) {
    add("glibc.malloc.top_pad", "67108864");
    add("glibc.malloc.mmap_threshold", "33554432");
  }
  ::setenv("GLIBC_TUNABLES", v.c_str(), 1);
}

}  // namespace

int main(int argc, char** argv) {
  csrbf::cli::hold_standard_streams();
  if (argc == 2 && std::strcmp(argv[1], "--version") == 0) {
    std::printf("csrbf %s\n", csrbf::kVersion);
    return std::fflush(stdout) == 0 && !std::ferror(stdout) ? 0 : 1;
  }
  char self[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof self - 1);
  if (n <= 0) {
    std::fprintf(stderr, "csrbf: error: cannot find this program's own path (/proc/self/exe): %s\n",
                 std::strerror(errno));
    return 1;
  }
  self[n] = 0;
  std::string dir(self);
  dir.erase(dir.find_last_of('/') + 1);
  const std::string libexec = dir + CSRBF_LIBEXEC_FROM_BIN + "/";
  std::string program = libexec + "csrbf-cli";
  if (launched_ranks() > 1 && ::access((libexec + "csrbf-cli-mpi").c_str(), X_OK) == 0)
    program = libexec + "csrbf-cli-mpi";
  else if (argc > 1 && std::strcmp(argv[1], "morph") == 0)
    program = libexec + "csrbf-morph";  // OpenFOAM cases; it runs csrbf-cli for the other formats
  else if (argc > 1 && std::strcmp(argv[1], "bench") == 0)
    program = libexec + "csrbf-bench";
  single_threads_under_limits();
  large_pages(argc > 1 && std::strcmp(argv[1], "morph") == 0 && !csrbf::cli::under_process_limits());
  ::execv(program.c_str(), argv);
  std::fprintf(stderr, "csrbf: error: cannot run %s: %s (csrbf is not installed whole: install it again)\n",
               program.c_str(), std::strerror(errno));
  return 1;
}
