#include "csrbf/io/controls.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "text.hpp"

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

Controls parse_controls(std::istream& in, const std::string& name) {
  Controls c;
  c.name = name;
  std::map<std::array<double, 3>, std::size_t> seen;  // source -> index into c
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    std::string_view body(line);
    if (const auto h = body.find('#'); h != std::string_view::npos) body = body.substr(0, h);
    body = detail::trim(body);
    if (body.empty()) continue;
    const auto tok = detail::split(body);
    const std::string where = name + ":" + std::to_string(lineno) + ": ";
    if (tok.size() != 6)
      throw FileError(where + "expected 6 numbers 'sx sy sz dx dy dz', got " + std::to_string(tok.size()) +
                      " fields: '" + std::string(body) + "'");
    double v[6];
    for (int k = 0; k < 6; ++k) {
      if (!detail::parse_double(tok[k], v[k]))
        throw FileError(where + "'" + std::string(tok[k]) + "' is not a number (line: '" + std::string(body) + "')");
      if (!std::isfinite(v[k]))
        throw FileError(where + "'" + std::string(tok[k]) + "' is not a finite number (line: '" + std::string(body) + "')");
    }
    const Vec3 s(v[0], v[1], v[2]), d(v[3], v[4], v[5]);
    const std::array<double, 3> key{v[0] == 0.0 ? 0.0 : v[0], v[1] == 0.0 ? 0.0 : v[1], v[2] == 0.0 ? 0.0 : v[2]};
    if (auto it = seen.find(key); it != seen.end()) {
      const std::size_t k = it->second;
      if (c.destinations[k] == d) {
        c.warnings.push_back(where + "duplicate of line " + std::to_string(c.lines[k]) + " (same source and destination); merged");
        continue;
      }
      throw FileError(where + "source (" + format_number(v[0]) + ", " + format_number(v[1]) + ", " + format_number(v[2]) +
                      ") is also on line " + std::to_string(c.lines[k]) +
                      " with a different destination; one point cannot move to two places");
    }
    seen.emplace(key, c.sources.size());
    c.sources.push_back(s);
    c.destinations.push_back(d);
    c.lines.push_back(lineno);
  }
  if (in.bad()) throw FileError(name + ": read error");
  if (c.sources.empty()) throw FileError(name + ": no control vectors (expected lines 'sx sy sz dx dy dz')");
  return c;
}

Controls read_controls(const std::filesystem::path& path) {
  check_readable(path, "a controls file");
  std::ifstream in(path);
  if (!in) throw FileError(path.string() + ": cannot open for reading");
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
