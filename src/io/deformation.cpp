#include "csrbf/io/deformation.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/names.hpp"
#include "json_reader.hpp"

#include <algorithm>
#include <limits>

namespace csrbf::io {
namespace detail {

DeformationSpec parse_deformation(const JsonNode& node, const std::filesystem::path& base) {
  DeformationSpec spec;
  spec.options.radius = node["radius"].positive();
  if (node.has("kernel")) {
    const auto k = parse_kernel(node["kernel"].string());
    if (!k) node["kernel"].expected("one of " + names_text<Kernel>("\""));
    spec.options.kernel = *k;
  }
  if (node.has("polynomial")) {
    const auto p = parse_polynomial(node["polynomial"].string());
    if (!p) node["polynomial"].expected("one of " + names_text<Polynomial>("\""));
    spec.options.polynomial = *p;
  }
  const bool inline_points = node.has("sources") || node.has("destinations");
  if (node.has("controls") == inline_points)
    node.fail("give either \"controls\" (a controls file) or \"sources\" and \"destinations\"");
  if (inline_points) {
    const JsonNode s = node["sources"], d = node["destinations"];
    if (s.size() == 0) s.fail("at least one control is needed");
    if (d.size() != s.size())
      d.fail("has " + std::to_string(d.size()) + " points but sources has " + std::to_string(s.size()));
    for (std::size_t i = 0; i < s.size(); ++i) {
      spec.sources.push_back(s[i].vec3());
      spec.destinations.push_back(d[i].vec3());
    }
  } else {
    const JsonNode c = node["controls"];
    const std::filesystem::path file = base / c.string();
    Controls controls;
    try {
      controls = read_controls(file);
    } catch (const FileError& e) {
      c.fail(e.what());
    }
    spec.sources = std::move(controls.sources);
    spec.destinations = std::move(controls.destinations);
  }
  if (node.has("active_area")) {
    const JsonNode a = node["active_area"];
    a.only({"vertex_count", "vertices", "bounds"});
    ActiveArea area;
    area.vertex_count = a["vertex_count"].index();
    if (area.vertex_count == 0 || area.vertex_count > std::numeric_limits<std::uint32_t>::max())
      a["vertex_count"].expected("a vertex count from 1 to 4294967295");
    const JsonNode v = a["vertices"];
    if (v.size() == 0)
      v.fail("an active area needs at least one vertex (leave \"active_area\" out for the whole mesh)");
    area.vertices.reserve(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      const std::size_t k = v[i].index();
      if (k >= area.vertex_count)
        v[i].fail("vertex " + std::to_string(k) + " is not below vertex_count " + std::to_string(area.vertex_count));
      if (!area.vertices.empty() && k <= area.vertices.back())
        v[i].fail("vertices must be sorted and unique (" + std::to_string(k) + " follows " +
                  std::to_string(area.vertices.back()) + ")");
      area.vertices.push_back(std::uint32_t(k));
    }
    if (a.has("bounds")) {
      const JsonNode b = a["bounds"];
      if (b.size() != 2) b.expected("[[xmin, ymin, zmin], [xmax, ymax, zmax]]");
      const std::array<Vec3, 2> box = {b[std::size_t(0)].vec3(), b[std::size_t(1)].vec3()};
      if (!(box[0].array() <= box[1].array()).all()) b.fail("the first corner must not exceed the second");
      area.bounds = box;
    }
    spec.area = std::move(area);
  }
  return spec;
}

}  // namespace detail

namespace {
DeformationSpec from_json(const nlohmann::json& j, const std::string& name, const std::filesystem::path& base) {
  const detail::JsonNode root(j, name);
  root.only({"format", "version", "kernel", "radius", "polynomial", "sources", "destinations", "controls",
             "active_area", "phase"});
  if (root.has("format") && root["format"].string() != "csrbf-deformation")
    root["format"].expected("\"csrbf-deformation\"");
  if (root.has("version") && root["version"].number() != 1) root["version"].expected("1");
  DeformationSpec spec = detail::parse_deformation(root, base);
  if (root.has("phase")) spec.phase = root["phase"].number(0.0, 1.0);
  return spec;
}
}  // namespace

DeformationSpec read_deformation(const std::filesystem::path& path, double max_bytes) {
  return from_json(detail::read_json_file(path, max_bytes), path.string(), path.parent_path());
}

DeformationSpec read_deformation_text(const std::string& text, const std::string& name,
                                      const std::filesystem::path& base) {
  return from_json(detail::parse_json(text, name), name, base);
}

void write_deformation(const std::filesystem::path& path, const DeformationSpec& spec) {
  if (spec.sources.size() != spec.destinations.size())
    throw FileError(path.string() + ": sources and destinations differ in number");
  const auto point = [](const Vec3& p) {
    std::string s("[");  // appended, not "[" + ...: GCC 12 warns falsely (-Wrestrict) on the latter
    s += format_number(p.x());
    s += ", ";
    s += format_number(p.y());
    s += ", ";
    s += format_number(p.z());
    s += "]";
    return s;
  };
  write_atomically(path, [&](std::ostream& out) {
    out << "{\n  \"format\": \"csrbf-deformation\",\n  \"version\": 1,\n"
        << "  \"kernel\": \"" << kernel_name(spec.options.kernel) << "\",\n"
        << "  \"radius\": " << format_number(spec.options.radius) << ",\n"
        << "  \"polynomial\": \"" << polynomial_name(spec.options.polynomial) << "\",\n";
    if (spec.phase) out << "  \"phase\": " << format_number(*spec.phase) << ",\n";
    for (int which = 0; which < 2; ++which) {
      const auto& pts = which == 0 ? spec.sources : spec.destinations;
      out << "  \"" << (which == 0 ? "sources" : "destinations") << "\": [";
      for (std::size_t i = 0; i < pts.size(); ++i) out << (i ? ",\n    " : "\n    ") << point(pts[i]);
      out << "\n  ]" << (which == 0 || spec.area ? ",\n" : "\n");
    }
    if (spec.area) {
      out << "  \"active_area\": {\"vertex_count\": " << spec.area->vertex_count << ", \"vertices\": [";
      for (std::size_t i = 0; i < spec.area->vertices.size(); ++i)
        out << (i == 0 ? "" : i % 16 == 0 ? ",\n    " : ", ") << spec.area->vertices[i];
      out << "]";
      if (spec.area->bounds)
        out << ",\n    \"bounds\": [" << point((*spec.area->bounds)[0]) << ", " << point((*spec.area->bounds)[1])
            << "]";
      out << "}\n";
    }
    out << "}\n";
  });
}

namespace {
/// The box (min, max corners) of rest[v] over the vertices v (not empty).
std::array<Vec3, 2> bounds_of(const std::vector<Vec3>& rest, const std::vector<std::uint32_t>& vertices) {
  std::array<Vec3, 2> box = {rest.at(vertices.front()), rest.at(vertices.front())};
  for (const auto v : vertices) {
    box[0] = box[0].cwiseMin(rest.at(v));
    box[1] = box[1].cwiseMax(rest.at(v));
  }
  return box;
}
}  // namespace

ActiveArea ActiveArea::of(const std::vector<Vec3>& rest, std::vector<std::uint32_t> vertices) {
  ActiveArea a;
  a.vertex_count = rest.size();
  if (!vertices.empty()) a.bounds = bounds_of(rest, vertices);
  a.vertices = std::move(vertices);
  return a;
}

void check_active_area(const ActiveArea& area, const std::vector<Vec3>& rest, const std::string& where,
                       const std::string& mesh) {
  if (rest.size() != area.vertex_count)
    throw FileError(where + ": active_area: the deformation was picked on a mesh of " +
                    std::to_string(area.vertex_count) + " vertices, " + mesh + " has " + std::to_string(rest.size()));
  if (!area.bounds || area.vertices.empty()) return;
  const std::array<Vec3, 2> here = bounds_of(rest, area.vertices);
  const auto& want = *area.bounds;
  const double scale =
      std::max({(want[1] - want[0]).norm(), want[0].cwiseAbs().maxCoeff(), want[1].cwiseAbs().maxCoeff()});
  const double off = std::max((here[0] - want[0]).cwiseAbs().maxCoeff(), (here[1] - want[1]).cwiseAbs().maxCoeff());
  if (!(off <= 1e-6 * scale))
    throw FileError(where + ": active_area: its vertices of " + mesh +
                    " are not where they were picked (their bounds "
                    "differ by " +
                    format_number(off) +
                    "): the mesh's vertices are in another order, as an STL or a "
                    "re-exported file may have them; use the mesh the deformation was made on");
}

void apply_deformation(const SpaceMap& map, const std::optional<ActiveArea>& area, std::vector<Vec3>& positions,
                       double phase) {
  if (!area) {
    map.apply(positions, positions, phase);
    return;
  }
  std::vector<Vec3> part;
  part.reserve(area->vertices.size());
  for (const auto v : area->vertices) part.push_back(positions.at(v));
  map.apply(part, part, phase);
  for (std::size_t i = 0; i < part.size(); ++i) positions[area->vertices[i]] = part[i];
}

}  // namespace csrbf::io
