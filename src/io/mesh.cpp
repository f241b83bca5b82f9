#include "csrbf/io/mesh.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/controls.hpp"
#include "gltf_check.hpp"
#include "text.hpp"

#include <assimp/DefaultIOSystem.h>
#include <nlohmann/json.hpp>
#include <assimp/Exporter.hpp>
#include <assimp/IOStream.hpp>
#include <assimp/IOSystem.hpp>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <sstream>

namespace fs = std::filesystem;

namespace csrbf::io {

using detail::parse_double;
using detail::parse_int;
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

Vec3 polygon_normal(const std::vector<Vec3>& p, const std::vector<std::uint32_t>& f) {
  Vec3 n = Vec3::Zero();
  for (std::size_t k = 0; k < f.size(); ++k) {
    const Vec3& a = p[f[k]];
    const Vec3& b = p[f[(k + 1) % f.size()]];
    n += Vec3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
  }
  return 0.5 * n;
}

namespace {

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

std::optional<PlyType> ply_type(std::string_view s) {
  if (s == "char" || s == "int8") return PlyType::I8;
  if (s == "uchar" || s == "uint8") return PlyType::U8;
  if (s == "short" || s == "int16") return PlyType::I16;
  if (s == "ushort" || s == "uint16") return PlyType::U16;
  if (s == "int" || s == "int32") return PlyType::I32;
  if (s == "uint" || s == "uint32") return PlyType::U32;
  if (s == "float" || s == "float32") return PlyType::F32;
  if (s == "double" || s == "float64") return PlyType::F64;
  return std::nullopt;
}
std::size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::I8:
    case PlyType::U8:
      return 1;
    case PlyType::I16:
    case PlyType::U16:
      return 2;
    case PlyType::I32:
    case PlyType::U32:
    case PlyType::F32:
      return 4;
    case PlyType::F64:
      return 8;
  }
  return 0;
}

void reverse_bytes(unsigned char* b, std::size_t n) { std::reverse(b, b + n); }

double ply_read(const unsigned char* p, PlyType t, bool swap) {
  unsigned char b[8];
  const std::size_t n = ply_size(t);
  std::memcpy(b, p, n);
  if (swap) reverse_bytes(b, n);
  switch (t) {
    case PlyType::I8: {
      std::int8_t v;
      std::memcpy(&v, b, 1);
      return v;
    }
    case PlyType::U8: {
      std::uint8_t v;
      std::memcpy(&v, b, 1);
      return v;
    }
    case PlyType::I16: {
      std::int16_t v;
      std::memcpy(&v, b, 2);
      return v;
    }
    case PlyType::U16: {
      std::uint16_t v;
      std::memcpy(&v, b, 2);
      return v;
    }
    case PlyType::I32: {
      std::int32_t v;
      std::memcpy(&v, b, 4);
      return v;
    }
    case PlyType::U32: {
      std::uint32_t v;
      std::memcpy(&v, b, 4);
      return v;
    }
    case PlyType::F32: {
      float v;
      std::memcpy(&v, b, 4);
      return v;
    }
    case PlyType::F64: {
      double v;
      std::memcpy(&v, b, 8);
      return v;
    }
  }
  return 0;
}

void ply_write(unsigned char* p, PlyType t, bool swap, double value) {
  unsigned char b[8];
  const std::size_t n = ply_size(t);
  if (t == PlyType::F32) {
    const float v = float(value);
    std::memcpy(b, &v, 4);
  } else {
    const double v = value;
    std::memcpy(b, &v, 8);
  }
  if (swap) reverse_bytes(b, n);
  std::memcpy(p, b, n);
}

std::vector<std::string> split_lines(std::string_view text, const fs::path& path) {
  std::vector<std::string> lines;
  std::size_t i = 0;
  while (i < text.size()) {
    std::size_t j = text.find('\n', i);
    if (j == std::string_view::npos) j = text.size();
    std::string l(text.substr(i, j - i));
    if (!l.empty() && l.back() == '\r') l.pop_back();
    // A carriage return inside a line: old Mac (CR-only) line endings, which would read as one line
    // and silently lose everything after its first record.
    if (l.find('\r') != std::string::npos)
      throw FileError(path.string() + ":" + std::to_string(lines.size() + 1) +
                      ": a carriage return inside the line (old Mac line endings? convert them to LF or CRLF)");
    lines.push_back(std::move(l));
    i = j + 1;
  }
  return lines;
}

// Rewrites the tokens of one line (joined by single spaces, so only numbers change).
std::string rewrite_line(const std::string& line, const std::vector<std::pair<std::uint32_t, double>>& repl) {
  auto tok = split(line);
  std::vector<std::string> out(tok.begin(), tok.end());
  for (const auto& [k, v] : repl) out[k] = format_number(v);
  std::string s;
  for (std::size_t k = 0; k < out.size(); ++k) {
    if (k) s += ' ';
    s += out[k];
  }
  return s;
}

