// OBJ, OFF and XYZ: read keeping every line, so that a save rewrites only the numbers; and the line
// helpers every text format shares.
#include "mesh_impl.hpp"

#include "csrbf/io/controls.hpp"
#include "text.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace fs = std::filesystem;

namespace csrbf::io {

using detail::parse_double;
using detail::parse_int;
using detail::split;
using detail::trim;

namespace detail {

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

std::string_view strip_comment(std::string_view s) {
  if (const auto h = s.find('#'); h != std::string_view::npos) s = s.substr(0, h);
  return trim(s);
}

}  // namespace detail

using detail::rewrite_line;
using detail::split_lines;
using detail::strip_comment;

void MeshDocument::Impl::load_obj(const std::string& text) {
  lines = split_lines(text, path);
  std::size_t vn_count = 0, vt_count = 0;
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
    } else if (tok[0] == "vt") {
      ++vt_count;  // kept as text; a face's reference to it is checked below
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
          // The texture coordinate ("v/vt" or "v/vt/vn"): written back as it was, so it must name one.
          const auto vt_text = t.substr(s1 + 1, s2 == std::string_view::npos ? std::string_view::npos : s2 - s1 - 1);
          if (!vt_text.empty()) {
            std::int64_t ti = 0;
            if (!parse_int(vt_text, ti) || ti == 0)
              throw FileError(where(li) + "bad texture coordinate reference '" + detail::cut(t) + "'");
            if (ti < 0) ti += std::int64_t(vt_count) + 1;
            if (ti < 1 || ti > std::int64_t(vt_count))
              throw FileError(where(li) + "texture coordinate reference '" + detail::cut(t) + "' is out of range (" +
                              std::to_string(vt_count) + " texture coordinates so far)");
          }
          if (s2 != std::string_view::npos && t.find('/', s2 + 1) != std::string_view::npos)
            throw FileError(where(li) + "bad vertex reference '" + detail::cut(t) + "' (v, v/vt, v//vn or v/vt/vn)");
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

}  // namespace csrbf::io
