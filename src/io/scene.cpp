#include "csrbf/io/scene.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/io/memory.hpp"

#include "csrbf/io/deformation.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/names.hpp"
#include "json_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <set>
#include <map>
#include <numbers>
#include <sstream>

namespace csrbf::io {
namespace {

namespace fs = std::filesystem;
using detail::JsonNode;

/// Times of keys[i].time, strictly increasing; errors name the key.
double key_time(const JsonNode& keys, std::size_t i, double previous) {
  const JsonNode t = keys[i]["time"];
  const double v = t.number();
  if (i > 0 && !(v > previous)) {
    std::ostringstream m;
    m << "keys must be in time order: " << v << " is not after the previous key's " << previous;
    t.fail(m.str());
  }
  return v;
}

constexpr std::size_t kMaxLights = 16;
// Bounds on a scene's counts, far above any real scene, so that a small file cannot ask for
// gigabytes (60 000 deformations in 2.7 MB did).
constexpr std::size_t kMaxObjects = 1000, kMaxParts = 256, kMaxDeformations = 64;
constexpr std::uint64_t kMaxTextureSide = 16384, kMaxTexturePixels = std::uint64_t(1) << 26;

/// The texture's header, read before any image library sees the file: a PNG or JPEG of at most
/// 16384 pixels a side and 2^26 pixels in all (256 MiB as RGBA).
void check_texture(const JsonNode& t, const fs::path& file) {
  std::string why;
  const auto [w, h] = texture_size(file, &why);
  if (!why.empty()) t.fail(why);
  if (w == 0 || h == 0 || w > kMaxTextureSide || h > kMaxTextureSide || w * h > kMaxTexturePixels)
    t.fail("texture file '" + file.string() + "' is " + std::to_string(w) + "x" + std::to_string(h) +
           " pixels; textures must be 1 to 16384 pixels a side and at most 67108864 pixels in all");
  // The whole file, before an image library decodes it: libpng under VTK crashes on a PNG cut short
  // (a segmentation fault, not an error), so a damaged image must be told here.
  const std::string problem = texture_problem(file);
  if (!problem.empty()) t.fail("texture file '" + file.string() + "' is damaged: " + problem);
}

void read_material(const JsonNode& n, const fs::path& base, anim::Material& m) {
  if (n.has("color")) m.color = n["color"].color();
  if (n.has("opacity")) m.opacity = n["opacity"].number(0.0, 1.0);
  if (n.has("specular")) m.specular = n["specular"].number(0.0, 1.0);
  if (n.has("texture")) {
    const JsonNode t = n["texture"];
    const fs::path file = base / t.string();
    std::error_code ec;
    if (!fs::exists(file, ec)) t.fail("texture file '" + file.string() + "' does not exist");
    if (!fs::is_regular_file(file, ec)) t.fail("texture file '" + file.string() + "' is not a regular file");
    check_texture(t, file);
    m.texture = file.string();
  }
  if (n.has("texture_mapping")) {
    const JsonNode t = n["texture_mapping"];
    const std::string s = t.string();
    if (s == "sphere")
      m.mapping = anim::TextureMapping::Sphere;
    else if (s == "plane")
      m.mapping = anim::TextureMapping::Plane;
    else if (s == "cylinder")
      m.mapping = anim::TextureMapping::Cylinder;
    else
      t.expected("one of \"sphere\", \"plane\", \"cylinder\"");
  }
}

anim::PositionTrack read_trajectory(const JsonNode& n) {
  n.only({"ends", "keys"});
  anim::TrackEnds ends = anim::TrackEnds::Natural;
  if (n.has("ends")) {
    const std::string s = n["ends"].string();
    if (s == "natural")
      ends = anim::TrackEnds::Natural;
    else if (s == "still")
      ends = anim::TrackEnds::Still;
    else
      n["ends"].expected("\"natural\" or \"still\"");
  }
  const JsonNode keys = n["keys"];
  if (keys.size() == 0) keys.fail("at least one key is needed");
  std::vector<anim::PositionKey> out;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const JsonNode k = keys[i];
    k.only({"time", "position", "tension", "continuity", "bias"});
    anim::PositionKey key;
    key.time = key_time(keys, i, out.empty() ? 0.0 : out.back().time);
    key.position = k["position"].vec3();
    if (k.has("tension")) key.tension = k["tension"].number(-1.0, 1.0);
    if (k.has("continuity")) key.continuity = k["continuity"].number(-1.0, 1.0);
    if (k.has("bias")) key.bias = k["bias"].number(-1.0, 1.0);
    out.push_back(key);
  }
  return anim::PositionTrack(std::move(out), ends);
}

anim::OrientationTrack read_orientation(const JsonNode& n) {
  n.only({"interpolation", "keys"});
  anim::Rotation mode = anim::Rotation::Squad;
  if (n.has("interpolation")) {
    const std::string s = n["interpolation"].string();
    if (s == "squad")
      mode = anim::Rotation::Squad;
    else if (s == "slerp")
      mode = anim::Rotation::Slerp;
    else
      n["interpolation"].expected("\"squad\" or \"slerp\"");
  }
  const JsonNode keys = n["keys"];
  if (keys.size() == 0) keys.fail("at least one key is needed");
  std::vector<anim::OrientationKey> out;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const JsonNode k = keys[i];
    k.only({"time", "quaternion", "axis", "angle"});
    anim::OrientationKey key;
    key.time = key_time(keys, i, out.empty() ? 0.0 : out.back().time);
    if (k.has("quaternion") == (k.has("axis") || k.has("angle")))
      k.fail("give either \"quaternion\": [w, x, y, z] or \"axis\": [x, y, z] with \"angle\" in degrees");
    if (k.has("quaternion")) {
      const JsonNode q = k["quaternion"];
      if (q.size() != 4) q.expected("[w, x, y, z]");
      Eigen::Quaterniond v(q[std::size_t{0}].number(), q[1].number(), q[2].number(), q[3].number());
      // Scaled by its largest component first, so that [1e200, 1e200, 0, 0] normalises instead of
      // overflowing.
      const double big = v.coeffs().cwiseAbs().maxCoeff();
      if (!(big > 0)) q.fail("the quaternion is zero");
      v.coeffs() /= big;
      if (v.norm() < 1e-12) q.fail("the quaternion is zero");
      key.rotation = v.normalized();
    } else {
      const Vec3 axis = k["axis"].vec3();
      if (axis.norm() < 1e-12) k["axis"].fail("the axis is zero");
      const double angle = k["angle"].number() * std::numbers::pi / 180.0;
      key.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
    }
    out.push_back(key);
  }
  return anim::OrientationTrack(std::move(out), mode);
}

