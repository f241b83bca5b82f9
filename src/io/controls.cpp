#include "csrbf/io/controls.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "text.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

namespace csrbf::io {

std::string format_number(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

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

Controls parse_controls(std::istream& in, const std::string& name) {
  Controls c;
  c.name = name;
  std::map<std::array<double, 3>, std::size_t> seen;  // source -> index into c
  std::string line;
  int lineno = 0;
  std::size_t duplicates = 0;
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
    const Vec3 s(v[0], v[1], v[2]), d(v[3], v[4], v[5]);
    const std::array<double, 3> key{v[0] == 0.0 ? 0.0 : v[0], v[1] == 0.0 ? 0.0 : v[1], v[2] == 0.0 ? 0.0 : v[2]};
    if (auto it = seen.find(key); it != seen.end()) {
      const std::size_t k = it->second;
      if (c.destinations[k] == d) {
        if (++duplicates <= kMaxWarnings)
          c.warnings.push_back(where + "duplicate of line " + std::to_string(c.lines[k]) +
                               " (same source and destination); merged");
        continue;
      }
      throw FileError(where + "source (" + format_number(v[0]) + ", " + format_number(v[1]) + ", " +
                      format_number(v[2]) + ") is also on line " + std::to_string(c.lines[k]) +
                      " with a different destination; one point cannot move to two places");
    }
    seen.emplace(key, c.sources.size());
    c.sources.push_back(s);
    c.destinations.push_back(d);
    c.lines.push_back(lineno);
  }
  if (duplicates > kMaxWarnings)
    c.warnings.push_back(name + ": " + std::to_string(duplicates - kMaxWarnings) + " more duplicate lines merged (" +
                         std::to_string(duplicates) + " in all)");
  if (in.bad()) throw FileError(name + ": read error");
  if (c.sources.empty()) throw FileError(name + ": no control vectors (expected lines 'sx sy sz dx dy dz')");
  return c;
}

Controls read_controls(const std::filesystem::path& path, double max_bytes) {
  // 1 GiB holds about 1.5e7 controls; a larger file is refused before it is read.
  std::istringstream in(read_input(path, "a controls file", std::min(max_bytes, double(1ull << 30))));
  return parse_controls(in, path.string());
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
