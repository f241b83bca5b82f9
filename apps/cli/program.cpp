#include "program.hpp"

#include "commands/animate.hpp"
#include "commands.hpp"
#include "process_limits.hpp"
#include "standard_streams.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/names.hpp"

#include <unistd.h>

#include <cerrno>
#include <climits>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <new>
#include <sstream>

namespace csrbf::cli {

namespace {

/// OpenBLAS (under CHOLMOD) starts its threads as it is loaded, each taking a 128 MiB buffer:
/// under an address-space limit (ulimit -v) or a tight process limit they cannot, and spin or end
/// the process. Its thread count is read only at load, so the program runs again with it set.
/// libgomp (OpenMP, under CHOLMOD's supernodal factorisation) likewise ended the process with only
/// "Thread creation failed" under ulimit -v 300000.
void single_blas_thread_under_limits(char** argv) {
  if (!under_process_limits()) return;
  bool changed = false;
  for (const char* v : {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"})
    if (!std::getenv(v)) changed = ::setenv(v, "1", 1) == 0 || changed;
  if (changed) ::execv("/proc/self/exe", argv);  // on failure, go on as we are
}

}  // namespace

void start_program(char** argv) {
  hold_standard_streams();
  single_blas_thread_under_limits(argv);
  // A file size limit (ulimit -f, or a quota) must fail the write, so that the temporary file is
  // removed and the target kept, rather than kill the process with SIGXFSZ half-way.
  std::signal(SIGXFSZ, SIG_IGN);
  // A signal during a write removes the partial file instead of leaving it.
  io::remove_partials_on_signals();
}

void add_time_limit(CLI::App* cmd, double& seconds) {
  cmd->add_option("--time-limit", seconds,
                  "End with exit 1, writing nothing, if the command has not finished after this many seconds of "
                  "wall time (e.g. for a radius whose fit is too slow)")
      ->check(finite_in(1e-3, 1e6, "--time-limit"));
}

void openfoam_spellings(int argc, char** argv) {
  static char time_option[] = "--time", latest_time[] = "--time=latest";
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "-time") == 0) argv[i] = time_option;
    if (std::strcmp(argv[i], "-latestTime") == 0) argv[i] = latest_time;
  }
}

int parse_failed(CLI::App& app, const CLI::ParseError& e, bool quiet) {
  // CLI11 quotes the values it refuses: printed with their control characters escaped.
  std::ostringstream out, err;
  const int code = app.exit(e, out, err);
  if (!quiet) {
    std::cout << printable(out.str(), true);
    if (code == 0) {
      std::cerr << printable(err.str(), true);
    } else {
      // As every other error: "csrbf: error: ...", the option named once (CLI11 puts "--x: " before a
      // validator's own "--x must be ...").
      std::string what = e.what();
      const auto colon = what.find(": ");
      if (colon != std::string::npos && what.compare(colon + 2, colon, what, 0, colon) == 0) what.erase(0, colon + 2);
      std::cerr << "csrbf: error: " << printable(what, true) << "\nRun with --help for more information.\n";
    }
  }
  return code == 0 ? 0 : 2;
}

int run_command(const std::function<int()>& command) {
  try {
    return command();
  } catch (const UsageError& e) {
    std::cerr << "csrbf: error: " << printable(e.what()) << '\n';
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr
        << "csrbf: error: out of memory (a limit such as ulimit -v, or --memory-limit too high for this machine)\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "csrbf: error: " << printable(e.what()) << '\n';
    return 1;
  }
}

int run_sibling(const char* name, char** argv) {
  char self[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof self - 1);
  std::string program = name;
  if (n > 0) {
    self[n] = 0;
    program = (std::filesystem::path(self).parent_path() / name).string();
  }
  ::execv(program.c_str(), argv);
  std::cerr << "csrbf: error: cannot run " << program << ": " << std::strerror(errno)
            << " (csrbf is not installed whole: install it again)\n";
  return 1;
}

}  // namespace csrbf::cli
