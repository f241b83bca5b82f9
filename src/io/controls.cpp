#include "csrbf/io/controls.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/io/memory.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/units.hpp"
#include "text.hpp"

#include <algorithm>
#include <cstdio>
#include <streambuf>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace csrbf::io {

std::string format_number(double v) { return format_shortest(v); }

namespace {
constexpr std::size_t kMaxLine = 1 << 16;  // a control line is about 100 bytes
constexpr std::size_t kMaxWarnings = 10;   // then one line that counts the rest

/// One line, without its '\n' (and '\r'); false at the end. A line past kMaxLine bytes is an error,
/// so that a file without line breaks is not read into memory whole.
bool next_line(std::istream& in, std::string& line, const std::string& name, int lineno) {
  line.clear();
  std::streambuf* sb = in.rdbuf();
  for (;;) {
    const int c = sb->sbumpc();
    if (c == std::char_traits<char>::eof()) {
      if (line.empty()) return false;
      break;
    }
    if (c == '\n') break;
    if (line.size() >= kMaxLine)
      throw FileError(name + ":" + std::to_string(lineno) + ": line longer than " + std::to_string(kMaxLine) +
                      " bytes (not a controls file?)");
    line.push_back(char(c));
  }
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return true;
}
}  // namespace

namespace {
/// The parse, with room reserved for `expected` controls (0: unknown).
Controls parse_reserved(std::istream& in, const std::string& name, std::size_t expected) {
  Controls c;
  c.name = name;
  c.sources.reserve(expected);
  c.destinations.reserve(expected);
  c.lines.reserve(expected);
  std::string line;
  int lineno = 0;
  while (next_line(in, line, name, lineno + 1)) {
    ++lineno;
    std::string_view body(line);
    if (lineno == 1) body = detail::skip_bom(body);
    if (const auto h = body.find('#'); h != std::string_view::npos) body = body.substr(0, h);
    body = detail::trim(body);
    if (body.empty()) continue;
    const auto tok = detail::split(body);
    const std::string where = name + ":" + std::to_string(lineno) + ": ";
    if (tok.size() != 6)
      throw FileError(where + "expected 6 numbers 'sx sy sz dx dy dz', got " + std::to_string(tok.size()) +
                      " fields: '" + detail::cut(body) + "'");
    double v[6];
    for (int k = 0; k < 6; ++k) {
      if (!detail::parse_double(tok[k], v[k]))
        throw FileError(where + "'" + detail::cut(tok[k]) + "' is not a number (line: '" + detail::cut(body) + "')");
      if (!std::isfinite(v[k]))
        throw FileError(where + "'" + detail::cut(tok[k]) + "' is not a finite number (line: '" + detail::cut(body) +
                        "')");
    }
    // -0 is 0: the same point.
    c.sources.emplace_back(v[0] == 0.0 ? 0.0 : v[0], v[1] == 0.0 ? 0.0 : v[1], v[2] == 0.0 ? 0.0 : v[2]);
    c.destinations.emplace_back(v[3], v[4], v[5]);
    c.lines.push_back(lineno);
  }
  if (in.bad()) throw FileError(name + ": read error");
  if (c.sources.empty()) throw FileError(name + ": no control vectors (expected lines 'sx sy sz dx dy dz')");

  // One source, one destination: the controls in the order of their sources (then lines), each
  // compared with the first of its source. A sort of 4-byte indices where a tree of every source
  // took about 80 bytes a control (3e6 controls went 3.6 times past --memory-limit).
  const std::size_t n = c.sources.size();
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
  const auto key = [&](std::uint32_t i) {
    return std::array<double, 3>{c.sources[i].x(), c.sources[i].y(), c.sources[i].z()};
  };
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    const auto ka = key(a), kb = key(b);
    return ka != kb ? ka < kb : a < b;
  });
  std::vector<char> merged(n, 0);
  std::size_t conflict = n, conflict_with = n;  // the first line (in the file) of another destination
  std::vector<std::pair<std::uint32_t, std::uint32_t>> duplicates;  // (control, the first of its source)
  for (std::size_t k = 1, first = 0; k < n; ++k) {
    if (key(order[k]) != key(order[first])) {
      first = k;
      continue;
    }
    const std::uint32_t i = order[k], f = order[first];
    if (c.destinations[i] == c.destinations[f]) {
      merged[i] = 1;
      duplicates.emplace_back(i, f);
    } else if (i < conflict) {
      conflict = i;
      conflict_with = f;
    }
  }
  if (conflict < n) {
    const Vec3& p = c.sources[conflict];
    throw FileError(name + ":" + std::to_string(c.lines[conflict]) + ": source (" + format_number(p.x()) + ", " +
                    format_number(p.y()) + ", " + format_number(p.z()) + ") is also on line " +
                    std::to_string(c.lines[conflict_with]) +
                    " with a different destination; one point cannot move to two places");
  }
  std::sort(duplicates.begin(), duplicates.end());
  for (std::size_t k = 0; k < std::min(duplicates.size(), kMaxWarnings); ++k)
    c.warnings.push_back(name + ":" + std::to_string(c.lines[duplicates[k].first]) + ": duplicate of line " +
                         std::to_string(c.lines[duplicates[k].second]) + " (same source and destination); merged");
  if (duplicates.size() > kMaxWarnings)
    c.warnings.push_back(name + ": " + std::to_string(duplicates.size() - kMaxWarnings) +
                         " more duplicate lines merged (" + std::to_string(duplicates.size()) + " in all)");
  if (!duplicates.empty()) {
    std::size_t kept = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (merged[i]) continue;
      c.sources[kept] = c.sources[i];
      c.destinations[kept] = c.destinations[i];
      c.lines[kept] = c.lines[i];
      ++kept;
    }
    c.sources.resize(kept);
    c.destinations.resize(kept);
    c.lines.resize(kept);
  }
  return c;
}

