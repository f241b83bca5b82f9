#include "csrbf/render/process.hpp"

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <fstream>
#include <poll.h>
#include <spawn.h>
#include <sstream>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

extern char** environ;

namespace csrbf::render {

namespace {
std::string errno_text() { return std::strerror(errno); }
}  // namespace

Child::Child(const std::vector<std::string>& argv, bool stdin_pipe, int extra_fd) {
  char tmpl[] = "/tmp/csrbf-child-XXXXXX";
  const int err_fd = mkstemp(tmpl);
  if (err_fd < 0) throw RenderError("cannot create a temporary file for " + argv[0] + "'s messages: " + errno_text());
  err_path_ = tmpl;
  int in[2] = {-1, -1};
  if (stdin_pipe && pipe2(in, O_CLOEXEC) != 0) {
    ::close(err_fd);
    throw RenderError("cannot create a pipe to " + argv[0] + ": " + errno_text());
  }
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  if (stdin_pipe) posix_spawn_file_actions_adddup2(&fa, in[0], 0);
  else posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, err_fd, 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  // Own process group: a terminal's Ctrl-C goes to csrbf, which stops its children itself.
  posix_spawnattr_setpgroup(&attr, 0);
  sigset_t def, none;
  sigemptyset(&def);
  sigaddset(&def, SIGINT);
  sigaddset(&def, SIGTERM);
  sigaddset(&def, SIGPIPE);
  sigemptyset(&none);
  posix_spawnattr_setsigdefault(&attr, &def);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  if (extra_fd >= 0) fcntl(extra_fd, F_SETFD, 0);  // inherited (e.g. Xvfb's -displayfd)
  const int rc = posix_spawnp(&pid_, argv[0].c_str(), &fa, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  ::close(err_fd);
  if (stdin_pipe) ::close(in[0]);
  if (rc != 0) {
    if (stdin_pipe) ::close(in[1]);
    std::filesystem::remove(err_path_);
    pid_ = -1;
    throw RenderError("cannot run '" + argv[0] + "': " + std::strerror(rc) +
                      (rc == ENOENT ? " (is it installed? scripts/install-deps.sh installs it)" : ""));
  }
  stdin_fd_ = stdin_pipe ? in[1] : -1;
}

Child::~Child() {
  if (pid_ > 0 && status_ < 0) kill();
  if (stdin_fd_ >= 0) ::close(stdin_fd_);
  std::error_code ec;
  std::filesystem::remove(err_path_, ec);
}

bool Child::write(const void* data, std::size_t bytes) {
  const char* p = static_cast<const char*>(data);
  while (bytes > 0) {
    const ssize_t n = ::write(stdin_fd_, p, bytes);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;  // EPIPE: the child has gone
    }
    p += n;
    bytes -= std::size_t(n);
  }
  return true;
}

int Child::finish() {
  if (stdin_fd_ >= 0) {
    ::close(stdin_fd_);
    stdin_fd_ = -1;
  }
  if (status_ >= 0) return status_;
  int st = 0;
  while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
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

std::string Child::error_output() const {
  std::ifstream in(err_path_);
  std::stringstream s;
  s << in.rdbuf();
  std::string t = s.str();
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
    name_ = d;
    return;
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
    if (left <= 0 || poll(&p, 1, int(left)) <= 0) break;
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
  if (had_previous_) setenv("DISPLAY", previous_.c_str(), 1);
  else unsetenv("DISPLAY");
}

}  // namespace csrbf::render
