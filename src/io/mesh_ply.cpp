// PLY, ASCII and binary (either byte order): elements bounded by what the file can hold, and
// positions and normals kept where they sit, so that a save rewrites only those bytes or numbers.
#include "mesh_impl.hpp"

#include "csrbf/io/controls.hpp"
#include "csrbf/units.hpp"
#include "text.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace csrbf::io {

using detail::parse_double;
using detail::parse_int;
using detail::split;
using detail::split_lines;
using detail::trim;

namespace detail {

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
/// The least and largest value of an integer type.
std::pair<double, double> integer_range(PlyType t) {
  switch (t) {
    case PlyType::I8:
      return {-128.0, 127.0};
    case PlyType::U8:
      return {0.0, 255.0};
    case PlyType::I16:
      return {-32768.0, 32767.0};
    case PlyType::U16:
      return {0.0, 65535.0};
    case PlyType::I32:
      return {-2147483648.0, 2147483647.0};
    default:
      return {0.0, 4294967295.0};
  }
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

static void reverse_bytes(unsigned char* b, std::size_t n) { std::reverse(b, b + n); }

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

}  // namespace detail

using detail::ply_read;
using detail::ply_size;
using detail::ply_type;

namespace {

using Impl = MeshDocument::Impl;

// What the PLY header says, shared by the phases of load_ply. The vertex pointer points into
// elements, so a plan is filled in place and never copied.
struct PlyPlan {
  std::string name;            // the file's path, for messages
  std::size_t body_start = 0;  // the '\n' that ends the header
  std::size_t body_bytes = 0;
  std::size_t header_lines = 0;
  std::vector<PlyElement> elements;
  const PlyElement* vertex = nullptr;
  std::size_t face_count = 0;
  int idx[6] = {-1, -1, -1, -1, -1, -1};  // the vertex's properties x y z nx ny nz, or -1
};

bool is_face_list(const PlyElement& e, const PlyProperty& pr) {
  return e.name == "face" && (pr.name == "vertex_indices" || pr.name == "vertex_index");
}

void read_format_line(Impl& m, const std::vector<std::string_view>& tok, std::size_t li, const std::string& line) {
  if (tok.size() < 2) throw FileError(m.where(li) + "bad format line '" + line + "'");
  if (tok[1] == "ascii")
    m.ply_binary = false;
  else if (tok[1] == "binary_little_endian") {
    m.ply_binary = true;
    m.ply_swap = std::endian::native != std::endian::little;
  } else if (tok[1] == "binary_big_endian") {
    m.ply_binary = true;
    m.ply_swap = std::endian::native != std::endian::big;
  } else
    throw FileError(m.where(li) + "unknown PLY format '" + std::string(tok[1]) + "'");
  // PLY has one version (found by the attacker's trial: "binary_little_endian 9.9" was read as 1.0).
  if (tok.size() != 3 || tok[2] != "1.0")
    throw FileError(m.where(li) + "PLY format version '" + (tok.size() > 2 ? std::string(tok[2]) : std::string()) +
                    "' (only 1.0 exists)");
}

PlyProperty read_property_line(const Impl& m, const std::vector<std::string_view>& tok, std::size_t li,
                               const std::string& line) {
  PlyProperty p;
  if (tok.size() == 5 && tok[1] == "list") {
    const auto ct = ply_type(tok[2]), it = ply_type(tok[3]);
    if (!ct || !it) throw FileError(m.where(li) + "unknown PLY type in '" + line + "'");
    p.list = true;
    p.count_type = *ct;
    p.type = *it;
    p.name = std::string(tok[4]);
  } else if (tok.size() == 3) {
    const auto t = ply_type(tok[1]);
    if (!t) throw FileError(m.where(li) + "unknown PLY type '" + std::string(tok[1]) + "'");
    p.type = *t;
    p.name = std::string(tok[2]);
  } else {
    throw FileError(m.where(li) + "bad property line '" + line + "'");
  }
  return p;
}

void read_ply_header(Impl& m, const std::string& text, PlyPlan& plan) {
  const std::string& name = plan.name;
  if (text.compare(0, 3, "ply") != 0) throw FileError(name + ": not a PLY file (no 'ply' magic)");
  const auto end = text.find("end_header");
  if (end == std::string::npos) throw FileError(name + ": PLY header has no 'end_header'");
  const auto body_start = text.find('\n', end);
  if (body_start == std::string::npos) throw FileError(name + ": PLY file ends after its header");
  plan.body_start = body_start;
  m.ply_header = text.substr(0, body_start + 1);
  const auto hlines = split_lines(m.ply_header, m.path);
  plan.header_lines = hlines.size();
  auto& elements = plan.elements;
  bool format_seen = false;
  for (std::size_t li = 1; li < hlines.size(); ++li) {
    const auto tok = split(hlines[li]);
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info" || tok[0] == "end_header") continue;
    if (tok[0] == "format") {
      read_format_line(m, tok, li, hlines[li]);
      format_seen = true;
    } else if (tok[0] == "element") {
      PlyElement e;
      if (tok.size() != 3 || !parse_int(tok[2], e.count))
        throw FileError(m.where(li) + "bad element line '" + hlines[li] + "'");
      e.name = std::string(tok[1]);
      elements.push_back(std::move(e));
    } else if (tok[0] == "property") {
      if (elements.empty()) throw FileError(m.where(li) + "property before any element");
      elements.back().props.push_back(read_property_line(m, tok, li, hlines[li]));
    } else {
      throw FileError(m.where(li) + "unknown PLY header keyword '" + std::string(tok[0]) + "'");
    }
  }
  if (!format_seen) throw FileError(name + ": PLY header has no 'format' line");
  plan.body_bytes = text.size() - (body_start + 1);
}

// Counts come from the header and are not trusted: each is bounded by what the body can hold
// before anything is allocated, and a list's length and indices must be integers.
void check_ply_counts(const Impl& m, const PlyPlan& plan) {
  const std::string& name = plan.name;
  const auto& elements = plan.elements;
  const std::size_t body_bytes = plan.body_bytes;
  for (std::size_t a = 0; a < elements.size(); ++a) {
    const auto& e = elements[a];
    for (std::size_t b = 0; b < a; ++b)
      if (elements[b].name == e.name) throw FileError(name + ": PLY header declares element '" + e.name + "' twice");
    for (std::size_t p = 0; p < e.props.size(); ++p)
      for (std::size_t q = 0; q < p; ++q)
        if (e.props[q].name == e.props[p].name)
          throw FileError(name + ": PLY header declares property '" + e.props[p].name + "' of element '" + e.name +
                          "' twice");
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
        least += m.ply_binary ? ply_size(pr.count_type) : 1;
      } else {
        least += m.ply_binary ? ply_size(pr.type) : 1;
      }
    }
    // An ASCII token takes at least 2 bytes with its separator.
    const std::size_t room = m.ply_binary ? body_bytes : (body_bytes + 1) / 2;
    if (least > 0 && e.count > room / least)
      throw FileError(name + ": PLY element '" + e.name + "' declares " + std::to_string(e.count) +
                      " entries but the file's body (" + std::to_string(body_bytes) + " bytes) can hold at most " +
                      std::to_string(room / least));
  }
}