/// A read-only stream over a string, without copying it (std::istringstream copies).
struct ViewBuffer : std::streambuf {
  explicit ViewBuffer(std::string& s) { setg(s.data(), s.data(), s.data() + s.size()); }
};
}  // namespace

Controls parse_controls(std::istream& in, const std::string& name) { return parse_reserved(in, name, 0); }

Controls read_controls(const std::filesystem::path& path, double memory_limit_bytes) {
  // The text within what the limit leaves (1 GiB at most, about 1.5e7 controls), then the controls
  // within what is left beside it: a line is at most one control of 52 bytes (source, destination,
  // line number), and the duplicate check's 4-byte index and 1-byte mark.
  const double text_room = std::min(memory_left(memory_limit_bytes), kGiB);
  std::string text = read_input(path, "a controls file", text_room);
  const std::size_t lines = std::size_t(std::count(text.begin(), text.end(), '\n')) + 1;
  const double need = 57.0 * double(lines);
  const double left = memory_left(memory_limit_bytes);
  if (need > left) {
    char m[400];
    std::snprintf(m, sizeof m,
                  ": %zu lines would take about %.3g GiB as controls, more than the %.3g GiB that --memory-limit "
                  "leaves beside the file's text; give --memory-limit %.2f or more",
                  lines, need / kGiB, left / kGiB, std::ceil(100 * (memory_limit_bytes - left + need) / kGiB) / 100);
    throw FileError(path.string() + m);
  }
  ViewBuffer buffer(text);
  std::istream in(&buffer);
  return parse_reserved(in, path.string(), lines);
}

void write_controls(const std::filesystem::path& path, const std::vector<Vec3>& sources,
                    const std::vector<Vec3>& destinations) {
  write_atomically(path, [&](std::ostream& out) {
    out << "# csrbf controls: sx sy sz dx dy dz\n";
    for (std::size_t i = 0; i < sources.size(); ++i) {
      const Vec3& s = sources[i];
      const Vec3& d = destinations[i];
      out << format_number(s.x()) << ' ' << format_number(s.y()) << ' ' << format_number(s.z()) << ' '
          << format_number(d.x()) << ' ' << format_number(d.y()) << ' ' << format_number(d.z()) << '\n';
    }
  });
}

}  // namespace csrbf::io
