// Writing outputs so that a failure never leaves a half-written file or clobbers an existing one:
// everything is written to a hidden partial beside the target and renamed over the target only
// once complete and verified. csrbf never removes or replaces anything it did not write:
// - a target may only be a new name or an existing regular file (never a folder, device, FIFO or
//   socket);
// - partials are named ".NAME.csrbf-partial-RANDOM[.ext]" and locked (flock) by the process that
//   writes them, and marked by an extended attribute (user.csrbf.partial) holding the random part of
//   their name; a partial left by a killed run (its lock released by the kernel) is removed by the
//   next csrbf write into that folder only when it carries that mark, never by its name alone.
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>
#include <string>

namespace csrbf::io {

/// Throws FileError when the target's folder does not exist or is not a folder, or when the target
/// exists and is not a regular file (a folder, a device, a FIFO or a socket is never replaced).
void check_output_path(const std::filesystem::path& target);

/// Calls write(stream) on a partial file beside target, checks the stream and that the file on
/// disk holds every byte written, then renames it to target (which keeps its permissions; a
/// symbolic link is followed, so the link stays and the file it names is replaced). On any failure
/// the partial is removed and target is untouched. before_commit, when given, runs between the check
/// and the rename (a second output renamed there leaves the two renames microseconds apart, so that
/// even SIGKILL can hardly part them); if it throws, nothing is renamed.
void write_atomically(const std::filesystem::path& target, const std::function<void(std::ostream&)>& write,
                      const std::function<void()>& before_commit = {});

/// Declares, at a command's start, that target (and, through a folder writer, any file named
/// target) must be created new: if it does not exist now, a later write_atomically or
/// write_atomically_via_folder never replaces it, even if another process made it meanwhile (of
/// concurrent writers of one new name exactly one succeeds; the others fail with "it exists"). Does
/// nothing when target exists now. Thread-safe.
void must_be_new(const std::filesystem::path& target);

/// Whether must_be_new registered target (it did not exist when the command started). Partial::commit
/// of such a target never replaces it.
bool registered_new(const std::filesystem::path& target);

/// For writers that need a path of their own (and may write side files, like glTF's .bin): calls
/// write(path) with path = a fresh partial folder / target's file name, then moves every file the
/// writer made there into target's folder (each must be new there or replace a regular file). On
/// failure nothing is moved and the folder is removed.
void write_atomically_via_folder(const std::filesystem::path& target,
                                 const std::function<void(const std::filesystem::path&)>& write);

/// A hidden, locked partial file or folder beside a target. The lock is held for the object's
/// lifetime; the destructor removes the partial unless it was committed. Not copyable.
class Partial {
 public:
  enum class Kind { File, Folder };
  /// Removes stale partials in target's folder, then creates a new one (ext appended to its name,
  /// e.g. ".mp4" so that a child program picks the format from it). Throws FileError.
  Partial(const std::filesystem::path& target, Kind kind, const std::string& ext = {});
  ~Partial();
  Partial(const Partial&) = delete;
  Partial& operator=(const Partial&) = delete;

  const std::filesystem::path& path() const noexcept { return path_; }
  /// Renames the partial file over target (which check_output_path accepted). Throws FileError.
  void commit(const std::filesystem::path& target);
  /// Renames the partial (a file or a folder) to target, which must not exist: nothing is ever
  /// replaced, not even an empty folder. Throws FileError.
  void commit_new(const std::filesystem::path& target);
  /// The partial is gone or has been moved by the caller: nothing to remove.
  /// (Also drops the partial's proof of ownership, so that the moved file or folder is the user's.)
  void release() noexcept;

 private:
  void disown() noexcept;
  std::filesystem::path path_;
  Kind kind_;
  int lock_fd_ = -1;
  int slot_ = -1;
  bool committed_ = false;
};

/// Installs handlers for SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGQUIT, SIGUSR1/2, SIGALRM, SIGVTALRM,
/// SIGPROF and SIGXCPU that remove this process's partial files and folders (with what is in them),
/// then die of the signal as before, and unblocks them in the calling thread (a launcher such as
/// mpirun may start processes with them blocked). (Partials of a process killed by SIGKILL are
/// removed by the next run into their folder.) From the moment the first output is moved into
/// place, the signals are ignored: the command finishes and reports what it wrote. For programs,
/// not libraries.
void remove_partials_on_signals() noexcept;

/// Removes this process's partial files and folders and makes every later commit of a partial fail ("cancelled
/// by a signal"): for a signal that announces the end (mpirun's SIGCONT) while the process goes on
/// for a moment. Async-signal-safe.
void cancel_writes() noexcept;

/// --time-limit: after seconds of wall time (from this call), SIGALRM removes this process's
/// partial files and folders, prints "csrbf: error: the time limit of S s (--time-limit) was reached; nothing
/// was written" (when speak) and exits 1, whatever the process is doing (a factorisation cannot be
/// asked to stop). Child processes die with it (they are started with PR_SET_PDEATHSIG). For
/// programs, not libraries; seconds in (0, 1e6].
void limit_time(double seconds, bool speak) noexcept;

/// How long csrbf waits on a pipe that makes no progress (a FIFO nobody writes to, a child that
/// stops reading) before failing: the environment variable CSRBF_PIPE_TIMEOUT (seconds, 1 to
/// 86400) or fallback.
int pipe_timeout_seconds(int fallback);

/// target, or the file a symbolic link target names (outputs replace the file, not the link).
std::filesystem::path resolve_output(const std::filesystem::path& target);
/// Gives onto the permission bits of from, if from exists.
void keep_mode(const std::filesystem::path& from, const std::filesystem::path& onto) noexcept;

/// Whether a file name is one of the numbered frames csrbf writes into a PNG folder
/// ("frame_00042.png").
bool is_frame_name(const std::string& name);

/// Removes partials in folder whose writer has died (their lock is free). Never touches anything
/// else. Called by every Partial; exposed for tests.
void remove_stale_partials(const std::filesystem::path& folder) noexcept;

}  // namespace csrbf::io