/// assimp reads the files a glTF names (its buffers, images) by itself: only regular files, and
/// all of them together within the memory limit.
class LimitedIOSystem : public Assimp::DefaultIOSystem {
 public:
  explicit LimitedIOSystem(double max_bytes) : left_(max_bytes) {}
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    std::error_code ec;
    const auto st = fs::status(file, ec);
    if (st.type() != fs::file_type::regular) {
      error_ = std::string("'") + file + "' is not a regular file";
      return nullptr;
    }
    left_ -= double(fs::file_size(file, ec));
    if (left_ < 0) {
      error_ = std::string("'") + file + "' takes the files read past the memory limit (--memory-limit)";
      return nullptr;
    }
    return DefaultIOSystem::Open(file, mode);
  }
  const std::string& error() const { return error_; }

 private:
  double left_;
  std::string error_;
};

std::string_view strip_comment(std::string_view s) {
  if (const auto h = s.find('#'); h != std::string_view::npos) s = s.substr(0, h);
  return trim(s);
}

}  // namespace

struct MeshDocument::Impl {
  MeshFormat format = MeshFormat::Obj;
  fs::path path;
  std::vector<Vec3> positions;
  std::vector<std::vector<std::uint32_t>> faces;
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
  std::vector<std::array<std::size_t, 6>> ply_offsets;  // binary: byte offset of x y z nx ny nz
  std::array<PlyType, 6> ply_types{};

  // assimp
  std::unique_ptr<Assimp::Importer> importer;

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
  void save_same(const fs::path& out) const;
  void save_generic(const fs::path& out, MeshFormat f) const;
};

void MeshDocument::Impl::load_obj(const std::string& text) {
  lines = split_lines(text, path);
  std::size_t vn_count = 0;
  std::vector<std::string> current_groups;
  std::string current_material;
  for (std::size_t li = 0; li < lines.size(); ++li) {
    const auto body = strip_comment(li == 0 ? detail::skip_bom(lines[li]) : std::string_view(lines[li]));
    if (body.empty()) continue;
    const auto tok = split(body);
    if (tok[0] == "v" || tok[0] == "vn") {
      if (tok.size() < 4)
        throw FileError(where(li) + "expected '" + detail::cut(tok[0]) + " x y z', got '" + detail::cut(body) + "'");
      Vec3 p;
      for (int k = 0; k < 3; ++k)
        if (!parse_double(tok[k + 1], p[k]) || !std::isfinite(p[k]))
          throw FileError(where(li) + "'" + detail::cut(tok[k + 1]) + "' is not a finite number (line: '" +
                          detail::cut(body) + "')");
      if (tok[0] == "v") {
        positions.push_back(p);
        position_slots.push_back({Slot{li, 1}, Slot{li, 2}, Slot{li, 3}});
      } else {
        normals.push_back(p);
        normal_slots.push_back({Slot{li, 1}, Slot{li, 2}, Slot{li, 3}});
        ++vn_count;
      }
    } else if (tok[0] == "f") {
      if (tok.size() < 4) throw FileError(where(li) + "a face needs at least 3 vertices: '" + detail::cut(body) + "'");
      std::vector<std::uint32_t> f;
      std::vector<std::int64_t> fn;
      for (std::size_t k = 1; k < tok.size(); ++k) {
        const auto t = tok[k];
        const auto s1 = t.find('/');
        std::int64_t vi = 0, ni = 0;
        if (!parse_int(t.substr(0, s1), vi) || vi == 0)
          throw FileError(where(li) + "bad vertex reference '" + detail::cut(t) + "'");
        if (vi < 0) vi += std::int64_t(positions.size()) + 1;
        if (vi < 1 || vi > std::int64_t(positions.size()))
          throw FileError(where(li) + "vertex reference '" + detail::cut(t) + "' is out of range (" +
                          std::to_string(positions.size()) + " vertices so far)");
        f.push_back(std::uint32_t(vi - 1));
        std::int64_t n_id = -1;
        if (s1 != std::string_view::npos) {
          const auto s2 = t.find('/', s1 + 1);
          if (s2 != std::string_view::npos && s2 + 1 < t.size()) {
            if (!parse_int(t.substr(s2 + 1), ni) || ni == 0)
              throw FileError(where(li) + "bad normal reference '" + detail::cut(t) + "'");
            if (ni < 0) ni += std::int64_t(vn_count) + 1;
            if (ni < 1 || ni > std::int64_t(vn_count))
              throw FileError(where(li) + "normal reference '" + detail::cut(t) + "' is out of range");
            n_id = ni - 1;
          }
        }
        fn.push_back(n_id);
      }
      for (const auto& g : current_groups) groups[g].push_back(std::uint32_t(faces.size()));
      if (!current_material.empty()) materials[current_material].push_back(std::uint32_t(faces.size()));
      faces.push_back(std::move(f));
      face_normal_ids.push_back(std::move(fn));
    } else if (tok[0] == "g" || tok[0] == "o") {
      current_groups.assign(tok.begin() + 1, tok.end());  // "g a b": the faces below are in a and b
    } else if (tok[0] == "usemtl") {
      current_material = tok.size() > 1 ? std::string(tok[1]) : std::string();
    }
  }
  has_normals = !normals.empty();
}

