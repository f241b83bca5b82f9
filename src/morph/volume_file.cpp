#include "csrbf/morph/volume_file.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "volume_formats.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>

namespace fs = std::filesystem;

namespace csrbf::morph {

namespace detail {

namespace {

class FoamFile final : public VolumeFile {
 public:
  FoamFile(const fs::path& path, const OpenOptions& o) : case_(read_openfoam(path, o.max_file_bytes, o.time)) {}
  const VolumeMesh& mesh() const override { return case_.mesh; }
  std::string format() const override { return "openfoam"; }
  std::string encoding() const override {
    return std::string(case_.points_file.binary ? "binary" : "ascii") + (case_.points_file.gzip ? ", gzip" : "");
  }
  void write_copy(std::span<const Vec3> points, const fs::path& out) const override {
    write_openfoam_copy(case_, points, out);
  }
  void write_in_place(std::span<const Vec3> points) const override { write_openfoam_in_place(case_, points); }
  const FoamCase* foam() const override { return &case_; }

 private:
  FoamCase case_;
};

}  // namespace

std::string lower_extension(const fs::path& path) {
  std::string e = path.extension().string();
  for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

void check_copy_target(const fs::path& in, const fs::path& out) {
  io::check_output_path(out);
  std::error_code ec;
  if (fs::symlink_status(out, ec).type() != fs::file_type::not_found)
    throw io::FileError("cannot write '" + out.string() +
                        "': it exists (csrbf writes a new file; in place rewrites the input)");
  if (lower_extension(in) != lower_extension(out))
    throw io::FileError("cannot write '" + out.string() + "': a copy of " + in.string() +
                        " keeps its format and extension '" + in.extension().string() + "'");
}

std::unique_ptr<VolumeFile> open_openfoam(const fs::path& path, const OpenOptions& o) {
  return std::make_unique<FoamFile>(path, o);
}

namespace {
// Constant-initialised: set by csrbf::morph_formats's registration as the program starts, read after.
std::atomic<const StandardFormats*> registered_formats{nullptr};
}  // namespace

const StandardFormats& standard_formats() {
  static const StandardFormats none{};
  const StandardFormats* formats = registered_formats.load();
  return formats ? *formats : none;
}

void register_standard_formats(const StandardFormats& formats) { registered_formats.store(&formats); }

}  // namespace detail

std::unique_ptr<VolumeFile> open_volume(const fs::path& path, const OpenOptions& options) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (!is_openfoam(path))
      throw io::FileError(path.string() +
                          ": a folder, but not an OpenFOAM case (no constant/polyMesh, and no faces or "
                          "owner file)");
    return detail::open_openfoam(path, options);
  }
  const std::string ext = detail::lower_extension(path);
  if (!options.time.empty())
    throw io::FileError(path.string() + ": -time '" + options.time +
                        "' picks an OpenFOAM case's time folder; this is a mesh file, which has no times");
  if (fs::exists(path, ec) && !fs::is_regular_file(path, ec))
    throw io::FileError(path.string() + ": not a regular file (a mesh file is read whole, not from a pipe or device)");
  const detail::StandardFormats& formats = detail::standard_formats();
  const auto opened = [&](auto* open, const char* library) {
    if (!open)
      throw io::FileError(path.string() + ": " + ext + " files are read through " + library +
                          ", which this program is linked without (csrbf::morph_formats)");
    return open(path, options);
  };
  if (ext == ".vtu" || ext == ".vtk") return opened(formats.open_vtk, "VTK");
  if (ext == ".msh") return opened(formats.open_gmsh, "Gmsh");
  if (ext == ".cgns") return opened(formats.open_cgns, "CGNS");
  if (ext == ".pvtu" && fs::exists(path, ec))
    throw io::FileError(path.string() +
                        ": a parallel VTK file: its pieces are morphed by as many MPI ranks (mpirun -np PIECES "
                        "csrbf morph ...), or a piece (.vtu) alone");
  if (!fs::exists(path, ec)) throw io::FileError(path.string() + ": no such file or folder");
  throw io::FileError(path.string() + ": unknown volume mesh format '" + ext + "' (csrbf morph reads " +
                      kVolumeFormats + ")");
}

}  // namespace csrbf::morph