// The vertex element and where its positions and normals sit; the face element's count.
void find_vertex_and_faces(Impl& m, PlyPlan& plan) {
  const std::string& name = plan.name;
  const PlyElement* vertex = nullptr;
  for (const auto& e : plan.elements) {
    if (e.name == "vertex") vertex = &e;
    if (e.name == "face" && e.count > 0 && std::none_of(e.props.begin(), e.props.end(), [](const PlyProperty& p) {
          return p.list && (p.name == "vertex_indices" || p.name == "vertex_index");
        }))
      throw FileError(name + ": PLY element 'face' has no list property 'vertex_indices' (or 'vertex_index')");
  }
  if (!vertex) throw FileError(name + ": PLY file has no 'vertex' element");
  plan.vertex = vertex;
  int* idx = plan.idx;
  const char* names[6] = {"x", "y", "z", "nx", "ny", "nz"};
  for (int k = 0; k < 6; ++k)
    for (std::size_t p = 0; p < vertex->props.size(); ++p)
      if (vertex->props[p].name == names[k] && !vertex->props[p].list) idx[k] = int(p);
  for (int k = 0; k < 3; ++k)
    if (idx[k] < 0) throw FileError(name + ": PLY 'vertex' element has no property '" + names[k] + "'");
  m.has_normals = idx[3] >= 0 && idx[4] >= 0 && idx[5] >= 0;
  for (int k = 0; k < (m.has_normals ? 6 : 3); ++k) {
    const PlyType t = vertex->props[std::size_t(idx[k])].type;
    if (t != PlyType::F32 && t != PlyType::F64)
      throw FileError(name + ": PLY property '" + names[k] + "' must be float or double to be deformed");
    m.ply_types[std::size_t(k)] = t;
  }

  const PlyElement* face_element = nullptr;
  for (const auto& e : plan.elements)
    if (e.name == "face") face_element = &e;
  plan.face_count = face_element ? face_element->count : 0;
}