void MeshDocument::Impl::load_off(const std::string& text) {
  lines = split_lines(text, path);
  std::size_t li = 0;
  auto next = [&]() -> std::vector<std::string_view> {
    while (li < lines.size()) {
      const auto b = strip_comment(li == 0 ? detail::skip_bom(lines[li]) : std::string_view(lines[li]));
      if (!b.empty()) return split(b);
      ++li;
    }
    return {};
  };
  auto tok = next();
  if (tok.empty()) throw FileError(path.string() + ": empty file, expected an 'OFF' header");
  std::string key(tok[0]);
  // [ST][C][N][4][n]OFF; we accept the 3-D forms with optional colour and normals.
  bool normals_present = false;
  {
    std::string k = key;
    if (k.size() < 3 || k.substr(k.size() - 3) != "OFF")
      throw FileError(where(li) + "expected an 'OFF' header, got '" + key + "'");
    const std::string pre = k.substr(0, k.size() - 3);
    for (char c : pre) {
      if (c == 'N')
        normals_present = true;
      else if (c != 'C' && c != 'S' && c != 'T')
        throw FileError(where(li) + "unsupported OFF variant '" + key + "' (supported: OFF, COFF, NOFF, CNOFF, STOFF)");
    }
  }
  tok.erase(tok.begin());
  if (tok.empty()) {
    ++li;
    tok = next();
  }
  std::size_t nv = 0, nf = 0;
  if (tok.size() < 2 || !parse_int(tok[0], nv) || !parse_int(tok[1], nf))
    throw FileError(where(li) + "expected 'vertex_count face_count edge_count', got '" +
                    detail::cut(lines[std::min(li, lines.size() - 1)]) + "'");
  // Each vertex and face takes a line: the counts are bounded by the file before any allocation.
  if (nv > lines.size() || nf > lines.size() || nv + nf > lines.size())
    throw FileError(where(li) + "the header declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                    " faces but the file has only " + std::to_string(lines.size()) + " lines");
  ++li;
  for (std::size_t v = 0; v < nv; ++v) {
    tok = next();
    if (tok.empty())
      throw FileError(path.string() + ": ends after " + std::to_string(v) + " of " + std::to_string(nv) + " vertices");
    const std::size_t need = normals_present ? 6 : 3;
    if (tok.size() < need)
      throw FileError(where(li) + "expected " + std::to_string(need) + " numbers for vertex " + std::to_string(v) +
                      ", got '" + lines[li] + "'");
    Vec3 p, n = Vec3::Zero();
    for (std::size_t k = 0; k < need; ++k) {
      double x;
      if (!parse_double(tok[k], x) || !std::isfinite(x))
        throw FileError(where(li) + "'" + detail::cut(tok[k]) + "' is not a finite number");
      (k < 3 ? p[k] : n[k - 3]) = x;
    }
    positions.push_back(p);
    position_slots.push_back({Slot{li, 0}, Slot{li, 1}, Slot{li, 2}});
    if (normals_present) {
      normals.push_back(n);
      normal_slots.push_back({Slot{li, 3}, Slot{li, 4}, Slot{li, 5}});
    }
    ++li;
  }
  for (std::size_t f = 0; f < nf; ++f) {
    tok = next();
    if (tok.empty())
      throw FileError(path.string() + ": ends after " + std::to_string(f) + " of " + std::to_string(nf) + " faces");
    std::size_t k = 0;
    if (!parse_int(tok[0], k) || k >= tok.size())
      throw FileError(where(li) + "bad face '" + detail::cut(lines[li]) + "' (expected 'n i1 ... in')");
    if (k < 3)
      throw FileError(where(li) + "a face has " + std::to_string(k) + " vertices; a face needs at least 3: '" +
                      detail::cut(lines[li]) + "'");
    std::vector<std::uint32_t> face(k);
    for (std::size_t j = 0; j < k; ++j)
      if (!parse_int(tok[j + 1], face[j]))
        throw FileError(where(li) + "bad vertex index '" + detail::cut(tok[j + 1]) + "'");
    faces.push_back(std::move(face));
    ++li;
  }
  has_normals = normals_present;
  check_faces();
}

void MeshDocument::Impl::load_xyz(const std::string& text) {
  lines = split_lines(text, path);
  for (std::size_t li = 0; li < lines.size(); ++li) {
    const auto b = strip_comment(li == 0 ? detail::skip_bom(lines[li]) : std::string_view(lines[li]));
    if (b.empty()) continue;
    const auto tok = split(b);
    if (tok.size() < 3) throw FileError(where(li) + "expected 'x y z', got '" + detail::cut(b) + "'");
    Vec3 p;
    for (int k = 0; k < 3; ++k)
      if (!parse_double(tok[k], p[k]) || !std::isfinite(p[k]))
        throw FileError(where(li) + "'" + detail::cut(tok[k]) + "' is not a finite number (line: '" + detail::cut(b) +
                        "')");
    positions.push_back(p);
    position_slots.push_back({Slot{li, 0}, Slot{li, 1}, Slot{li, 2}});
  }
  if (positions.empty()) throw FileError(path.string() + ": no points (expected lines 'x y z')");
}

void MeshDocument::Impl::load_ply(const std::string& text) {
  const std::string name = path.string();
  if (text.compare(0, 3, "ply") != 0) throw FileError(name + ": not a PLY file (no 'ply' magic)");
  const auto end = text.find("end_header");
  if (end == std::string::npos) throw FileError(name + ": PLY header has no 'end_header'");
  const auto body_start = text.find('\n', end);
  if (body_start == std::string::npos) throw FileError(name + ": PLY file ends after its header");
  ply_header = text.substr(0, body_start + 1);
  const auto hlines = split_lines(ply_header, path);
  std::vector<PlyElement> elements;
  bool format_seen = false;
  for (std::size_t li = 1; li < hlines.size(); ++li) {
    const auto tok = split(hlines[li]);
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info" || tok[0] == "end_header") continue;
    if (tok[0] == "format") {
      if (tok.size() < 2) throw FileError(where(li) + "bad format line '" + hlines[li] + "'");
      if (tok[1] == "ascii")
        ply_binary = false;
      else if (tok[1] == "binary_little_endian") {
        ply_binary = true;
        ply_swap = std::endian::native != std::endian::little;
      } else if (tok[1] == "binary_big_endian") {
        ply_binary = true;
        ply_swap = std::endian::native != std::endian::big;
      } else
        throw FileError(where(li) + "unknown PLY format '" + std::string(tok[1]) + "'");
      format_seen = true;
    } else if (tok[0] == "element") {
      PlyElement e;
      if (tok.size() != 3 || !parse_int(tok[2], e.count))
        throw FileError(where(li) + "bad element line '" + hlines[li] + "'");
      e.name = std::string(tok[1]);
      elements.push_back(std::move(e));
    } else if (tok[0] == "property") {
      if (elements.empty()) throw FileError(where(li) + "property before any element");
      PlyProperty p;
      if (tok.size() == 5 && tok[1] == "list") {
        const auto ct = ply_type(tok[2]), it = ply_type(tok[3]);
        if (!ct || !it) throw FileError(where(li) + "unknown PLY type in '" + hlines[li] + "'");
        p.list = true;
        p.count_type = *ct;
        p.type = *it;
        p.name = std::string(tok[4]);
      } else if (tok.size() == 3) {
        const auto t = ply_type(tok[1]);
        if (!t) throw FileError(where(li) + "unknown PLY type '" + std::string(tok[1]) + "'");
        p.type = *t;
        p.name = std::string(tok[2]);
      } else {
        throw FileError(where(li) + "bad property line '" + hlines[li] + "'");
      }
      elements.back().props.push_back(std::move(p));
    } else {
      throw FileError(where(li) + "unknown PLY header keyword '" + std::string(tok[0]) + "'");
    }
  }
  if (!format_seen) throw FileError(name + ": PLY header has no 'format' line");
  // Counts come from the header and are not trusted: each is bounded by what the body can hold
  // before anything is allocated, and a list's length and indices must be integers.
  const std::size_t body_bytes = text.size() - (body_start + 1);
  for (std::size_t a = 0; a < elements.size(); ++a) {
    const auto& e = elements[a];
    for (std::size_t b = 0; b < a; ++b)
      if (elements[b].name == e.name) throw FileError(name + ": PLY header declares element '" + e.name + "' twice");
    if (e.props.empty() && e.count > 0)
      throw FileError(name + ": PLY element '" + e.name + "' has " + std::to_string(e.count) +
                      " entries but no properties");
    std::size_t least = 0;  // bytes (binary) or tokens (ASCII) of one entry at the least
    for (const auto& pr : e.props) {
      if (pr.list) {
        const auto integral = [](PlyType t) { return t != PlyType::F32 && t != PlyType::F64; };
        if (!integral(pr.count_type) || !integral(pr.type))
          throw FileError(name + ": PLY list property '" + pr.name + "' of element '" + e.name +
                          "' must have integer count and index types");
        least += ply_binary ? ply_size(pr.count_type) : 1;
      } else {
        least += ply_binary ? ply_size(pr.type) : 1;
      }
    }
    // An ASCII token takes at least 2 bytes with its separator.
    const std::size_t room = ply_binary ? body_bytes : (body_bytes + 1) / 2;
    if (least > 0 && e.count > room / least)
      throw FileError(name + ": PLY element '" + e.name + "' declares " + std::to_string(e.count) +
                      " entries but the file's body (" + std::to_string(body_bytes) + " bytes) can hold at most " +
                      std::to_string(room / least));
  }
  const PlyElement* vertex = nullptr;
  for (const auto& e : elements) {
    if (e.name == "vertex") vertex = &e;
    if (e.name == "face" && e.count > 0 && std::none_of(e.props.begin(), e.props.end(), [](const PlyProperty& p) {
          return p.list && (p.name == "vertex_indices" || p.name == "vertex_index");
        }))
      throw FileError(name + ": PLY element 'face' has no list property 'vertex_indices' (or 'vertex_index')");
  }
  if (!vertex) throw FileError(name + ": PLY file has no 'vertex' element");
  int idx[6] = {-1, -1, -1, -1, -1, -1};
  const char* names[6] = {"x", "y", "z", "nx", "ny", "nz"};
  for (int k = 0; k < 6; ++k)
    for (std::size_t p = 0; p < vertex->props.size(); ++p)
      if (vertex->props[p].name == names[k] && !vertex->props[p].list) idx[k] = int(p);
  for (int k = 0; k < 3; ++k)
    if (idx[k] < 0) throw FileError(name + ": PLY 'vertex' element has no property '" + names[k] + "'");
  has_normals = idx[3] >= 0 && idx[4] >= 0 && idx[5] >= 0;
  for (int k = 0; k < (has_normals ? 6 : 3); ++k) {
    const PlyType t = vertex->props[std::size_t(idx[k])].type;
    if (t != PlyType::F32 && t != PlyType::F64)
      throw FileError(name + ": PLY property '" + names[k] + "' must be float or double to be deformed");
    ply_types[std::size_t(k)] = t;
  }

  if (ply_binary) {
    ply_body.assign(text.begin() + std::ptrdiff_t(body_start + 1), text.end());
    std::size_t off = 0;
    const std::size_t size = ply_body.size();
    auto need = [&](std::size_t n, const std::string& what) {
      if (off + n > size) throw FileError(name + ": PLY body ends early, in " + what);
    };
    for (const auto& e : elements) {
      for (std::size_t i = 0; i < e.count; ++i) {
        std::array<std::size_t, 6> offs{};
        std::vector<std::uint32_t> face;
        for (std::size_t p = 0; p < e.props.size(); ++p) {
          const auto& pr = e.props[p];
          const std::string what = e.name + " " + std::to_string(i) + " property '" + pr.name + "'";
          if (!pr.list) {
            need(ply_size(pr.type), what);
            if (&e == vertex)
              for (int k = 0; k < 6; ++k)
                if (idx[k] == int(p)) offs[std::size_t(k)] = off;
            off += ply_size(pr.type);
          } else {
            need(ply_size(pr.count_type), what);
            const double c = ply_read(&ply_body[off], pr.count_type, ply_swap);
            off += ply_size(pr.count_type);
            if (c < 0) throw FileError(name + ": negative list length in " + what);
            if (c > double((size - off) / ply_size(pr.type)))
              throw FileError(name + ": PLY body ends early, in " + what);
            const bool face_list = e.name == "face" && (pr.name == "vertex_indices" || pr.name == "vertex_index");
            if (face_list && c < 3)
              throw FileError(name + ": face " + std::to_string(i) + " has " + std::to_string(std::size_t(c)) +
                              " vertices; a face needs at least 3");
            const bool is_face = e.name == "face" && (pr.name == "vertex_indices" || pr.name == "vertex_index");
            for (std::size_t j = 0; j < std::size_t(c); ++j) {
              if (is_face) {
                const double v = ply_read(&ply_body[off], pr.type, ply_swap);
                if (v < 0 || v > 4294967295.0)
                  throw FileError(name + ": vertex index " + std::to_string(std::int64_t(v)) + " out of range in " +
                                  what);
                face.push_back(std::uint32_t(v));
              }
              off += ply_size(pr.type);
            }
          }
        }
        if (&e == vertex) {
          Vec3 p, n = Vec3::Zero();
          for (int k = 0; k < 3; ++k)
            p[k] = ply_read(&ply_body[offs[std::size_t(k)]], ply_types[std::size_t(k)], ply_swap);
          if (has_normals)
            for (int k = 0; k < 3; ++k)
              n[k] = ply_read(&ply_body[offs[std::size_t(k + 3)]], ply_types[std::size_t(k + 3)], ply_swap);
          if (!p.allFinite()) throw FileError(name + ": vertex " + std::to_string(i) + " is not finite");
          positions.push_back(p);
          normals.push_back(n);
          ply_offsets.push_back(offs);
        } else if (e.name == "face") {
          faces.push_back(std::move(face));
        }
      }
    }
    if (off != size)
      throw FileError(name + ": " + std::to_string(size - off) + " bytes of trailing data after the last PLY element");
  } else {
    lines = split_lines(std::string_view(text).substr(body_start + 1), path);
    std::size_t li = 0, tk = 0;
    std::vector<std::string_view> tok;
    auto advance = [&]() -> std::pair<std::string_view, Slot> {
      while (li < lines.size()) {
        if (tk == 0) tok = split(lines[li]);
        if (tk < tok.size()) {
          Slot s{li, std::uint32_t(tk)};
          return {tok[tk++], s};
        }
        ++li;
        tk = 0;
      }
      throw FileError(name + ": PLY body ends early");
    };
    const std::size_t header_lines = hlines.size();
    auto body_where = [&](const Slot& s) { return name + ":" + std::to_string(header_lines + s.line + 1) + ": "; };
    for (const auto& e : elements) {
      for (std::size_t i = 0; i < e.count; ++i) {
        std::array<Slot, 6> slots{};
        Vec3 p = Vec3::Zero(), n = Vec3::Zero();
        std::vector<std::uint32_t> face;
        for (std::size_t pi = 0; pi < e.props.size(); ++pi) {
          const auto& pr = e.props[pi];
          if (!pr.list) {
            auto [t, s] = advance();
            double v;
            if (!parse_double(t, v)) throw FileError(body_where(s) + "'" + detail::cut(t) + "' is not a number");
            if (&e == vertex)
              for (int k = 0; k < 6; ++k)
                if (idx[k] == int(pi)) {
                  if (!std::isfinite(v))
                    throw FileError(body_where(s) + "'" + detail::cut(t) + "' is not a finite number");
                  slots[std::size_t(k)] = s;
                  (k < 3 ? p[k] : n[k - 3]) = v;
                }
          } else {
            auto [t, s] = advance();
            std::size_t c = 0;
            if (!parse_int(t, c)) throw FileError(body_where(s) + "bad list length '" + detail::cut(t) + "'");
            const bool is_face = e.name == "face" && (pr.name == "vertex_indices" || pr.name == "vertex_index");
            if (c > body_bytes / 2)
              throw FileError(body_where(s) + "list length " + detail::cut(t) + " is longer than the file");
            if (is_face && c < 3)
              throw FileError(body_where(s) + "a face has " + detail::cut(t) + " vertices; a face needs at least 3");
            for (std::size_t j = 0; j < c; ++j) {
              auto [t2, s2] = advance();
              if (is_face) {
                std::uint32_t v = 0;
                if (!parse_int(t2, v)) throw FileError(body_where(s2) + "bad vertex index '" + detail::cut(t2) + "'");
                face.push_back(v);
              }
            }
          }
        }
        if (&e == vertex) {
          positions.push_back(p);
          normals.push_back(n);
          position_slots.push_back({slots[0], slots[1], slots[2]});
          if (has_normals) normal_slots.push_back({slots[3], slots[4], slots[5]});
        } else if (e.name == "face") {
          faces.push_back(std::move(face));
        }
      }
    }
    for (; li < lines.size(); ++li, tk = 0) {
      if (tk == 0) tok = split(lines[li]);
      if (tk < tok.size())
        throw FileError(name + ":" + std::to_string(header_lines + li + 1) +
                        ": trailing data after the last PLY element: '" + detail::cut(lines[li]) + "'");
    }
  }
  check_faces();
}

void MeshDocument::Impl::load_assimp(double max_bytes) {
  if (format == MeshFormat::Gltf || format == MeshFormat::Glb)
    detail::check_gltf(path, format == MeshFormat::Glb, max_bytes);
  importer = std::make_unique<Assimp::Importer>();
  auto* io = new LimitedIOSystem(max_bytes);  // owned by the importer
  importer->SetIOHandler(io);
  unsigned flags = aiProcess_PreTransformVertices | aiProcess_ValidateDataStructure;
  // STL repeats every vertex for each facet with the facet's normal: drop the normals so that the
  // copies of one vertex are joined (they are recomputed on output).
  if (format == MeshFormat::Stl) flags |= aiProcess_DropNormals | aiProcess_JoinIdenticalVertices;
  // Read first without post-processing, so that a non-finite vertex is found before joining or
  // cleaning steps can drop or merge it.
  const aiScene* raw = importer->ReadFile(path.string(), aiProcess_ValidateDataStructure);
  if (!raw)
    throw FileError(path.string() + ": cannot read mesh: " +
                    (io->error().empty() ? std::string(importer->GetErrorString()) : io->error()));
  for (unsigned m = 0; m < raw->mNumMeshes; ++m)
    for (unsigned v = 0; v < raw->mMeshes[m]->mNumVertices; ++v) {
      const aiVector3D& p = raw->mMeshes[m]->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw FileError(path.string() + ": mesh " + std::to_string(m) + " vertex " + std::to_string(v) +
                        " is not finite (" + format_number(p.x) + " " + format_number(p.y) + " " + format_number(p.z) +
                        ")");
    }
  const aiScene* scene = importer->ApplyPostProcessing(flags & ~unsigned(aiProcess_ValidateDataStructure));
  if (!scene) throw FileError(path.string() + ": cannot read mesh: " + importer->GetErrorString());
  if (scene->mNumMeshes == 0) throw FileError(path.string() + ": the file holds no mesh");
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    const auto base = std::uint32_t(positions.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const Vec3 p(mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z);
      // assimp passes NaN through, and a node's scale of 1e39 overflows single precision.
      if (!p.allFinite())
        throw FileError(path.string() + ": mesh " + std::to_string(m) + " vertex " + std::to_string(v) +
                        " is not finite (" + format_number(p.x()) + " " + format_number(p.y()) + " " +
                        format_number(p.z()) + ")");
      positions.push_back(p);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices < 3) continue;
      std::vector<std::uint32_t> out(face.mIndices, face.mIndices + face.mNumIndices);
      for (auto& i : out) i += base;
      faces.push_back(std::move(out));
    }
    has_normals = has_normals || mesh->mNormals != nullptr;
  }
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
        ply_write(&body[ply_offsets[i][std::size_t(k)]], ply_types[std::size_t(k)], ply_swap, positions[i][k]);
      if (has_normals)
        for (int k = 0; k < 3; ++k)
          ply_write(&body[ply_offsets[i][std::size_t(k + 3)]], ply_types[std::size_t(k + 3)], ply_swap, vn[i][k]);
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

