#include "child_reader.hpp"

#include "csrbf/io/error.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/units.hpp"

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <new>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace csrbf::morph::detail {

namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;  // AddressSanitizer reserves terabytes of shadow: no RLIMIT_AS
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

void write_all(int fd, const std::string& s) {
  for (std::size_t done = 0; done < s.size();) {
    const ssize_t n = ::write(fd, s.data() + done, s.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) ::_exit(4);
    done += std::size_t(n);
  }
}

}  // namespace

std::string read_in_child(const std::filesystem::path& file, const std::string& library, double memory_limit_bytes,
                          const std::function<std::string()>& work) {
  using io::FileError;
  const std::string name = file.string();
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw FileError(name + ": cannot start " + library + "'s reader: " + std::strerror(errno));
  std::fflush(nullptr);
  // At least 1 GiB of address space beyond the parent's: a library the child loads (Gmsh's, with
  // OpenCASCADE) maps hundreds of MB of code, and under a small --memory-limit the loader's "failed
  // to map segment" hid the limit. The back-stop is for runaway allocations; the readers' own checks
  // of stated counts against the file's size bound what a file may ask for.
  const double as_limit = io::address_space_bytes() + std::max(memory_limit_bytes, kGiB);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int e = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw FileError(name + ": cannot start " + library + "'s reader: " + std::strerror(e));
  }
  if (pid == 0) {
    ::close(fds[0]);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(5);  // the parent died before prctl
    // The parent's handlers remove its partial files: not the child's business.
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGPROF, SIGXCPU})
      ::signal(sig, SIG_DFL);
    // What the library or the C library prints as it fails ("malloc(): invalid size") is not for
    // the user: the parent reports the failure, naming the file.
    if (const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC); null >= 0) ::dup2(null, 2);
    if (!kSanitized && as_limit > 0 && as_limit < 1.8e19) {
      rlimit r{};
      if (::getrlimit(RLIMIT_AS, &r) == 0 && (r.rlim_cur == RLIM_INFINITY || double(r.rlim_cur) > as_limit)) {
        r.rlim_cur = rlim_t(as_limit);
        ::setrlimit(RLIMIT_AS, &r);
      }
    }
    std::string out;
    int status = 0;
    try {
      out = "M";  // by appends: GCC 12 warns falsely on '"M" + string' (-Wrestrict, PR 105329)
      out += work();
    } catch (const std::bad_alloc&) {
      out = "Enot enough memory within the memory limit (a count in the file that lies?)";
      status = 3;
    } catch (const std::exception& e) {
      out = "E";
      out += e.what();
      status = 3;
    } catch (...) {
      out = "E";
      out += library + " threw an unknown exception";
      status = 3;
    }
    write_all(fds[1], out);
    ::_exit(status);
  }
  ::close(fds[1]);
  std::string in;
  char buf[1 << 16];
  bool too_big = false;
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    if (double(in.size()) + double(n) > 4 * memory_limit_bytes + 4096) {
      too_big = true;
      ::kill(pid, SIGKILL);
      break;
    }
    in.append(buf, std::size_t(n));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (too_big) throw FileError(name + ": the mesh passes the memory limit");
  if (WIFSIGNALED(status))
    throw FileError(name + ": " + library + "'s reader crashed on it (signal " + std::to_string(WTERMSIG(status)) +
                    ", " + ::strsignal(WTERMSIG(status)) + "): the file is corrupt, truncated or hostile");
  if (!in.empty() && in[0] == 'E') throw FileError(name + ": " + library + " cannot read it: " + in.substr(1));
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || in.empty() || in[0] != 'M')
    throw FileError(name + ": " + library + "'s reader failed (exit status " + std::to_string(WEXITSTATUS(status)) +
                    ")");
  in.erase(0, 1);
  return in;
}

}  // namespace csrbf::morph::detail
