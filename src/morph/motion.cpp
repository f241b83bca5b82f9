#include "csrbf/morph/motion.hpp"

#include "../io/json_reader.hpp"
#include "../io/text.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/names.hpp"

#include <Eigen/Geometry>

#include <charconv>
#include <cmath>
#include <sstream>

namespace fs = std::filesystem;

namespace csrbf::morph {

Vec3 PatchMotion::displacement(const Vec3& x) const {
  switch (kind) {
    case Kind::Translate:
      return translation;
    case Kind::Rotate: {
      const Eigen::AngleAxisd r(degrees * M_PI / 180.0, axis);
      return origin + r * (x - origin) - x;
    }
    default:
      return Vec3::Zero();
  }
}

namespace {

using io::FileError;
using io::detail::JsonNode;

void read_displacements(PatchMotion& m, const fs::path& base) {
  const fs::path path = m.file.is_absolute() ? m.file : base / m.file;
  m.file = path;
  const std::string text = io::read_input(path, "a displacements file");
  std::size_t line = 0, at = 0;
  const std::string name = path.string();
  while (at < text.size()) {
    ++line;
    std::size_t e = text.find('\n', at);
    if (e == std::string::npos) e = text.size();
    std::string_view l(text.data() + at, e - at);
    at = e + 1;
    if (line == 1) l = io::detail::skip_bom(l);
    if (const auto hash = l.find('#'); hash != std::string_view::npos) l = l.substr(0, hash);
    const auto fields = io::detail::split(io::detail::trim(l));
    if (fields.empty()) continue;
    const std::string where = name + ":" + std::to_string(line) + ": ";
    if (fields.size() != 4)
      throw FileError(where + "expected 'point_id dx dy dz', got " + std::to_string(fields.size()) + " fields: '" +
                      io::detail::cut(l) + "'");
    PatchMotion::Given g{};
    g.line = line;
    const auto r = std::from_chars(fields[0].data(), fields[0].data() + fields[0].size(), g.point);
    if (r.ec != std::errc() || r.ptr != fields[0].data() + fields[0].size())
      throw FileError(where + "point id '" + io::detail::cut(fields[0]) + "' is not a non-negative integer");
    for (int c = 0; c < 3; ++c) {
      double v = 0;
      const auto& f = fields[std::size_t(c) + 1];
      const auto rr = std::from_chars(f.data(), f.data() + f.size(), v);
      if (rr.ec != std::errc() || rr.ptr != f.data() + f.size() || !std::isfinite(v))
        throw FileError(where + "'" + io::detail::cut(f) + "' is not a finite number");
      g.d[c] = v;
    }
    m.given.push_back(g);
  }
  if (m.given.empty()) throw FileError(name + ": no displacements (expected lines 'point_id dx dy dz')");
}

}  // namespace

Motion read_motion(const fs::path& path) {
  const nlohmann::json j = io::detail::read_json_file(path);
  return motion_from_json(j, path.string(), path.has_parent_path() ? path.parent_path() : fs::path("."));
}

std::string PatchMotion::source() const { return file.empty() ? where + ".displacements" : file.string(); }

std::string PatchMotion::at(const Given& g) const {
  return file.empty() ? where + ".displacements[" + std::to_string(g.line - 1) + "]: "
                      : file.string() + ":" + std::to_string(g.line) + ": ";
}

Motion motion_from_json(const nlohmann::json& j, const std::string& name, const fs::path& base) {
  Motion m;
  m.file = name;
  const JsonNode root(j, m.file);
  if (!j.is_object()) root.expected("an object with \"patches\"");
  root.only({"radius", "kernel", "polynomial", "patch_array", "patches"});
  if (root.has("patch_array")) {
    m.patch_array = root["patch_array"].string();
    if (m.patch_array.empty()) root["patch_array"].expected("the name of an integer point or cell data array");
  }
  if (root.has("radius")) {
    if (root["radius"].json().is_string() && root["radius"].json().get<std::string>() == "auto")
      m.radius_auto = true;
    else if (root["radius"].json().is_string())
      root["radius"].expected("a number > 0 or \"auto\"");
    else
      m.radius = root["radius"].number(1e-150, 1e150);
  }
  if (root.has("kernel")) {
    const auto k = parse_name<Kernel>(root["kernel"].string());
    if (!k) root["kernel"].expected("a kernel (c0, c2, c4, c6)");
    m.kernel = *k;
  }
  if (root.has("polynomial")) {
    const auto p = parse_name<Polynomial>(root["polynomial"].string());
    if (!p) root["polynomial"].expected("a polynomial (none, constant, linear)");
    m.polynomial = *p;
  }
  const JsonNode patches = root["patches"];
  if (!patches.json().is_object() || patches.json().empty())
    patches.expected("an object naming at least one patch, e.g. {\"wall\": \"fixed\"}");
  for (const auto& [name, value] : patches.json().items()) {
    const JsonNode node = patches[name.c_str()];
    PatchMotion pm;
    pm.patch = name;
    pm.where = m.file + ": " + node.path();
    if (value.is_string()) {
      const std::string kind = value.get<std::string>();
      if (kind != "fixed" && kind != "slip" && kind != "free")
        node.expected("\"fixed\", \"slip\", \"free\", or an object with translate, rotate or displacements");
      pm.kind = kind == "slip"   ? PatchMotion::Kind::Slip
                : kind == "free" ? PatchMotion::Kind::Free
                                 : PatchMotion::Kind::Fixed;
    } else if (value.is_object() && value.size() == 1) {
      node.only({"translate", "rotate", "displacements"});
      if (node.has("translate")) {
        pm.kind = PatchMotion::Kind::Translate;
        pm.translation = node["translate"].vec3();
      } else if (node.has("rotate")) {
        pm.kind = PatchMotion::Kind::Rotate;
        const JsonNode r = node["rotate"];
        r.only({"axis", "degrees", "origin"});
        const Vec3 axis = r["axis"].vec3();
        if (!(axis.norm() > 1e-300)) r["axis"].fail("the axis is zero; give a direction, e.g. [0, 0, 1]");
        pm.axis = axis.normalized();
        pm.degrees = r["degrees"].number(-1e6, 1e6);
        if (r.has("origin")) pm.origin = r["origin"].vec3();
      } else {
        pm.kind = PatchMotion::Kind::Displacements;
        const JsonNode rows = node["displacements"];
        if (rows.json().is_array()) {  // inline: [[point_id, dx, dy, dz], ...]
          if (rows.size() == 0) rows.expected("rows [point_id, dx, dy, dz], at least one");
          for (std::size_t k = 0; k < rows.size(); ++k) {
            const JsonNode row = rows[k];
            if (!row.json().is_array() || row.size() != 4) row.expected("a row [point_id, dx, dy, dz]");
            PatchMotion::Given g{};
            // A float that is a whole number is one too (numpy's (k, 4) rows are all floats).
            const JsonNode id = row[std::size_t(0)];
            if (id.json().is_number_float()) {
              const double v = id.json().get<double>();
              if (!(v >= 0 && v < 9.007199254740992e15 && v == std::floor(v)))
                id.expected("a point id, an integer >= 0");
              g.point = std::uint64_t(v);
            } else {
              g.point = id.index();
            }
            for (int c = 0; c < 3; ++c) g.d[c] = row[std::size_t(c) + 1].number();
            g.line = k + 1;
            pm.given.push_back(g);
          }
        } else {
          pm.file = rows.string();
          if (pm.file.empty())
            rows.expected("the name of a file of 'point_id dx dy dz' lines, or rows [point_id, dx, dy, dz]");
          read_displacements(pm, base);
        }
      }
    } else {
      node.expected("\"fixed\", \"slip\", or an object with one of translate, rotate, displacements");
    }
    m.patches.push_back(std::move(pm));
  }
  return m;
}

}  // namespace csrbf::morph