namespace {

std::unique_ptr<aiScene> make_scene(const std::vector<Vec3>& p, const std::vector<std::vector<std::uint32_t>>& faces,
                                    bool triangulate) {
  auto scene = std::make_unique<aiScene>();
  scene->mRootNode = new aiNode();
  scene->mRootNode->mNumMeshes = 1;
  scene->mRootNode->mMeshes = new unsigned[1]{0};
  scene->mNumMaterials = 1;
  scene->mMaterials = new aiMaterial* [1] { new aiMaterial() };
  auto* mesh = new aiMesh();
  scene->mNumMeshes = 1;
  scene->mMeshes = new aiMesh* [1] { mesh };
  mesh->mMaterialIndex = 0;
  mesh->mNumVertices = unsigned(p.size());
  mesh->mVertices = new aiVector3D[p.size()];
  for (std::size_t i = 0; i < p.size(); ++i)
    mesh->mVertices[i] = aiVector3D(ai_real(p[i].x()), ai_real(p[i].y()), ai_real(p[i].z()));
  std::vector<std::vector<std::uint32_t>> polys;
  for (const auto& f : faces) {
    if (triangulate && f.size() > 3)
      for (std::size_t k = 1; k + 1 < f.size(); ++k) polys.push_back({f[0], f[k], f[k + 1]});
    else
      polys.push_back(f);
  }
  mesh->mNumFaces = unsigned(polys.size());
  mesh->mFaces = new aiFace[polys.size()];
  bool poly = false;
  for (std::size_t i = 0; i < polys.size(); ++i) {
    mesh->mFaces[i].mNumIndices = unsigned(polys[i].size());
    mesh->mFaces[i].mIndices = new unsigned[polys[i].size()];
    std::copy(polys[i].begin(), polys[i].end(), mesh->mFaces[i].mIndices);
    poly = poly || polys[i].size() > 3;
  }
  mesh->mPrimitiveTypes = aiPrimitiveType_TRIANGLE | (poly ? aiPrimitiveType_POLYGON : 0);
  return scene;
}

const char* assimp_export_id(MeshFormat f) {
  switch (f) {
    case MeshFormat::Stl:
      return "stlb";
    case MeshFormat::Gltf:
      return "gltf2";
    case MeshFormat::Glb:
      return "glb2";
    default:
      return nullptr;
  }
}

/// assimp's exporters do not check their writes: this file system records every short write, and
/// every failed flush or close, so that a full disk or a file size limit fails the export.
class CheckedIOSystem : public Assimp::IOSystem {
 public:
  class Stream : public Assimp::IOStream {
   public:
    Stream(std::FILE* f, CheckedIOSystem& sys, std::string name) : f_(f), sys_(sys), name_(std::move(name)) {}
    ~Stream() override {
      if (std::fflush(f_) != 0) sys_.fail(name_, errno);
      if (std::ferror(f_)) sys_.fail(name_, errno ? errno : EIO);
      if (std::fclose(f_) != 0) sys_.fail(name_, errno);
    }
    size_t Read(void* buf, size_t size, size_t count) override { return std::fread(buf, size, count, f_); }
    size_t Write(const void* buf, size_t size, size_t count) override {
      const size_t n = std::fwrite(buf, size, count, f_);
      if (n != count) sys_.fail(name_, errno);
      return n;
    }
    aiReturn Seek(size_t offset, aiOrigin origin) override {
      const int w = origin == aiOrigin_SET ? SEEK_SET : origin == aiOrigin_CUR ? SEEK_CUR : SEEK_END;
      return std::fseek(f_, long(offset), w) == 0 ? aiReturn_SUCCESS : aiReturn_FAILURE;
    }
    size_t Tell() const override { return size_t(std::ftell(f_)); }
    size_t FileSize() const override {
      const long here = std::ftell(f_);
      std::fseek(f_, 0, SEEK_END);
      const long end = std::ftell(f_);
      std::fseek(f_, here, SEEK_SET);
      return size_t(end);
    }
    void Flush() override {
      if (std::fflush(f_) != 0) sys_.fail(name_, errno);
    }

