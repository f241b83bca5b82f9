// MeshDocument: the format from the extension, load, save in the same format (rewriting only the
// numbers of positions and normals) or another (through the writers of mesh_assimp.cpp), accessors.
// Each format's reader is in its own file (mesh_impl.hpp lists them).
#include "mesh_impl.hpp"
#include "csrbf/io/input_file.hpp"

#include "csrbf/io/controls.hpp"
#include "text.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/units.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace csrbf::io {

using detail::parse_double;
using detail::parse_int;
using detail::rewrite_line;
using detail::split;
using detail::trim;

MeshFormat format_for(const fs::path& path) {
  std::string e = path.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  if (e == ".obj") return MeshFormat::Obj;
  if (e == ".ply") return MeshFormat::Ply;
  if (e == ".off") return MeshFormat::Off;
  if (e == ".xyz") return MeshFormat::Xyz;
  if (e == ".stl") return MeshFormat::Stl;
  if (e == ".gltf") return MeshFormat::Gltf;
  if (e == ".glb") return MeshFormat::Glb;
  return MeshFormat::Assimp;
}

const char* format_name(MeshFormat f) noexcept {
  switch (f) {
    case MeshFormat::Obj:
      return "OBJ";
    case MeshFormat::Ply:
      return "PLY";
    case MeshFormat::Off:
      return "OFF";
    case MeshFormat::Xyz:
      return "XYZ";
    case MeshFormat::Stl:
      return "STL";
    case MeshFormat::Gltf:
      return "glTF";
    case MeshFormat::Glb:
      return "GLB";
    case MeshFormat::Assimp:
      return "assimp";
  }
  return "?";
}

Vec3 polygon_normal(const std::vector<Vec3>& p, std::span<const std::uint32_t> f) {
  Vec3 n = Vec3::Zero();
  for (std::size_t k = 0; k < f.size(); ++k) {
    const Vec3& a = p[f[k]];
    const Vec3& b = p[f[(k + 1) % f.size()]];
    n += Vec3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
  }
  return 0.5 * n;
}

std::vector<Vec3> MeshDocument::Impl::vertex_normals() const {
  std::vector<Vec3> acc(positions.size(), Vec3::Zero());
  for (const auto& f : faces) {
    const Vec3 n = polygon_normal(positions, f);
    for (auto v : f) acc[v] += n;
  }
  for (std::size_t i = 0; i < acc.size(); ++i) {
    const double len = acc[i].norm();
    acc[i] = len > 0 ? Vec3(acc[i] / len) : (i < normals.size() ? normals[i] : Vec3::Zero());
  }
  return acc;
}

void MeshDocument::Impl::save_same(const fs::path& out) const {
  // Text formats: rewrite the numbers of positions and normals, keep every other byte of each line.
  std::vector<std::vector<std::pair<std::uint32_t, double>>> repl(lines.size());
  auto put = [&](const std::array<Slot, 3>& s, const Vec3& v) {
    for (int k = 0; k < 3; ++k) repl[s[std::size_t(k)].line].emplace_back(s[std::size_t(k)].token, v[k]);
  };
  std::vector<Vec3> vn;
  if (has_normals) {
    if (format == MeshFormat::Obj) {
      // Each vn is the normalised sum of the normals of the faces whose corners use it, so split
      // (hard-edge) normals stay split.
      vn.assign(normals.size(), Vec3::Zero());
      for (std::size_t f = 0; f < faces.size(); ++f) {
        const Vec3 n = polygon_normal(positions, faces[f]);
        for (auto id : face_normal_ids[f])
          if (id >= 0) vn[std::size_t(id)] += n;
      }
      for (std::size_t i = 0; i < vn.size(); ++i) {
        const double len = vn[i].norm();
        vn[i] = len > 0 ? Vec3(vn[i] / len) : normals[i];
      }
    } else {
      vn = vertex_normals();
    }
  }
  if (format == MeshFormat::Ply && ply_binary) {
    std::vector<unsigned char> body = ply_body;
    for (std::size_t i = 0; i < positions.size(); ++i) {
      for (int k = 0; k < 3; ++k)
        ply_write(&body[ply_offset(i, k)], ply_types[std::size_t(k)], ply_swap, positions[i][k]);
      if (has_normals)
        for (int k = 0; k < 3; ++k)
          ply_write(&body[ply_offset(i, k + 3)], ply_types[std::size_t(k + 3)], ply_swap, vn[i][k]);
    }
    write_atomically(out, [&](std::ostream& os) {
      os << ply_header;
      os.write(reinterpret_cast<const char*>(body.data()), std::streamsize(body.size()));
    });
    return;
  }
  for (std::size_t i = 0; i < positions.size(); ++i) put(position_slots[i], positions[i]);
  for (std::size_t i = 0; i < normal_slots.size(); ++i) put(normal_slots[i], vn[i]);
  write_atomically(out, [&](std::ostream& os) {
    if (format == MeshFormat::Ply) os << ply_header;
    for (std::size_t li = 0; li < lines.size(); ++li) {
      if (repl[li].empty()) {
        os << lines[li] << '\n';
        continue;
      }
      // The first line's byte order mark is not a token: its numbers were counted without it.
      const std::string_view line =
          li == 0 && format != MeshFormat::Ply ? detail::skip_bom(lines[li]) : std::string_view(lines[li]);
      os << lines[li].substr(0, lines[li].size() - line.size()) << rewrite_line(std::string(line), repl[li]) << '\n';
    }
  });
}

