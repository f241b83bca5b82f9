#include "csrbf/render/process.hpp"

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <fcntl.h>
#include <fstream>
#include <poll.h>
#include <sys/prctl.h>
#include <sstream>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

#include <X11/Xlib.h>

namespace csrbf::render {

namespace {
std::string errno_text() { return std::strerror(errno); }
}  // namespace

namespace {
/// A temporary file with no name: it is unlinked at once, so nothing is left behind whatever
/// happens to this process.
int anonymous_file(const std::string& program) {
  char tmpl[] = "/tmp/csrbf-child-XXXXXX";
  const int fd = mkostemp(tmpl, O_CLOEXEC);
  if (fd < 0) throw RenderError("cannot create a temporary file for " + program + "'s messages: " + errno_text());
  ::unlink(tmpl);
  return fd;
}

std::string read_all(int fd) {
  std::string t;
  if (fd < 0) return t;
  char buf[4096];
  off_t at = 0;
  for (;;) {
    const ssize_t n = ::pread(fd, buf, sizeof buf, at);
    if (n <= 0) break;
    t.append(buf, std::size_t(n));
    at += n;
  }
  return t;
}

/// argv[0] looked up in PATH (before fork: the child may only call async-signal-safe functions).
std::string find_program(const std::string& name) {
  if (name.find('/') != std::string::npos) return name;
  const char* env = std::getenv("PATH");
  const std::string path = env ? env : "/usr/local/bin:/usr/bin:/bin";
  std::size_t i = 0;
  while (i <= path.size()) {
    std::size_t j = path.find(':', i);
    if (j == std::string::npos) j = path.size();
    const std::string dir = j > i ? path.substr(i, j - i) : std::string(".");
    const std::string cand = dir + "/" + name;
    if (::access(cand.c_str(), X_OK) == 0) return cand;
    i = j + 1;
  }
  return {};
}
}  // namespace

Child::Child(const std::vector<std::string>& argv, bool stdin_pipe, int extra_fd, bool capture_stdout) {
  const std::string program = find_program(argv[0]);
  if (program.empty())
    throw RenderError("cannot run '" + argv[0] + "': " + std::strerror(ENOENT) +
                      " (is it installed? scripts/install-deps.sh installs it)");
  err_fd_ = anonymous_file(argv[0]);
  if (capture_stdout) out_fd_ = anonymous_file(argv[0]);
  int in[2] = {-1, -1}, report[2] = {-1, -1};
  if ((stdin_pipe && pipe2(in, O_CLOEXEC) != 0) || pipe2(report, O_CLOEXEC) != 0) {
    const std::string why = errno_text();
    for (int fd : {in[0], in[1], report[0], report[1]})
      if (fd >= 0) ::close(fd);
    throw RenderError("cannot create a pipe to " + argv[0] + ": " + why);
  }
  const int null_fd = ::open("/dev/null", O_RDWR | O_CLOEXEC);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t parent = ::getpid();
  const int death = argv[0] == "Xvfb" ? SIGTERM : SIGKILL;  // Xvfb removes its lock files on SIGTERM
  pid_ = ::fork();
  if (pid_ == 0) {
    // The child: async-signal-safe calls only, then exec.
    ::setpgid(0, 0);                   // own process group: a terminal's Ctrl-C reaches csrbf, which stops its children
    ::prctl(PR_SET_PDEATHSIG, death);  // dies with csrbf, even after kill -9 of csrbf
    if (::getppid() != parent) ::_exit(127);
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    for (int sig : {SIGINT, SIGTERM, SIGPIPE, SIGHUP, SIGXFSZ}) ::sigaction(sig, &dfl, nullptr);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::dup2(stdin_pipe ? in[0] : null_fd, 0);
    ::dup2(out_fd_ >= 0 ? out_fd_ : null_fd, 1);
    ::dup2(err_fd_, 2);
    if (extra_fd >= 0) ::fcntl(extra_fd, F_SETFD, 0);  // inherited (e.g. Xvfb's -displayfd)
    ::execv(program.c_str(), args.data());
    const int e = errno;
    [[maybe_unused]] const ssize_t w = ::write(report[1], &e, sizeof e);
    ::_exit(127);
  }
  const int fork_errno = errno;
  if (null_fd >= 0) ::close(null_fd);
  ::close(report[1]);
  if (stdin_pipe) ::close(in[0]);
  int exec_errno = 0;
  if (pid_ > 0) {
    ssize_t n;
    while ((n = ::read(report[0], &exec_errno, sizeof exec_errno)) < 0 && errno == EINTR) {
    }
    if (n != sizeof exec_errno) exec_errno = 0;
  }
  ::close(report[0]);
  if (pid_ < 0 || exec_errno != 0) {
    const int why = pid_ < 0 ? fork_errno : exec_errno;
    if (stdin_pipe) ::close(in[1]);
    if (pid_ > 0) {
      int st = 0;
      while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
      }
    }
    pid_ = -1;
    throw RenderError("cannot run '" + argv[0] + "': " + std::strerror(why));
  }
  if (stdin_pipe) {
    stdin_fd_ = in[1];
    ::fcntl(stdin_fd_, F_SETFL, ::fcntl(stdin_fd_, F_GETFL) | O_NONBLOCK);
  }
}

