#include "csrbf/io/atomic_file.hpp"

#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <dirent.h>
#include <fcntl.h>
#include <fstream>
#include <poll.h>
#include <pthread.h>
#include <mutex>
#include <random>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/xattr.h>
#include <system_error>
#include <unistd.h>
#include <vector>

namespace fs = std::filesystem;

namespace csrbf::io {

namespace {

constexpr const char* kMarker = ".csrbf-partial-";
// The proof that a partial is csrbf's: an extended attribute holding the random part of its name,
// set on the file or folder right after its exclusive creation. A stale partial is removed only
// with that proof, never by its name alone (a user's folder may be named like one).
constexpr const char* kOwnerAttr = "user.csrbf.partial";

std::string unique_suffix() {
  static thread_local std::mt19937_64 rng([] {
    std::random_device rd;
    return (std::uint64_t(rd()) << 32) ^ rd() ^ std::uint64_t(std::time(nullptr));
  }());
  char buf[32];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

fs::path folder_of(const fs::path& target) { return target.has_parent_path() ? target.parent_path() : fs::path("."); }

std::string errno_text() { return std::strerror(errno); }

/// ".NAME.csrbf-partial-RANDOM.ext", NAME cut so that the whole stays within 255 bytes.
std::string partial_name(const fs::path& target, const std::string& ext, std::string& token) {
  token = unique_suffix();
  std::string base = target.filename().string();
  if (base.size() > 180) base.resize(180);
  std::string s(".");  // built by appends: GCC 12 warns falsely on '"." + string' (-Wrestrict, PR 105329)
  s += base;
  s += kMarker;
  s += token;
  s += ext.size() <= 16 ? ext : ext.substr(0, 16);
  return s;
}

/// The random part of a partial's name (16 hex digits after the marker), or empty.
std::string token_in_name(const std::string& name) {
  const auto at = name.rfind(kMarker);
  if (at == std::string::npos || name.size() < at + std::strlen(kMarker) + 16) return {};
  std::string t = name.substr(at + std::strlen(kMarker), 16);
  for (char c : t)
    if (!std::isxdigit(static_cast<unsigned char>(c))) return {};
  return t;
}

/// Whether the open file or folder fd carries csrbf's proof of ownership for this token.
bool owned(int fd, const std::string& token) {
  char buf[64];
  const ssize_t n = ::fgetxattr(fd, kOwnerAttr, buf, sizeof buf);
  return !token.empty() && n == ssize_t(token.size()) && std::memcmp(buf, token.data(), token.size()) == 0;
}

/// Removes a partial folder and everything csrbf wrote into it (a copied case holds folders and
/// symbolic links too; links are removed, never followed).
void remove_partial_folder(const fs::path& dir) noexcept {
  std::error_code ec;
  fs::remove_all(dir, ec);
}

/// Partial files and folders of this process, for a signal handler to remove (fixed storage: a
/// handler may not allocate). A slot is 0 (free), kPending (its partial is being created: the
/// handler waits for the outcome), kFileSlot or kFolderSlot (created by this process).
constexpr int kSlots = 32;
constexpr int kFileSlot = 1, kPending = 2, kFolderSlot = 3;
char g_partials[kSlots][4096];
std::atomic<int> g_used[kSlots];

/// A slot for a partial about to be created at p (kPending): the creating thread blocks signals, but
/// a signal sent to the process runs its handler on another thread, which must not find the new file
/// unregistered (Hostile.SignalsLeaveNothing left one, 1 run in a few, under load).
int reserve_partial(const fs::path& p) noexcept {
  const std::string& s = p.native();
  if (s.size() >= sizeof g_partials[0]) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = 0;
    if (g_used[i].compare_exchange_strong(expected, kPending)) {
      std::memcpy(g_partials[i], s.c_str(), s.size() + 1);
      return i;
    }
  }
  return -1;
}
/// The partial of a reserved slot exists and is this process's.
void confirm_partial(int slot, bool folder) noexcept {
  if (slot >= 0) g_used[slot].store(folder ? kFolderSlot : kFileSlot);
}
void unregister_partial(int slot) noexcept {
  if (slot >= 0) g_used[slot].store(0);
}

std::atomic<bool> g_cancelled{false};

/// Removes `name` in the folder parent_fd and, for a folder, everything in it, with system calls
/// that a signal handler may make (no allocation, no std::filesystem): links are removed, never
/// followed; 16 levels at most (csrbf's partial folders hold a copied case, 4 levels deep). Another
/// thread may still be writing into the folder: it is read again until it can be removed, 4 times
/// at most.
void remove_tree_at(int parent_fd, const char* name, int depth) noexcept {
  if (::unlinkat(parent_fd, name, 0) == 0 || (errno != EISDIR && errno != EPERM) || depth >= 16) return;
  const int fd = ::openat(parent_fd, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return;
  alignas(8) char buf[2048];
  for (int pass = 0; pass < 4; ++pass) {
    for (ssize_t n; (n = ::getdents64(fd, buf, sizeof buf)) > 0;)
      for (ssize_t off = 0; off < n;) {
        const auto* d = reinterpret_cast<const struct dirent64*>(buf + off);
        off += d->d_reclen;
        if (std::strcmp(d->d_name, ".") != 0 && std::strcmp(d->d_name, "..") != 0)
          remove_tree_at(fd, d->d_name, depth + 1);
      }
    if (::unlinkat(parent_fd, name, AT_REMOVEDIR) == 0 || errno != ENOTEMPTY) break;
    ::lseek(fd, 0, SEEK_SET);
  }
  ::close(fd);
}

void unlink_partials() noexcept {
  for (int i = 0; i < kSlots; ++i) {
    // A partial being created on another thread (which blocks signals there) is settled within
    // microseconds, or as long as its mkdir takes (a slow file system; the attacker delayed it by
    // 3 s and the folder stayed, unmarked): waited for up to 10 s (clock_gettime is
    // async-signal-safe).
    int kind = g_used[i].load();
    timespec start{}, now{};
    ::clock_gettime(CLOCK_MONOTONIC, &start);
    while (kind == kPending) {
      ::clock_gettime(CLOCK_MONOTONIC, &now);
      if (now.tv_sec - start.tv_sec > 10) break;
      kind = g_used[i].load();
    }
    if (kind == kFileSlot)
      ::unlink(g_partials[i]);
    else if (kind == kFolderSlot)
      remove_tree_at(AT_FDCWD, g_partials[i], 0);
  }
}

/// Set as the first output is moved into place: from then on a signal no longer ends the command,
/// which finishes and reports what it wrote (ended by the signal just after a rename, it died with
/// 128 + the signal over a complete output: found by the attacker's trial, 4 runs in 60).
std::atomic<bool> g_finishing{false};

extern "C" void remove_partials_and_die(int sig) {
  if (g_finishing.load()) return;
  unlink_partials();
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

void check_not_cancelled(const fs::path& target) {
  if (g_cancelled.load())
    throw FileError("cannot write '" + target.string() + "': the run was cancelled by a signal (nothing written)");
}

}  // namespace

int pipe_timeout_seconds(int fallback) {
  if (const char* e = std::getenv("CSRBF_PIPE_TIMEOUT")) {
    const int v = std::atoi(e);
    if (v >= 1 && v <= 86400) return v;
  }
  return fallback;
}

void cancel_writes() noexcept {
  g_cancelled.store(true);
  unlink_partials();
}

namespace {
char g_time_message[160];
std::size_t g_time_message_size = 0;
extern "C" void time_is_up(int) {
  if (g_finishing.load()) return;  // an output is being moved into place: the command is done
  unlink_partials();
  if (g_time_message_size) {
    const ssize_t written = ::write(2, g_time_message, g_time_message_size);
    (void)written;  // nothing more can be done about a closed stderr
  }
  ::_exit(1);
}

/// From the first output's rename on, neither --time-limit nor a signal ends the command: an alarm
/// then would report "nothing was written" over a written (or replaced) file.
void time_limit_off() noexcept {
  g_finishing.store(true);
  itimerval off{};
  ::setitimer(ITIMER_REAL, &off, nullptr);
}
}  // namespace

void limit_time(double seconds, bool speak) noexcept {
  if (!(seconds > 0) || seconds > 1e6) return;
  const int n =
      std::snprintf(g_time_message, sizeof g_time_message,
                    "csrbf: error: the time limit of %g s (--time-limit) was reached; nothing was written\n", seconds);
  g_time_message_size = speak && n > 0 ? std::min(std::size_t(n), sizeof g_time_message - 1) : 0;
  struct sigaction sa {};
  sa.sa_handler = time_is_up;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGALRM, &sa, nullptr);
  sigset_t alarm;
  sigemptyset(&alarm);
  sigaddset(&alarm, SIGALRM);
  ::pthread_sigmask(SIG_UNBLOCK, &alarm, nullptr);
  itimerval t{};
  t.it_value.tv_sec = time_t(seconds);
  t.it_value.tv_usec = suseconds_t((seconds - double(time_t(seconds))) * 1e6);
  if (t.it_value.tv_sec == 0 && t.it_value.tv_usec == 0) t.it_value.tv_usec = 1;
  ::setitimer(ITIMER_REAL, &t, nullptr);
}

void remove_partials_on_signals() noexcept {
  struct sigaction sa {};
  sa.sa_handler = remove_partials_and_die;
  sigemptyset(&sa.sa_mask);
  sigset_t handled;
  sigemptyset(&handled);
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGPIPE, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGPROF, SIGXCPU}) {
    ::sigaction(sig, &sa, nullptr);
    sigaddset(&handled, sig);
  }
  // A mask is inherited: mpirun starts its ranks from a thread that blocks these signals, so a
  // rank never saw mpirun's SIGTERM and wrote its output after mpirun had gone. Threads started
  // after this call inherit the unblocked mask.
  ::pthread_sigmask(SIG_UNBLOCK, &handled, nullptr);
}