   private:
    std::FILE* f_;
    CheckedIOSystem& sys_;
    std::string name_;
  };

  bool Exists(const char* file) const override { return fs::exists(file); }
  char getOsSeparator() const override { return '/'; }
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    std::FILE* f = std::fopen(file, mode);
    if (!f) {
      fail(file, errno);
      return nullptr;
    }
    return new Stream(f, *this, fs::path(file).filename().string());
  }
  void Close(Assimp::IOStream* s) override { delete s; }

  void fail(const std::string& name, int err) {
    if (error_.empty())
      error_ = "writing '" + name + "' failed: " + std::strerror(err ? err : EIO) + " (disk full or file size limit?)";
  }
  const std::string& error() const { return error_; }

 private:
  std::string error_;
};

void export_scene(const aiScene* scene, const fs::path& out, MeshFormat f) {
  const char* id = assimp_export_id(f);
  write_atomically_via_folder(out, [&](const fs::path& tmp) {
    Assimp::Exporter exporter;
    auto* io = new CheckedIOSystem;  // owned by the exporter
    exporter.SetIOHandler(io);
    const aiReturn r = exporter.Export(scene, id, tmp.string());
    if (!io->error().empty()) throw FileError("cannot write '" + out.string() + "': " + io->error());
    if (r != AI_SUCCESS) {
      const std::string why = exporter.GetErrorString();
      throw FileError("cannot write '" + out.string() + "': " + format_name(f) + " export failed" +
                      (why.empty() ? std::string(" (assimp gave no reason)") : ": " + why));
    }
  });
}

}  // namespace