Child::~Child() {
  if (pid_ > 0 && status_ < 0) kill();
  if (stdin_fd_ >= 0) ::close(stdin_fd_);
  if (err_fd_ >= 0) ::close(err_fd_);
  if (out_fd_ >= 0) ::close(out_fd_);
}

bool Child::write(const void* data, std::size_t bytes, int stall_seconds, const std::function<bool()>& stop) {
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(stdin_fd_, p, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) {
        // A reader that stops reading but does not exit must not hang us, nor delay a Ctrl-C.
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(stall_seconds);
        int r = 0;
        while (r <= 0) {
          if (stop && stop()) return false;
          if (std::chrono::steady_clock::now() >= deadline) {
            stalled_ = true;
            return false;
          }
          pollfd q{stdin_fd_, POLLOUT, 0};
          r = poll(&q, 1, 200);
          if (r < 0 && errno != EINTR) return false;
        }
        continue;
      }
      return false;  // EPIPE: the child has gone
    }
    p += n;
    bytes -= std::size_t(n);
  }
  return true;
}

int Child::finish(int timeout_seconds, const std::function<bool()>& stop) {
  if (stdin_fd_ >= 0) {
    ::close(stdin_fd_);
    stdin_fd_ = -1;
  }
  if (status_ >= 0) return status_;
  int st = 0;
  if (timeout_seconds < 0 && !stop) {
    while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
    }
  } else {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(std::max(timeout_seconds, 0));
    for (;;) {
      const pid_t r = waitpid(pid_, &st, WNOHANG);
      if (r == pid_) break;
      if ((stop && stop()) || (timeout_seconds >= 0 && std::chrono::steady_clock::now() >= deadline)) {
        kill();
        return -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  status_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  return status_;
}

void Child::kill() {
  if (pid_ <= 0 || status_ >= 0) return;
  if (stdin_fd_ >= 0) {
    ::close(stdin_fd_);
    stdin_fd_ = -1;
  }
  ::kill(pid_, SIGTERM);
  int st = 0;
  for (int i = 0; i < 100; ++i) {  // up to 2 s
    const pid_t r = waitpid(pid_, &st, WNOHANG);
    if (r == pid_) {
      status_ = 128 + SIGTERM;
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(pid_, SIGKILL);
  waitpid(pid_, &st, 0);
  status_ = 128 + SIGKILL;
}

std::string Child::output() const { return read_all(out_fd_); }

std::string Child::error_output() const {
  std::string t = read_all(err_fd_);
  while (!t.empty() && (t.back() == '\n' || t.back() == ' ')) t.pop_back();
  if (t.size() > 2000) t = "..." + t.substr(t.size() - 2000);
  return t;
}

// ---------------------------------------------------------------------------------------------------

Display::Display(bool force_private) {
  const char* d = std::getenv("DISPLAY");
  had_previous_ = d != nullptr;
  if (d) previous_ = d;
  if (d && *d && !force_private) {
    // A DISPLAY that names no running server (a stale :77) would abort inside VTK: check it, and
    // render on a private Xvfb instead.
    if (::Display* x = XOpenDisplay(d)) {
      XCloseDisplay(x);
      name_ = d;
      return;
    }
    fallback_from_ = d;
  }
  // Xvfb picks a free display number and writes it to the descriptor given by -displayfd.
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) throw RenderError("cannot create a pipe for Xvfb: " + errno_text());
  try {
    xvfb_ = std::make_unique<Child>(std::vector<std::string>{"Xvfb", "-displayfd", std::to_string(fds[1]), "-screen",
                                                             "0", "1920x1080x24", "-nolisten", "tcp", "-noreset"},
                                    false, fds[1]);
  } catch (const RenderError& e) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw RenderError(std::string("no display: DISPLAY is not set and a private X server could not be started: ") +
                      e.what());
  }
  ::close(fds[1]);
  std::string number;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (number.find('\n') == std::string::npos) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    pollfd p{fds[0], POLLIN, 0};
    if (left <= 0) break;
    const int r = poll(&p, 1, int(left));
    if (r < 0 && errno == EINTR) continue;  // a Ctrl-C now is seen by the caller once Xvfb is up
    if (r <= 0) break;
    char buf[32];
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n <= 0) break;
    number.append(buf, std::size_t(n));
  }
  ::close(fds[0]);
  if (number.find('\n') == std::string::npos) {
    const std::string err = xvfb_->error_output();
    xvfb_->kill();
    throw RenderError("no display: DISPLAY is not set and the private Xvfb did not start" +
                      (err.empty() ? std::string() : ": " + err));
  }
  number.erase(number.find('\n'));
  name_ = ":" + number;
  setenv("DISPLAY", name_.c_str(), 1);
}

Display::~Display() {
  if (!xvfb_) return;
  xvfb_->kill();
  if (had_previous_)
    setenv("DISPLAY", previous_.c_str(), 1);
  else
    unsetenv("DISPLAY");
}

}  // namespace csrbf::render