void check_ply_budget(const Impl& m, const std::string& text, const PlyPlan& plan) {
  // Bounded by the body's size, the counts say what reading will hold: the body's copy; a
  // position, a normal where the file has them, and where they sit (8 bytes, or 48 with list
  // properties in the vertex) a vertex; a face's offset and at least 3 corners (20 bytes).
  const PlyElement* vertex = plan.vertex;
  const bool lists =
      std::any_of(vertex->props.begin(), vertex->props.end(), [](const PlyProperty& p) { return p.list; });
  const double per_vertex = 24.0 + (m.has_normals ? 24.0 : 0.0) + (lists ? 48.0 : 8.0);
  const double predicted = double(plan.body_bytes) + per_vertex * double(vertex->count) +
                           20.0 * double(plan.face_count) + double(text.size());
  if (predicted > m.read_budget) {
    std::ostringstream os;
    os.precision(3);
    os << plan.name << ": its " << vertex->count << " vertices and " << plan.face_count << " faces would take about "
       << predicted / kGiB << " GiB once read, more than the " << m.read_budget / kGiB
       << " GiB that --memory-limit leaves (give a larger --memory-limit)";
    throw FileError(os.str());
  }
}

void reserve_ply_binary(Impl& m, const std::string& text, const PlyPlan& plan) {
  // Reserved as predicted (the counts are checked above), so that no vector doubles past them.
  const PlyElement* vertex = plan.vertex;
  m.positions.reserve(vertex->count);
  if (m.has_normals) m.normals.reserve(vertex->count);
  m.faces.reserve(plan.face_count, 3 * plan.face_count);
  m.ply_fixed_layout =
      std::none_of(vertex->props.begin(), vertex->props.end(), [](const PlyProperty& p) { return p.list; });
  if (m.ply_fixed_layout)
    m.ply_vertex_start.reserve(vertex->count);
  else
    m.ply_offsets.reserve(vertex->count);
  m.ply_body.assign(text.begin() + std::ptrdiff_t(plan.body_start + 1), text.end());
}