void MeshDocument::Impl::save_generic(const fs::path& out, MeshFormat f) const {
  switch (f) {
    case MeshFormat::Obj:
      write_atomically(out, [&](std::ostream& os) {
        os << "# written by csrbf\n";
        for (const auto& p : positions)
          os << "v " << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
        for (const auto& face : faces) {
          os << 'f';
          for (auto v : face) os << ' ' << v + 1;
          os << '\n';
        }
      });
      return;
    case MeshFormat::Off:
      write_atomically(out, [&](std::ostream& os) {
        os << "OFF\n" << positions.size() << ' ' << faces.size() << " 0\n";
        for (const auto& p : positions)
          os << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
        for (const auto& face : faces) {
          os << face.size();
          for (auto v : face) os << ' ' << v;
          os << '\n';
        }
      });
      return;
    case MeshFormat::Ply:
      write_atomically(out, [&](std::ostream& os) {
        os << "ply\nformat ascii 1.0\ncomment written by csrbf\nelement vertex " << positions.size()
           << "\nproperty double x\nproperty double y\nproperty double z\nelement face " << faces.size()
           << "\nproperty list uchar int vertex_indices\nend_header\n";
        for (const auto& p : positions)
          os << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
        for (const auto& face : faces) {
          os << face.size();
          for (auto v : face) os << ' ' << v;
          os << '\n';
        }
      });
      return;
    case MeshFormat::Xyz:
      write_atomically(out, [&](std::ostream& os) {
        for (const auto& p : positions)
          os << format_number(p.x()) << ' ' << format_number(p.y()) << ' ' << format_number(p.z()) << '\n';
      });
      return;
    case MeshFormat::Stl:
    case MeshFormat::Gltf:
    case MeshFormat::Glb: {
      if (faces.empty())
        throw FileError("cannot write '" + out.string() + "': " + format_name(f) +
                        " needs faces and the mesh has none");
      const auto scene = make_scene(positions, faces, f == MeshFormat::Stl);
      export_scene(scene.get(), out, f);
      return;
    }
    case MeshFormat::Assimp:
      break;
  }
  throw FileError("cannot write '" + out.string() + "': unknown output format '" + out.extension().string() +
                  "' (use .obj, .ply, .off, .xyz, .stl, .gltf or .glb)");
}

