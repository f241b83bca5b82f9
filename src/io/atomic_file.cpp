#include "csrbf/io/atomic_file.hpp"

#include "csrbf/io/error.hpp"

#include <fstream>
#include <random>
#include <system_error>
#include <unistd.h>

namespace fs = std::filesystem;

namespace csrbf::io {

namespace {
std::string unique_suffix() {
  static thread_local std::mt19937_64 rng(std::random_device{}() ^ (std::uint64_t(::getpid()) << 32));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}
fs::path folder_of(const fs::path& target) {
  return target.has_parent_path() ? target.parent_path() : fs::path(".");
}
}  // namespace

void check_output_path(const fs::path& target) {
  if (target.empty()) throw FileError("output path is empty");
  const fs::path dir = folder_of(target);
  std::error_code ec;
  if (!fs::exists(dir, ec)) throw FileError("cannot write '" + target.string() + "': folder '" + dir.string() + "' does not exist");
  if (!fs::is_directory(dir, ec)) throw FileError("cannot write '" + target.string() + "': '" + dir.string() + "' is not a folder");
  if (fs::is_directory(target, ec)) throw FileError("cannot write '" + target.string() + "': it is a folder");
}

void write_atomically(const fs::path& target, const std::function<void(std::ostream&)>& write) {
  check_output_path(target);
  std::string name = ".";  // built by appends: GCC 12 warns falsely on '"." + string' (-Wrestrict, PR 105329)
  name += target.filename().string();
  name += ".tmp-";
  name += unique_suffix();
  const fs::path tmp = folder_of(target) / name;
  try {
    {
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      if (!out) throw FileError("cannot write '" + target.string() + "': cannot create a file in '" + folder_of(target).string() + "'");
      write(out);
      out.flush();
      if (!out) throw FileError("cannot write '" + target.string() + "': write failed (disk full?)");
    }
    std::error_code ec;
    fs::rename(tmp, target, ec);
    if (ec) throw FileError("cannot write '" + target.string() + "': " + ec.message());
  } catch (...) {
    std::error_code ignore;
    fs::remove(tmp, ignore);
    throw;
  }
}

void write_atomically_via_folder(const fs::path& target, const std::function<void(const fs::path&)>& write) {
  check_output_path(target);
  const fs::path dir = folder_of(target) / (".csrbf-tmp-" + unique_suffix());
  std::error_code ec;
  if (!fs::create_directory(dir, ec) || ec)
    throw FileError("cannot write '" + target.string() + "': cannot create a temporary folder in '" + folder_of(target).string() + "'");
  try {
    write(dir / target.filename());
    if (!fs::exists(dir / target.filename())) throw FileError("cannot write '" + target.string() + "': the writer produced no file");
    for (const auto& e : fs::directory_iterator(dir)) {
      fs::rename(e.path(), folder_of(target) / e.path().filename(), ec);
      if (ec) throw FileError("cannot write '" + target.string() + "': " + ec.message());
    }
    fs::remove_all(dir, ec);
  } catch (...) {
    std::error_code ignore;
    fs::remove_all(dir, ignore);
    throw;
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

}  // namespace csrbf::io
