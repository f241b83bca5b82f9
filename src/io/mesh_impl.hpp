// MeshDocument's state and the helpers its readers and writers share (private to csrbf::io). Each
// format has its own file: mesh_text.cpp (OBJ, OFF, XYZ and the line helpers), mesh_ply.cpp (PLY,
// ASCII and binary), mesh_assimp.cpp (STL, glTF, GLB through assimp, checked by gltf_check.cpp);
// mesh.cpp loads, saves in the same format (rewriting only the numbers) and answers the accessors.
#pragma once

#include "csrbf/io/error.hpp"
#include "csrbf/io/mesh.hpp"

#include <assimp/Importer.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace csrbf::io {

namespace detail {

// A token to rewrite: (line, token) in a text file.
struct Slot {
  std::size_t line = 0;
  std::uint32_t token = 0;
};

enum class PlyType { I8, U8, I16, U16, I32, U32, F32, F64 };
struct PlyProperty {
  std::string name;
  PlyType type = PlyType::F32;
  bool list = false;
  PlyType count_type = PlyType::U8;
};
struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> props;
};

std::optional<PlyType> ply_type(std::string_view s);
std::size_t ply_size(PlyType t);
double ply_read(const unsigned char* p, PlyType t, bool swap);
void ply_write(unsigned char* p, PlyType t, bool swap, double value);

/// The lines of a text file, CRLF or LF; a carriage return inside a line is refused (file:line).
std::vector<std::string> split_lines(std::string_view text, const std::filesystem::path& path);
/// Rewrites the tokens of one line (joined by single spaces, so only numbers change).
std::string rewrite_line(const std::string& line, const std::vector<std::pair<std::uint32_t, double>>& repl);
/// The line without its '#' comment, trimmed.
std::string_view strip_comment(std::string_view s);

}  // namespace detail

using detail::PlyElement;
using detail::PlyProperty;
using detail::PlyType;
using detail::Slot;

struct MeshDocument::Impl {
  MeshFormat format = MeshFormat::Obj;
  std::filesystem::path path;
  std::vector<Vec3> positions;
  PolygonList faces;
  bool has_normals = false;

  // Text formats (OBJ, OFF, XYZ, ASCII PLY body): the original lines and where each number sits.
  std::vector<std::string> lines;
  std::vector<std::array<Slot, 3>> position_slots;
  std::vector<std::array<Slot, 3>> normal_slots;           // per vertex (OFF, PLY) or per vn (OBJ)
  std::vector<Vec3> normals;                               // original values, kept where none can be computed
  std::vector<std::vector<std::int64_t>> face_normal_ids;  // OBJ: vn index of each face corner, or -1
  std::map<std::string, std::vector<std::uint32_t>> groups, materials;  // OBJ: g/o and usemtl -> faces

  // PLY
  std::string ply_header;
  bool ply_binary = false, ply_swap = false;
  std::vector<unsigned char> ply_body;
  // Binary: where x y z nx ny nz of vertex i sit. A vertex element without list properties has one
  // layout: its start a vertex, plus the same 6 offsets in it; else the 6 offsets a vertex.
  bool ply_fixed_layout = true;
  std::vector<std::size_t> ply_vertex_start;
  std::array<std::size_t, 6> ply_relative{};
  std::vector<std::array<std::size_t, 6>> ply_offsets;
  std::size_t ply_offset(std::size_t i, int k) const {
    return ply_fixed_layout ? ply_vertex_start[i] + ply_relative[std::size_t(k)] : ply_offsets[i][std::size_t(k)];
  }
  std::array<PlyType, 6> ply_types{};

  // assimp
  std::unique_ptr<Assimp::Importer> importer;

  // What reading may take (bytes, beside the file's text): checked against what the header's counts
  // predict before anything is allocated, where a format states them (binary PLY).
  double read_budget = std::numeric_limits<double>::infinity();

  std::string where(std::size_t line) const { return path.string() + ":" + std::to_string(line + 1) + ": "; }
  void check_faces() const {
    for (std::size_t f = 0; f < faces.size(); ++f) {
      if (faces[f].size() < 3)
        throw FileError(path.string() + ": face " + std::to_string(f) + " has " + std::to_string(faces[f].size()) +
                        " vertices; a face needs at least 3");
      for (auto v : faces[f])
        if (v >= positions.size())
          throw FileError(path.string() + ": face " + std::to_string(f) + " refers to vertex " + std::to_string(v) +
                          " but there are " + std::to_string(positions.size()) + " vertices");
    }
  }

  void load_obj(const std::string& text);
  void load_off(const std::string& text);
  void load_xyz(const std::string& text);
  void load_ply(const std::string& text);
  void load_assimp(double max_bytes);

  std::vector<Vec3> vertex_normals() const;  // area-weighted, normalised; original where none
  void save_same(const std::filesystem::path& out) const;
  void save_generic(const std::filesystem::path& out, MeshFormat f) const;
  /// Writes the scene assimp read (materials, texture coordinates, ...) with the new positions,
  /// where the mesh came through assimp and assimp writes `f`; false otherwise.
  bool save_read_scene(const std::filesystem::path& out, MeshFormat f) const;
};

}  // namespace csrbf::io