anim::PhaseTrack read_phase(const JsonNode& n) {
  if (n.json().is_number()) return anim::PhaseTrack({anim::PhaseKey{0.0, n.number()}});
  if (!n.json().is_object()) n.expected("a number or {\"easing\": ..., \"keys\": [{\"time\": t, \"phase\": p}, ...]}");
  n.only({"easing", "keys"});
  anim::PhaseEasing easing = anim::PhaseEasing::Smooth;
  if (n.has("easing")) {
    const std::string s = n["easing"].string();
    if (s == "smooth")
      easing = anim::PhaseEasing::Smooth;
    else if (s == "linear")
      easing = anim::PhaseEasing::Linear;
    else
      n["easing"].expected("\"smooth\" or \"linear\"");
  }
  const JsonNode keys = n["keys"];
  if (keys.size() == 0) keys.fail("at least one key is needed");
  std::vector<anim::PhaseKey> out;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const JsonNode k = keys[i];
    k.only({"time", "phase"});
    const double t = key_time(keys, i, out.empty() ? 0.0 : out.back().time);
    out.push_back({t, k["phase"].number()});
  }
  return anim::PhaseTrack(std::move(out), easing);
}

struct PendingContact {
  std::size_t object, part, deformation;
  JsonNode node;
  std::string collider;
};