bool is_frame_name(const std::string& name) {
  // frame_ + 5 or more digits + .png
  if (name.size() < 15 || name.compare(0, 6, "frame_") != 0 || name.compare(name.size() - 4, 4, ".png") != 0)
    return false;
  for (std::size_t i = 6; i + 4 < name.size(); ++i)
    if (name[i] < '0' || name[i] > '9') return false;
  return true;
}

void remove_stale_partials(const fs::path& folder) noexcept {
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.empty() || name[0] != '.' || name.find(kMarker) == std::string::npos) continue;
    struct stat st {};
    if (::lstat(it->path().c_str(), &st) != 0) continue;
    const bool dir = S_ISDIR(st.st_mode);
    if (!dir && !S_ISREG(st.st_mode)) continue;
    // Between its creation and its lock a live partial is unlocked for a few microseconds: leave
    // anything younger than 2 s.
    if (std::time(nullptr) - st.st_ctime < 2) continue;
    const int fd = ::open(it->path().c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | (dir ? O_DIRECTORY : 0));
    if (fd < 0) continue;
    if (owned(fd, token_in_name(name)) && ::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      if (dir)
        remove_partial_folder(it->path());
      else
        ::unlink(it->path().c_str());
    }
    ::close(fd);
  }
}

Partial::Partial(const fs::path& target, Kind kind, const std::string& ext) : kind_(kind) {
  const fs::path dir = folder_of(target);
  remove_stale_partials(dir);
  // No signal between the partial's creation and its registration for the signal handler.
  sigset_t all, old;
  sigfillset(&all);
  pthread_sigmask(SIG_BLOCK, &all, &old);
  std::string token;
  for (int attempt = 0; attempt < 8; ++attempt) {
    path_ = dir / partial_name(target, ext, token);
    slot_ = reserve_partial(path_);
    if (kind == Kind::File) {
      lock_fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    } else if (::mkdir(path_.c_str(), 0777) == 0) {
      lock_fd_ = ::open(path_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
      if (lock_fd_ < 0) ::rmdir(path_.c_str());
    }
    if (lock_fd_ >= 0) break;
    const int e = errno;
    unregister_partial(slot_);  // not ours (EEXIST: someone's file by that name), or not made
    slot_ = -1;
    errno = e;
    if (errno != EEXIST) break;
  }
  const int open_errno = errno;
  if (lock_fd_ >= 0) {
    confirm_partial(slot_, kind == Kind::Folder);
    ::flock(lock_fd_, LOCK_EX | LOCK_NB);
    // Without the attribute (a file system without user xattrs) a partial left by a killed run is
    // not removed by later runs: better left than a user's file removed by its name.
    ::fsetxattr(lock_fd_, kOwnerAttr, token.data(), token.size(), 0);
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  errno = open_errno;
  if (lock_fd_ < 0)
    throw FileError("cannot write '" + target.string() + "': cannot create a " +
                    (kind == Kind::File ? "file" : "folder") + " in '" + dir.string() + "': " + errno_text());
}

Partial::~Partial() {
  // Removed, then unregistered: a signal in between finds the name gone, harmlessly.
  if (!committed_) {
    if (kind_ == Kind::File)
      ::unlink(path_.c_str());
    else
      remove_partial_folder(path_);
  }
  unregister_partial(slot_);
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

void keep_mode(const fs::path& from, const fs::path& onto) noexcept {
  struct stat st {};
  if (::stat(from.c_str(), &st) == 0) ::chmod(onto.c_str(), st.st_mode & 07777);
}

fs::path resolve_output(const fs::path& target) {
  // A symbolic link to a file is followed, so that the link stays and its file gets the output.
  std::error_code ec;
  if (fs::is_symlink(fs::symlink_status(target, ec))) {
    const fs::path real = fs::canonical(target, ec);
    if (ec)
      throw FileError("cannot write '" + target.string() + "': it is a symbolic link to nothing (" + ec.message() +
                      ")");
    return real;
  }
  return target;
}

void Partial::disown() noexcept {
  if (lock_fd_ >= 0) ::fremovexattr(lock_fd_, kOwnerAttr);
}

void Partial::release() noexcept {
  unregister_partial(slot_);
  slot_ = -1;
  disown();
  committed_ = true;
}

void Partial::commit(const fs::path& target) {
  // A target that was new when the command started is never replaced, whoever made it since.
  if (registered_new(target)) return commit_new(target);
  check_not_cancelled(target);
  check_output_path(target);  // again: the target may have changed while we wrote
  keep_mode(target, path_);   // a replaced file keeps its permissions
  disown();
  time_limit_off();
  std::error_code ec;
  fs::rename(path_, target, ec);
  if (ec) throw FileError("cannot write '" + target.string() + "': " + ec.message());
  // Only now: a signal handler that runs in between unlinks a name that is gone, harmlessly.
  unregister_partial(slot_);
  slot_ = -1;
  committed_ = true;
}

void Partial::commit_new(const fs::path& target) {
  // RENAME_NOREPLACE: an existing target, even an empty folder that rename(2) would replace, is
  // never replaced.
  check_not_cancelled(target);
  disown();
  time_limit_off();
  if (::renameat2(AT_FDCWD, path_.c_str(), AT_FDCWD, target.c_str(), RENAME_NOREPLACE) != 0)
    throw FileError(
        "cannot write '" + target.string() + "': " +
        (errno == EEXIST ? std::string("it exists (csrbf writes a new one, and never replaces it)") : errno_text()));
  unregister_partial(slot_);
  slot_ = -1;
  committed_ = true;
}

void check_output_path(const fs::path& target) {
  if (target.empty()) throw FileError("output path is empty");
  const fs::path dir = folder_of(target);
  std::error_code ec;
  if (!fs::exists(dir, ec))
    throw FileError("cannot write '" + target.string() + "': folder '" + dir.string() + "' does not exist");
  if (!fs::is_directory(dir, ec))
    throw FileError("cannot write '" + target.string() + "': '" + dir.string() + "' is not a folder");
  const auto st = fs::status(target, ec);
  switch (st.type()) {
    case fs::file_type::not_found:
    case fs::file_type::regular:
      return;
    case fs::file_type::directory:
      throw FileError("cannot write '" + target.string() + "': it is a folder");
    default:
      throw FileError("cannot write '" + target.string() +
                      "': it exists and is not a regular file (a device, FIFO or socket is never replaced)");
  }
}

namespace {
bool exists_no_follow(const fs::path& p) {
  std::error_code ec;
  return fs::symlink_status(p, ec).type() != fs::file_type::not_found;
}

std::mutex g_new_mutex;
std::vector<fs::path> g_new_outputs;  // must_be_new(): absolute, lexically normal

fs::path normal(const fs::path& p) {
  std::error_code ec;
  const fs::path a = fs::absolute(p, ec);
  return (ec ? p : a).lexically_normal();
}

/// The names in folder that must_be_new registered.
std::vector<fs::path> registered_new_in(const fs::path& folder) {
  const fs::path f = normal(folder / "x").parent_path();
  std::vector<fs::path> names;
  std::lock_guard lock(g_new_mutex);
  for (const auto& p : g_new_outputs)
    if (p.parent_path() == f) names.push_back(p.filename());
  return names;
}
}  // namespace

bool registered_new(const fs::path& target) {
  const fs::path t = normal(target);
  std::lock_guard lock(g_new_mutex);
  return std::find(g_new_outputs.begin(), g_new_outputs.end(), t) != g_new_outputs.end();
}

void must_be_new(const fs::path& target) {
  if (exists_no_follow(target)) return;
  std::lock_guard lock(g_new_mutex);
  g_new_outputs.push_back(normal(target));
}

void write_atomically(const fs::path& target_in, const std::function<void(std::ostream&)>& write,
                      const std::function<void()>& before_commit) {
  const fs::path target = resolve_output(target_in);
  check_output_path(target);
  const bool existed = exists_no_follow(target) && !registered_new(target);
  Partial partial(target, Partial::Kind::File);
  std::streamoff written = 0;
  {
    std::ofstream out(partial.path(), std::ios::binary | std::ios::trunc);
    if (!out)
      throw FileError("cannot write '" + target.string() + "': cannot open a file in '" + folder_of(target).string() +
                      "'");
    write(out);
    out.flush();
    written = out ? std::streamoff(out.tellp()) : -1;
    out.close();
    if (!out || written < 0)
      throw FileError("cannot write '" + target.string() + "': write failed (disk full or file size limit?)");
  }
  std::error_code ec;
  const auto size = fs::file_size(partial.path(), ec);
  if (ec || std::streamoff(size) != written)
    throw FileError("cannot write '" + target.string() + "': only " + std::to_string(ec ? 0 : size) + " of " +
                    std::to_string(written) + " bytes reached the disk");
  if (before_commit) before_commit();
  // A target that was new is created without replacing (of concurrent writers, one wins and the
  // others fail with "exists"); one that existed is replaced.
  if (existed)
    partial.commit(target);
  else
    partial.commit_new(target);
}

void write_atomically_via_folder(const fs::path& target_in, const std::function<void(const fs::path&)>& write) {
  const fs::path target = resolve_output(target_in);
  check_output_path(target);
  // The names that exist now may be replaced (each checked below), unless they were new when the
  // command started; any other is created new.
  std::vector<fs::path> existed;
  {
    const std::vector<fs::path> fresh = registered_new_in(folder_of(target));
    std::error_code ec;
    for (fs::directory_iterator it(folder_of(target), ec), end; !ec && it != end; it.increment(ec))
      if (std::find(fresh.begin(), fresh.end(), it->path().filename()) == fresh.end())
        existed.push_back(it->path().filename());
  }
  Partial partial(target, Partial::Kind::Folder);
  const fs::path dir = partial.path();
  write(dir / target.filename());
  std::error_code ec;
  if (!fs::is_regular_file(dir / target.filename(), ec))
    throw FileError("cannot write '" + target.string() + "': the writer produced no file");
  // Check every destination first, so that either all files move or none.
  std::vector<fs::path> made;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file())
      throw FileError("cannot write '" + target.string() + "': the writer made '" + it->path().filename().string() +
                      "', not a file");
    const fs::path dest = folder_of(target) / it->path().filename();
    check_output_path(dest);
    // A side file (glTF's .bin) replaces an existing file only when that is the side file of the
    // target being replaced (the target names it): otherwise it is someone else's file.
    if (it->path().filename() != target.filename() && fs::exists(dest)) {
      std::ifstream old(target, std::ios::binary);
      std::string head(1 << 20, '\0');
      old.read(head.data(), std::streamsize(head.size()));
      head.resize(std::size_t(old.gcount()));
      if (head.find("\"" + it->path().filename().string() + "\"") == std::string::npos)
        throw FileError("cannot write '" + target.string() + "': its side file '" + dest.string() +
                        "' exists and is not the side file of an earlier '" + target.filename().string() +
                        "' (csrbf does not replace it; move it away or choose another name)");
    }
    made.push_back(it->path());
  }
  if (ec) throw FileError("cannot write '" + target.string() + "': " + ec.message());
  // The main file last: once it is there, its side files are too.
  std::stable_partition(made.begin(), made.end(), [&](const fs::path& p) { return p.filename() != target.filename(); });
  check_not_cancelled(target);
  time_limit_off();
  std::vector<fs::path> placed;  // files this call created that were new names
  for (const auto& p : made) {
    const fs::path dest = folder_of(target) / p.filename();
    const bool was_new = std::find(existed.begin(), existed.end(), p.filename()) == existed.end();
    keep_mode(dest, p);
    int rc = 0;
    if (was_new)
      rc = ::renameat2(AT_FDCWD, p.c_str(), AT_FDCWD, dest.c_str(), RENAME_NOREPLACE);
    else
      rc = ::rename(p.c_str(), dest.c_str());
    if (rc != 0) {
      const int e = errno;
      for (const auto& q : placed) ::unlink(q.c_str());  // made by this call a moment ago
      throw FileError("cannot write '" + dest.string() + "': " +
                      (e == EEXIST ? std::string("it exists (it was new when csrbf started; another program made it "
                                                 "meanwhile, and csrbf does not replace it)")
                                   : std::string(std::strerror(e))));
    }
    if (was_new) placed.push_back(dest);
  }
}

void check_readable(const std::filesystem::path& path, const char* what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (ec || st.type() == fs::file_type::not_found) throw FileError(path.string() + ": no such file");
  if (st.type() == fs::file_type::directory) throw FileError(path.string() + ": is a folder, not " + what);
  if (st.type() != fs::file_type::regular && st.type() != fs::file_type::fifo)
    throw FileError(path.string() + ": is not a regular file (a device or socket), not " + what);
}

std::string read_input(const std::filesystem::path& path, const char* what, double max_bytes) {
  check_readable(path, what);
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw FileError(path.string() + ": cannot open for reading: " + errno_text());
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw FileError(path.string() + ": cannot read: " + errno_text());
  if (S_ISFIFO(st.st_mode)) {
    // A FIFO nobody writes to would block for ever: wait for a writer for a bounded time.
    const int wait = pipe_timeout_seconds(60);
    pollfd p{fd, POLLIN, 0};
    int r;
    while ((r = ::poll(&p, 1, wait * 1000)) < 0 && errno == EINTR) {
    }
    if (r == 0) throw FileError(path.string() + ": nothing was written to this FIFO in " + std::to_string(wait) + " s");
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  if (S_ISREG(st.st_mode) && double(st.st_size) > max_bytes)
    throw FileError(path.string() + ": " + std::to_string(st.st_size) + " bytes is more than the " +
                    std::to_string(std::llround(max_bytes)) + " bytes allowed for " + what + " (--memory-limit)");
  std::string text;
  try {
    if (S_ISREG(st.st_mode)) {
      // Straight into the string (a copy through a buffer cost a tenth of reading a large mesh);
      // a file that shrinks meanwhile ends early, one that grows goes on below.
      text.resize(std::size_t(st.st_size));
      std::size_t got = 0;
      while (got < text.size()) {
        const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
        if (n < 0) {
          if (errno == EINTR) continue;
          throw FileError(path.string() + ": read error after " + std::to_string(got) + " bytes: " + errno_text());
        }
        if (n == 0) break;
        got += std::size_t(n);
      }
      text.resize(got);
    }
    char buf[1 << 16];
    for (;;) {
      const ssize_t n = ::read(fd, buf, sizeof buf);
      if (n < 0) {
        if (errno == EINTR) continue;
        throw FileError(path.string() + ": read error after " + std::to_string(text.size()) +
                        " bytes: " + errno_text());
      }
      if (n == 0) break;
      if (double(text.size() + std::size_t(n)) > max_bytes)
        throw FileError(path.string() + ": more than the " + std::to_string(std::llround(max_bytes)) +
                        " bytes allowed for " + what + " (--memory-limit)");
      text.append(buf, std::size_t(n));
    }
  } catch (const std::bad_alloc&) {
    throw FileError(path.string() + ": not enough memory to read it (" + std::to_string(text.size()) + " bytes read)");
  }
  return text;
}

}  // namespace csrbf::io