MeshDocument MeshDocument::load(const fs::path& path, double memory_limit_bytes) {
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->format = format_for(path);
  // A mesh takes up to about 12 times its file's size once read (a text file's lines and where each
  // number is; a binary file's faces as vectors, and assimp's copies).
  const double max_file = memory_limit_bytes / 12;
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
        const auto size = fs::file_size(path, ec);
        if (!ec && double(size) > max_file)
          throw FileError(path.string() + ": " + std::to_string(size) +
                          " bytes is more than the memory limit allows (--memory-limit)");
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
const std::vector<std::vector<std::uint32_t>>& MeshDocument::faces() const noexcept { return impl_->faces; }
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
  if (impl_->importer && assimp_export_id(out) && out != MeshFormat::Stl) {
    // Keep the scene assimp read (materials, texture coordinates, ...) and change its positions.
    auto* scene = const_cast<aiScene*>(impl_->importer->GetScene());
    std::size_t base = 0;
    const auto vn = impl_->vertex_normals();
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
      aiMesh* mesh = scene->mMeshes[m];
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const Vec3& p = impl_->positions[base + v];
        mesh->mVertices[v] = aiVector3D(ai_real(p.x()), ai_real(p.y()), ai_real(p.z()));
        if (mesh->mNormals)
          mesh->mNormals[v] =
              aiVector3D(ai_real(vn[base + v].x()), ai_real(vn[base + v].y()), ai_real(vn[base + v].z()));
      }
      base += mesh->mNumVertices;
    }
    return export_scene(scene, path, out);
  }
  impl_->save_generic(path, out);
}

}  // namespace csrbf::io