anim::Deformation read_deformation_entry(const JsonNode& n, const fs::path& base, std::vector<PendingContact>& contacts,
                                         std::size_t object, std::size_t part, std::size_t index,
                                         const std::vector<Vec3>& rest, double memory_limit_bytes) {
  n.only({"name", "deformation", "controls", "sources", "destinations", "radius", "kernel", "polynomial", "phase",
          "contact", "active_area"});
  anim::Deformation def;
  def.name = n.has("name") ? n["name"].string() : "deformation " + std::to_string(index);
  if (n.has("phase")) def.schedule = read_phase(n["phase"]);
  const int sources = int(n.has("deformation")) + int(n.has("controls") || n.has("sources") || n.has("destinations")) +
                      int(n.has("contact"));
  if (sources != 1)
    n.fail(
        "give exactly one of \"deformation\" (a deformation JSON file), \"controls\" (a controls file), "
        "\"sources\" with \"destinations\", or \"contact\"");
  if (n.has("contact")) {
    const JsonNode c = n["contact"];
    c.only({"collider", "collider_radius", "spread"});
    anim::Contact contact;
    contact.collider_radius = c["collider_radius"].positive();
    if (c.has("spread")) contact.spread = c["spread"].number(0.0, 10.0);
    def.contact = contact;
    def.options.radius = n["radius"].positive();
    def.options.memory_limit_bytes = memory_limit_bytes;  // each frame's fit
    if (n.has("kernel")) {
      const auto k = parse_kernel(n["kernel"].string());
      if (!k) n["kernel"].expected("one of " + names_text<Kernel>("\""));
      def.options.kernel = *k;
    }
    if (n.has("polynomial")) n["polynomial"].fail("a contact deformation has no polynomial (it must stay local)");
    if (n.has("active_area")) n["active_area"].fail("a contact deformation acts on its whole part");
    contacts.push_back({object, part, index, c["collider"], c["collider"].string()});
    return def;
  }
  DeformationSpec spec;
  if (n.has("deformation")) {
    for (const char* k : {"radius", "kernel", "polynomial", "active_area"})
      if (n.has(k)) n[k].fail("set in the deformation file; remove it here");
    const JsonNode f = n["deformation"];
    try {
      spec = read_deformation(base / f.string(), memory_limit_bytes / 16.0);
    } catch (const FileError& e) {
      f.fail(e.what());
    }
  } else {
    spec = detail::parse_deformation(n, base);
  }
  if (spec.area) {
    const JsonNode where = n.has("active_area") ? n["active_area"] : n["deformation"];
    try {
      check_active_area(*spec.area, rest, "this deformation", "this object's mesh");
    } catch (const FileError& e) {
      where.fail(e.what());
    }
    def.area = std::move(spec.area->vertices);
  }
  try {
    // The fit gets what the program, the meshes and the fits before it leave of the limit.
    spec.options.memory_limit_bytes = memory_left(memory_limit_bytes);
    def.map = spec.fit();
  } catch (const InvalidInput& e) {
    n.fail(std::string("cannot fit this deformation: ") + e.what());
  } catch (const std::runtime_error& e) {
    n.fail(std::string("cannot fit this deformation: ") + e.what());
  }
  return def;
}