void read_ply_binary(Impl& m, const PlyPlan& plan) {
  const std::string& name = plan.name;
  const int* idx = plan.idx;
  const auto& body = m.ply_body;
  std::size_t off = 0;
  const std::size_t size = body.size();
  auto need = [&](std::size_t n, const std::string& what) {
    if (off + n > size) throw FileError(name + ": PLY body ends early, in " + what);
  };
  for (const auto& e : plan.elements) {
    for (std::size_t i = 0; i < e.count; ++i) {
      std::array<std::size_t, 6> offs{};
      const std::size_t start = off;
      std::vector<std::uint32_t> face;
      for (std::size_t p = 0; p < e.props.size(); ++p) {
        const auto& pr = e.props[p];
        const std::string what = e.name + " " + std::to_string(i) + " property '" + pr.name + "'";
        if (!pr.list) {
          need(ply_size(pr.type), what);
          if (&e == plan.vertex)
            for (int k = 0; k < 6; ++k)
              if (idx[k] == int(p)) offs[std::size_t(k)] = off;
          off += ply_size(pr.type);
        } else {
          need(ply_size(pr.count_type), what);
          const double c = ply_read(&body[off], pr.count_type, m.ply_swap);
          off += ply_size(pr.count_type);
          if (c < 0) throw FileError(name + ": negative list length in " + what);
          if (c > double((size - off) / ply_size(pr.type))) throw FileError(name + ": PLY body ends early, in " + what);
          const bool is_face = is_face_list(e, pr);
          if (is_face && c < 3)
            throw FileError(name + ": face " + std::to_string(i) + " has " + std::to_string(std::size_t(c)) +
                            " vertices; a face needs at least 3");
          for (std::size_t j = 0; j < std::size_t(c); ++j) {
            if (is_face) {
              const double v = ply_read(&body[off], pr.type, m.ply_swap);
              if (v < 0 || v > 4294967295.0)
                throw FileError(name + ": vertex index " + std::to_string(std::int64_t(v)) + " out of range in " +
                                what);
              face.push_back(std::uint32_t(v));
            }
            off += ply_size(pr.type);
          }
        }
      }
      if (&e == plan.vertex) {
        Vec3 p, n = Vec3::Zero();
        for (int k = 0; k < 3; ++k)
          p[k] = ply_read(&body[offs[std::size_t(k)]], m.ply_types[std::size_t(k)], m.ply_swap);
        if (m.has_normals)
          for (int k = 0; k < 3; ++k)
            n[k] = ply_read(&body[offs[std::size_t(k + 3)]], m.ply_types[std::size_t(k + 3)], m.ply_swap);
        if (!p.allFinite()) throw FileError(name + ": vertex " + std::to_string(i) + " is not finite");
        m.positions.push_back(p);
        if (m.has_normals) m.normals.push_back(n);
        if (!m.ply_fixed_layout) {
          m.ply_offsets.push_back(offs);
        } else {
          if (i == 0)
            for (std::size_t k = 0; k < 6; ++k) m.ply_relative[k] = offs[k] - start;
          m.ply_vertex_start.push_back(start);
        }
      } else if (e.name == "face") {
        m.faces.push_back(std::move(face));
      }
    }
  }
  if (off != size)
    throw FileError(name + ": " + std::to_string(size - off) + " bytes of trailing data after the last PLY element");
}

void read_ply_ascii(Impl& m, const std::string& text, const PlyPlan& plan) {
  const std::string& name = plan.name;
  const int* idx = plan.idx;
  m.lines = split_lines(std::string_view(text).substr(plan.body_start + 1), m.path);
  const auto& lines = m.lines;
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
  const std::size_t header_lines = plan.header_lines;
  auto body_where = [&](const Slot& s) { return name + ":" + std::to_string(header_lines + s.line + 1) + ": "; };
  for (const auto& e : plan.elements) {
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
          // An integer property holds an integer of its type's range (a uchar of 300, -5 or 1.5 was
          // taken, and written out wrapped).
          if (pr.type != PlyType::F32 && pr.type != PlyType::F64) {
            const auto [lo, hi] = integer_range(pr.type);
            if (!(v >= lo && v <= hi) || v != std::floor(v))
              throw FileError(body_where(s) + "'" + detail::cut(t) + "' is not an integer from " + format_number(lo) +
                              " to " + format_number(hi) + " (property '" + pr.name + "' of element '" + e.name + "')");
          }
          if (&e == plan.vertex)
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
          const bool is_face = is_face_list(e, pr);
          if (c > plan.body_bytes / 2)
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
      if (&e == plan.vertex) {
        m.positions.push_back(p);
        m.normals.push_back(n);
        m.position_slots.push_back({slots[0], slots[1], slots[2]});
        if (m.has_normals) m.normal_slots.push_back({slots[3], slots[4], slots[5]});
      } else if (e.name == "face") {
        m.faces.push_back(std::move(face));
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

}  // namespace

void MeshDocument::Impl::load_ply(const std::string& text) {
  PlyPlan plan;
  plan.name = path.string();
  read_ply_header(*this, text, plan);
  check_ply_counts(*this, plan);
  find_vertex_and_faces(*this, plan);
  if (ply_binary) {
    check_ply_budget(*this, text, plan);
    reserve_ply_binary(*this, text, plan);
    read_ply_binary(*this, plan);
  } else {
    read_ply_ascii(*this, text, plan);
  }
  check_faces();
}

}  // namespace csrbf::io
