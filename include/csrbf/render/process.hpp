// Child processes of the renderer: the ffmpeg encoder and a private X server. Both run in their own
// process group, so a Ctrl-C at the terminal reaches csrbf alone, which then stops them in order.
#pragma once

#include "csrbf/errors.hpp"

#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace csrbf::render {

/// A child could not be started, failed, or the display could not be opened. The message says
/// which program and why (with the program's own error output where it wrote any).
class RenderError : public csrbf::Error {
 public:
  using csrbf::Error::Error;
};

/// A running program with a pipe to its standard input; standard output is discarded (or kept, with
/// capture_stdout) and standard error kept in an unnamed temporary file for messages. The program
/// dies with this process (PR_SET_PDEATHSIG), even when this process is killed with SIGKILL. The
/// destructor kills it if it is still running.
class Child {
 public:
  /// argv[0] is looked up in PATH. stdin_pipe: open a pipe to its standard input.
  Child(const std::vector<std::string>& argv, bool stdin_pipe, int extra_fd = -1, bool capture_stdout = false);
  ~Child();
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  /// Writes all bytes to its standard input; false if it has exited, or has not read anything for
  /// stall_seconds (then stalled() is true).
  /// stop: asked every 0.2 s while the child does not read; true abandons the write (false back).
  bool write(const void* data, std::size_t bytes, int stall_seconds = 120, const std::function<bool()>& stop = {});
  bool stalled() const noexcept { return stalled_; }
  /// Closes its standard input and waits; returns its exit status (128 + signal if killed). With
  /// timeout_seconds >= 0 (or when stop() turns true), a child still running then is killed and
  /// -1 returned.
  int finish(int timeout_seconds = -1, const std::function<bool()>& stop = {});
  /// Kills it (SIGTERM, then SIGKILL after a grace period) and waits.
  void kill();
  /// What it wrote to standard error so far (the last 2000 characters).
  std::string error_output() const;
  /// Its standard output (capture_stdout only).
  std::string output() const;
  int pid() const noexcept { return pid_; }

 private:
  int pid_ = -1;
  int stdin_fd_ = -1;
  int status_ = -1;
  int err_fd_ = -1, out_fd_ = -1;
  bool stalled_ = false;
};

/// Makes sure X is available for VTK's render windows (Debian's VTK 9.1 renders through X only).
/// With DISPLAY set to a display that opens, that display is used. Without one (or when it does not
/// open), a private Xvfb is started for the lifetime of this object (DISPLAY is set for this
/// process) and stopped afterwards.
class Display {
 public:
  /// force_private: start Xvfb even when DISPLAY is set.
  explicit Display(bool force_private = false);
  ~Display();
  Display(const Display&) = delete;
  Display& operator=(const Display&) = delete;
  bool is_private() const noexcept { return xvfb_ != nullptr; }
  /// The DISPLAY that was set but could not be opened (a private Xvfb was started instead), or "".
  const std::string& unreachable_display() const noexcept { return fallback_from_; }
  const std::string& name() const noexcept { return name_; }

 private:
  std::unique_ptr<Child> xvfb_;
  std::string name_, previous_, fallback_from_;
  bool had_previous_ = false;
};

}  // namespace csrbf::render