/// Vertex and face sets of a part from "vertices", "group" or "material" (or the whole mesh).
void read_part_selection(const JsonNode& n, const MeshDocument& mesh, anim::Part& part) {
  const auto& faces = mesh.faces();
  const std::size_t nv = mesh.positions().size();
  const int ways = int(n.has("vertices")) + int(n.has("group")) + int(n.has("material"));
  if (ways > 1) n.fail("give at most one of \"vertices\", \"group\", \"material\"");
  std::vector<char> in(nv, 0);
  if (n.has("group") || n.has("material")) {
    const bool group = n.has("group");
    const JsonNode g = group ? n["group"] : n["material"];
    const std::string name = g.string();
    const auto& table = group ? mesh.groups() : mesh.materials();
    const auto it = table.find(name);
    if (it == table.end()) {
      std::string list;
      for (const auto& [k, v] : table) list += (list.empty() ? "" : ", ") + k;
      g.fail("the mesh has no " + std::string(group ? "group" : "material") + " '" + name +
             "' (it has: " + (list.empty() ? std::string("none") : list) + ")");
    }
    part.faces = it->second;
    for (const auto f : part.faces)
      for (const auto v : faces[f]) in[v] = 1;
  } else {
    if (n.has("vertices")) {
      const JsonNode list = n["vertices"];
      if (list.size() == 0) list.fail("at least one vertex is needed");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const std::size_t v = list[i].index();
        if (v >= nv)
          list[i].fail("vertex " + std::to_string(v) + " is out of range (the mesh has " + std::to_string(nv) + ")");
        in[v] = 1;
      }
    } else {
      std::fill(in.begin(), in.end(), 1);
    }
    for (std::size_t f = 0; f < faces.size(); ++f)
      if (std::all_of(faces[f].begin(), faces[f].end(), [&](std::uint32_t v) { return in[v] != 0; }))
        part.faces.push_back(std::uint32_t(f));
  }
  for (std::size_t v = 0; v < nv; ++v)
    if (in[v]) part.vertices.push_back(std::uint32_t(v));
}

}  // namespace