MeshDocument MeshDocument::load(const fs::path& path, double memory_limit_bytes) {
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->format = format_for(path);
  // A mesh takes up to about 12 times its file's size once read (a text file's lines and where each
  // number is; a binary file's faces as vectors, and assimp's copies).
  const double max_file = memory_limit_bytes / 12;
  {
    // Said with the limit it needs, before read_input's plainer refusal.
    std::error_code ec;
    const auto size = fs::is_regular_file(path, ec) ? fs::file_size(path, ec) : 0;
    if (!ec && double(size) > max_file) {
      char text[200];
      std::snprintf(text, sizeof text,
                    ": %.0f bytes; a mesh may take 12 times its file's size once read, more than --memory-limit "
                    "%.3g GiB allows: give --memory-limit %.2f or more",
                    double(size), memory_limit_bytes / kGiB,
                    std::ceil(100 * (12.0 * double(size) + resident_bytes()) / kGiB) / 100);
      throw FileError(path.string() + text);
    }
  }
  try {
    switch (impl->format) {
      case MeshFormat::Obj:
        impl->load_obj(read_input(path, "a mesh", max_file));
        break;
      case MeshFormat::Off:
        impl->load_off(read_input(path, "a mesh", max_file));
        break;
      case MeshFormat::Xyz:
        impl->load_xyz(read_input(path, "a mesh", max_file));
        break;
      case MeshFormat::Ply:
        // A binary PLY's vertices take up to 8 times their file bytes once read (positions, normals
        // and where each sits): its counts are checked against what the program leaves of the limit.
        impl->read_budget = memory_limit_bytes - resident_bytes();
        impl->load_ply(read_input(path, "a mesh", max_file));
        break;
      case MeshFormat::Assimp:
        check_readable(path, "a mesh");
        // assimp reads dozens of other formats, some of whose readers crash or loop on bad files:
        // only the ones csrbf is tested and fuzzed with.
        throw FileError(path.string() + ": unknown mesh format '" + path.extension().string() +
                        "' (csrbf reads .obj .ply .off .xyz .stl .gltf .glb)");
      default: {
        check_readable(path, "a mesh");
        std::error_code ec;
        if (!fs::is_regular_file(path, ec))
          throw FileError(path.string() + ": " + format_name(impl->format) +
                          " meshes are read from regular files only, not pipes");
        // Its size was checked above; assimp's reads are bounded by max_file too (LimitedIOSystem).
        impl->load_assimp(max_file);
      }
    }
  } catch (const std::bad_alloc&) {
    throw FileError(path.string() + ": not enough memory to read the mesh");
  } catch (const std::length_error&) {
    throw FileError(path.string() + ": the mesh is too large to read");
  }
  if (impl->positions.empty()) throw FileError(path.string() + ": the mesh has no vertices");
  return MeshDocument(std::move(impl));
}

MeshDocument::MeshDocument(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MeshDocument::MeshDocument(MeshDocument&&) noexcept = default;
MeshDocument& MeshDocument::operator=(MeshDocument&&) noexcept = default;
MeshDocument::~MeshDocument() = default;

MeshFormat MeshDocument::format() const noexcept { return impl_->format; }
std::vector<Vec3>& MeshDocument::positions() noexcept { return impl_->positions; }
const std::vector<Vec3>& MeshDocument::positions() const noexcept { return impl_->positions; }
const PolygonList& MeshDocument::faces() const noexcept { return impl_->faces; }
bool MeshDocument::has_normals() const noexcept { return impl_->has_normals; }
const std::map<std::string, std::vector<std::uint32_t>>& MeshDocument::groups() const noexcept { return impl_->groups; }
const std::map<std::string, std::vector<std::uint32_t>>& MeshDocument::materials() const noexcept {
  return impl_->materials;
}

void MeshDocument::save(const fs::path& path) const {
  const MeshFormat out = format_for(path);
  const MeshFormat in = impl_->format;
  check_output_path(path);
  // Never a NaN or an infinity in a file: checked in double, and against single precision where the
  // format stores float (STL, glTF, GLB; PLY whose coordinates are float).
  const bool single = out == MeshFormat::Stl || out == MeshFormat::Gltf || out == MeshFormat::Glb ||
                      (out == MeshFormat::Ply && in == MeshFormat::Ply &&
                       (impl_->ply_types[0] == PlyType::F32 || impl_->ply_types[1] == PlyType::F32 ||
                        impl_->ply_types[2] == PlyType::F32));
  const double limit = single ? double(std::numeric_limits<float>::max()) : std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < impl_->positions.size(); ++i) {
    const Vec3& p = impl_->positions[i];
    if (!(p.cwiseAbs().maxCoeff() <= limit))
      throw FileError("cannot write '" + path.string() + "': vertex " + std::to_string(i) + " (" +
                      format_number(p.x()) + " " + format_number(p.y()) + " " + format_number(p.z()) + ") is " +
                      (p.allFinite() ? std::string("beyond the single precision the format stores") : "not finite"));
  }
  const bool text_same =
      out == in && (in == MeshFormat::Obj || in == MeshFormat::Ply || in == MeshFormat::Off || in == MeshFormat::Xyz);
  if (text_same) return impl_->save_same(path);
  // STL keeps nothing but triangles, so it is always written from positions and faces (assimp's STL
  // exporter also refuses some of its importer's scenes without a reason).
  if (out != MeshFormat::Stl && impl_->save_read_scene(path, out)) return;
  impl_->save_generic(path, out);
}

}  // namespace csrbf::io