namespace {

anim::Scene read_scene_json(const nlohmann::json& j, const std::string& file, const fs::path& base,
                            double memory_limit_bytes) {
  const JsonNode root(j, file);
  root.only({"format", "version", "duration", "fps", "background", "camera", "lights", "objects"});
  if (root.has("format") && root["format"].string() != "csrbf-scene") root["format"].expected("\"csrbf-scene\"");
  if (root.has("version") && root["version"].number() != 1) root["version"].expected("1");

  anim::Scene scene;
  scene.duration = root["duration"].positive();
  if (root.has("fps")) scene.fps = root["fps"].number(0.1, 1000.0);
  if (root.has("background")) scene.background = root["background"].color();
  if (root.has("camera")) {
    const JsonNode c = root["camera"];
    c.only({"position", "focal_point", "view_up", "view_angle"});
    if (c.has("position")) scene.camera.position = c["position"].vec3();
    if (c.has("focal_point")) scene.camera.focal_point = c["focal_point"].vec3();
    if (c.has("view_up")) scene.camera.view_up = c["view_up"].vec3();
    if (c.has("view_angle")) scene.camera.view_angle = c["view_angle"].number(1.0, 179.0);
    if ((scene.camera.position - scene.camera.focal_point).norm() < 1e-12)
      c.fail("position and focal_point are the same point");
    if (scene.camera.view_up.cross(scene.camera.position - scene.camera.focal_point).norm() < 1e-12)
      c["view_up"].fail("view_up is zero or parallel to the direction of view");
  }
  if (root.has("lights")) {
    const JsonNode ls = root["lights"];
    if (ls.size() > kMaxLights)
      ls.fail("at most " + std::to_string(kMaxLights) + " lights are rendered, got " + std::to_string(ls.size()));
    for (std::size_t i = 0; i < ls.size(); ++i) {
      const JsonNode l = ls[i];
      l.only({"position", "color", "intensity", "headlight"});
      anim::Light light;
      if (l.has("headlight")) light.headlight = l["headlight"].boolean();
      if (l.has("position"))
        light.position = l["position"].vec3();
      else if (!light.headlight)
        l.fail("a light needs \"position\" (or \"headlight\": true)");
      if (l.has("color")) light.color = l["color"].color();
      if (l.has("intensity")) light.intensity = l["intensity"].number(0.0, 100.0);
      scene.lights.push_back(light);
    }
  }

  const JsonNode objects = root["objects"];
  if (objects.size() == 0) objects.fail("at least one object is needed");
  if (objects.size() > kMaxObjects)
    objects.fail("at most " + std::to_string(kMaxObjects) + " objects, got " + std::to_string(objects.size()));
  std::vector<PendingContact> contacts;
  std::map<std::string, std::size_t> names;
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const JsonNode on = objects[o];
    on.only({"name", "mesh", "color", "opacity", "specular", "texture", "texture_mapping", "trajectory", "orientation",
             "parts"});
    anim::Object obj;
    obj.name = on.has("name") ? on["name"].string() : "object " + std::to_string(o);
    if (!names.emplace(obj.name, o).second) on["name"].fail("another object is already named '" + obj.name + "'");
    const JsonNode mn = on["mesh"];
    const fs::path mesh_path = base / mn.string();
    std::optional<MeshDocument> mesh;
    try {
      mesh.emplace(MeshDocument::load(mesh_path, memory_limit_bytes));
    } catch (const FileError& e) {
      mn.fail(e.what());
    }
    if (mesh->positions().empty()) mn.fail("the mesh '" + mesh_path.string() + "' has no vertices");
    obj.rest = mesh->positions();
    obj.faces = mesh->faces();
    read_material(on, base, obj.material);
    if (on.has("trajectory")) obj.trajectory = read_trajectory(on["trajectory"]);
    if (on.has("orientation")) obj.orientation = read_orientation(on["orientation"]);
    if (on.has("parts")) {
      const JsonNode ps = on["parts"];
      if (ps.size() > kMaxParts)
        ps.fail("at most " + std::to_string(kMaxParts) + " parts, got " + std::to_string(ps.size()));
      for (std::size_t p = 0; p < ps.size(); ++p) {
        const JsonNode pn = ps[p];
        pn.only({"name", "vertices", "group", "material", "color", "opacity", "specular", "texture", "texture_mapping",
                 "combine", "deformations"});
        anim::Part part;
        part.name = pn.has("name") ? pn["name"].string() : "part " + std::to_string(p);
        part.material = obj.material;
        read_material(pn, base, part.material);
        read_part_selection(pn, *mesh, part);
        if (pn.has("combine")) {
          const std::string s = pn["combine"].string();
          if (s == "compose")
            part.combine = anim::Combine::Compose;
          else if (s == "sum")
            part.combine = anim::Combine::Sum;
          else
            pn["combine"].expected("\"compose\" or \"sum\"");
        }
        if (pn.has("deformations")) {
          const JsonNode ds = pn["deformations"];
          if (ds.size() > kMaxDeformations)
            ds.fail("at most " + std::to_string(kMaxDeformations) + " deformations a part, got " +
                    std::to_string(ds.size()));
          for (std::size_t d = 0; d < ds.size(); ++d)
            part.deformations.push_back(
                read_deformation_entry(ds[d], base, contacts, o, p, d, mesh->positions(), memory_limit_bytes));
        }
        obj.parts.push_back(std::move(part));
      }
    }
    obj.finalize();
    scene.objects.push_back(std::move(obj));
  }
  for (const auto& c : contacts) {
    const auto it = names.find(c.collider);
    if (it == names.end()) c.node.fail("no object is named '" + c.collider + "'");
    if (it->second == c.object) c.node.fail("an object cannot collide with itself");
    scene.objects[c.object].parts[c.part].deformations[c.deformation].contact->collider = it->second;
  }
  return scene;
}

}  // namespace

anim::Scene read_scene(const fs::path& path, double memory_limit_bytes) {
  // Its tree takes about 7 times its text: a 124 MB scene peaked at 804 MB under a limit of 0.1 GiB.
  // A limit below what the program holds is told as such (memory_left), not as a JSON too large.
  const nlohmann::json j = detail::read_json_file(path, memory_left(memory_limit_bytes) / 8.0);
  return read_scene_json(j, path.string(), path.parent_path(), memory_limit_bytes);
}

anim::Scene read_scene_text(const std::string& text, const std::string& name, const fs::path& base,
                            double memory_limit_bytes) {
  return read_scene_json(detail::parse_json(text, name), name, base, memory_limit_bytes);
}

}  // namespace csrbf::io
