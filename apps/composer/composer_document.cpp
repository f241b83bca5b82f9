#include "composer_document.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/io/scene.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>

namespace csrbf::composer {

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Json vec(const Vec3& v) { return Json::array({v.x(), v.y(), v.z()}); }

/// Keys a, b, c ... sorted by "time": the index where t goes, or an error if a key is at t.
std::size_t insertion_index(const Json& keys, double t) {
  std::size_t i = 0;
  while (i < keys.size() && keys[i]["time"].get<double>() < t) ++i;
  if (i < keys.size() && std::abs(keys[i]["time"].get<double>() - t) < 1e-9) {
    std::ostringstream m;
    m << "a key is already at t = " << t << " s";
    throw EditError(m.str());
  }
  return i;
}

/// The paths a scene names, rewritten by f: meshes, textures, controls and deformation files.
template <class F>
void for_each_path(Json& j, F&& f) {
  for (auto& o : j["objects"]) {
    for (const char* k : {"mesh", "texture"})
      if (o.contains(k)) f(o[k]);
    if (!o.contains("parts")) continue;
    for (auto& p : o["parts"]) {
      if (p.contains("texture")) f(p["texture"]);
      if (!p.contains("deformations")) continue;
      for (auto& d : p["deformations"])
        for (const char* k : {"controls", "deformation"})
          if (d.contains(k)) f(d[k]);
    }
  }
}

}  // namespace

Eigen::Quaterniond quaternion_from_angles(double yaw, double pitch, double roll) {
  return Eigen::AngleAxisd(yaw * kDeg, Vec3::UnitY()) * Eigen::AngleAxisd(pitch * kDeg, Vec3::UnitX()) *
         Eigen::AngleAxisd(roll * kDeg, Vec3::UnitZ());
}

Vec3 angles_from_quaternion(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d r = q.normalized().toRotationMatrix();
  // R = Ry(a) Rx(b) Rz(c): r(1,2) = -sin b, r(0,2) = sin a cos b, r(2,2) = cos a cos b,
  // r(1,0) = cos b sin c, r(1,1) = cos b cos c.
  const double b = std::asin(std::clamp(-r(1, 2), -1.0, 1.0));
  double a, c;
  if (std::abs(std::cos(b)) > 1e-9) {
    a = std::atan2(r(0, 2), r(2, 2));
    c = std::atan2(r(1, 0), r(1, 1));
  } else {  // gimbal lock: put it all in yaw
    a = std::atan2(-r(2, 0), r(0, 0));
    c = 0;
  }
  return Vec3(a, b, c) / kDeg;
}

Document::Document() { reset(fs::current_path()); }

void Document::reset(const fs::path& base) {
  base_ = base;
  path_.clear();
  json_ = {{"format", "csrbf-scene"},
           {"version", 1},
           {"duration", 4.0},
           {"fps", 25},
           {"background", {0.1, 0.1, 0.14}},
           {"camera", {{"position", {0.5, 0.8, 3.2}}, {"focal_point", {0.5, 0.5, 0.5}}, {"view_angle", 35}}},
           {"objects", Json::array()}};
}

namespace {

/// Relative paths of `j` from folder `from` rewritten for folder `to` (absolute ones where no
/// relative path leads there).
void rebase(Json& j, const fs::path& from, const fs::path& to) {
  // An empty folder is the current one (a scene opened by a bare name: fs::absolute("") throws).
  const fs::path old_base = fs::absolute(from.empty() ? fs::path(".") : from).lexically_normal(),
                 new_base = fs::absolute(to.empty() ? fs::path(".") : to).lexically_normal();
  if (old_base == new_base) return;
  for_each_path(j, [&](Json& p) {
    if (!p.is_string()) return;
    const fs::path abs =
        fs::path(p.get<std::string>()).is_absolute() ? fs::path(p.get<std::string>()) : old_base / p.get<std::string>();
    const fs::path rel = abs.lexically_normal().lexically_relative(new_base);
    p = rel.empty() ? abs.lexically_normal().string() : rel.string();
  });
}

}  // namespace

void Document::set_json(Json j, const fs::path& from_base) {
  rebase(j, from_base, base_);
  json_ = std::move(j);
}

void Document::adopt(Json j, const fs::path& base, const fs::path& path) {
  json_ = std::move(j);
  if (!json_.contains("objects")) json_["objects"] = Json::array();
  base_ = base;
  path_ = path;
}

void Document::open(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw io::FileError(file.string() + ": cannot open for reading");
  std::ostringstream text;
  text << in.rdbuf();
  {
    // A deformation file is the usual wrong pick here: say what it is and where it goes.
    const Json peek = Json::parse(text.str(), nullptr, false);
    if (peek.is_object() && !peek.contains("objects") &&
        (peek.value("format", "") == "csrbf-deformation" || peek.contains("sources") || peek.contains("controls")))
      throw io::FileError(file.string() +
                          ": this is a deformation file, not a scene. Open or build a scene, select an object and "
                          "attach it with Object > Attach deformation... (Ctrl+D)");
  }
  io::read_scene_text(text.str(), file.string(), file.parent_path());  // the whole check
  json_ = Json::parse(text.str());
  if (!json_.contains("objects")) json_["objects"] = Json::array();
  // Absolute from here on: a bare name ("fish.scene.json") has an empty parent folder.
  path_ = fs::absolute(file).lexically_normal();
  base_ = path_.parent_path();
}

void Document::save(const fs::path& file) {
  const fs::path new_base = fs::absolute(file).parent_path();
  Json out = json_;
  rebase(out, base_, new_base);
  io::write_atomically(file, [&](std::ostream& o) { o << out.dump(1) << '\n'; });
  json_ = std::move(out);
  base_ = new_base;
  path_ = fs::absolute(file).lexically_normal();
}

anim::Scene Document::build() const {
  if (object_count() == 0) {  // a new scene: nothing to read yet (a scene file needs an object)
    anim::Scene empty;
    empty.duration = duration();
    empty.fps = fps();
    return empty;
  }
  const std::string name = path_.empty() ? std::string("(unsaved scene)") : path_.filename().string();
  return io::read_scene_text(json_.dump(), name, base_);
}

std::string Document::relative(const fs::path& file) const {
  const fs::path abs = fs::absolute(file).lexically_normal();
  const fs::path rel = abs.lexically_relative(fs::absolute(base_.empty() ? fs::path(".") : base_));
  return rel.empty() ? abs.string() : rel.string();
}

Json& Document::object(std::size_t i) {
  if (i >= json_["objects"].size()) throw EditError("no object " + std::to_string(i));
  return json_["objects"][i];
}
const Json& Document::object(std::size_t i) const {
  if (i >= json_["objects"].size()) throw EditError("no object " + std::to_string(i));
  return json_["objects"][i];
}

std::size_t Document::object_count() const { return json_["objects"].size(); }
std::string Document::object_name(std::size_t i) const {
  return object(i).value("name", "object " + std::to_string(i));
}
double Document::duration() const { return json_["duration"].get<double>(); }
double Document::fps() const { return json_.value("fps", 25.0); }

double Document::snap(double t) const { return std::round(t * fps()) / fps(); }

Json& Document::deformation_entry(std::size_t o, std::size_t d) {
  if (d >= deformation_count(o)) throw EditError("no deformation " + std::to_string(d));
  return object(o)["parts"][0]["deformations"][d];
}
const Json& Document::deformation_entry(std::size_t o, std::size_t d) const {
  if (d >= deformation_count(o)) throw EditError("no deformation " + std::to_string(d));
  return object(o)["parts"][0]["deformations"][d];
}

std::string Document::deformation_name(std::size_t o, std::size_t d) const {
  return deformation_entry(o, d).value("name", "deformation " + std::to_string(d + 1));
}

void Document::set_deformation_name(std::size_t o, std::size_t d, const std::string& name) {
  if (name.empty()) throw EditError("a deformation needs a name");
  deformation_entry(o, d)["name"] = name;
}

void Document::remove_deformation(std::size_t o, std::size_t d) {
  deformation_entry(o, d);
  Json& ds = object(o)["parts"][0]["deformations"];
  ds.erase(d);
}

std::string Document::combine(std::size_t o) const {
  const Json& obj = object(o);
  if (!obj.contains("parts") || obj["parts"].empty()) return "compose";
  return obj["parts"][0].value("combine", "compose");
}

void Document::set_combine(std::size_t o, const std::string& c) {
  if (c != "sum" && c != "compose") throw EditError("combine must be \"sum\" or \"compose\", got '" + c + "'");
  Json& obj = object(o);
  if (!obj.contains("parts") || obj["parts"].empty()) throw EditError("the object has no deformations to combine");
  obj["parts"][0]["combine"] = c;
}

std::string Document::easing(std::size_t o, std::size_t d) const {
  const Json& e = deformation_entry(o, d);
  if (!e.contains("phase") || !e["phase"].is_object()) return "smooth";
  return e["phase"].value("easing", "smooth");
}

void Document::set_easing(std::size_t o, std::size_t d, const std::string& easing) {
  if (easing != "smooth" && easing != "linear")
    throw EditError("easing must be \"smooth\" or \"linear\", got '" + easing + "'");
  keys(o, Track::Phase, d);  // makes the schedule keyed
  deformation_entry(o, d)["phase"]["easing"] = easing;
}

double Document::phase_value(std::size_t o, std::size_t d, std::size_t key) const {
  const Json& e = deformation_entry(o, d);
  if (!e.contains("phase")) return 1.0;
  if (e["phase"].is_number()) return e["phase"].get<double>();
  const Json& k = e["phase"]["keys"];
  if (key >= k.size()) throw EditError("no phase key " + std::to_string(key));
  return k[key]["phase"].get<double>();
}

void Document::set_phase_value(std::size_t o, std::size_t d, std::size_t key, double phase) {
  if (!std::isfinite(phase) || std::abs(phase) > 1e6) throw EditError("the phase must be a number within +-1e6");
  Json& k = keys(o, Track::Phase, d);
  if (key >= k.size()) throw EditError("no phase key " + std::to_string(key));
  k[key]["phase"] = phase;
}

void Document::remove_phase_key(std::size_t o, std::size_t d, std::size_t key) {
  Json& k = keys(o, Track::Phase, d);
  if (key >= k.size()) throw EditError("no phase key " + std::to_string(key));
  if (k.size() == 1) throw EditError("a schedule keeps at least one key (remove the deformation instead)");
  k.erase(key);
}

void Document::set_camera(const Vec3& position, const Vec3& focal, const Vec3& up, double angle) {
  if (!position.allFinite() || !focal.allFinite() || !up.allFinite() || (position - focal).norm() == 0 ||
      up.norm() == 0)
    throw EditError("the camera needs a position apart from its focal point and a view-up direction");
  if (!(angle > 0 && angle < 180)) throw EditError("the view angle must be in (0, 180) degrees");
  json_["camera"] = {
      {"position", vec(position)}, {"focal_point", vec(focal)}, {"view_up", vec(up)}, {"view_angle", angle}};
}

namespace {
void check_rgb(const Vec3& c) {
  for (int k = 0; k < 3; ++k)
    if (!(c[k] >= 0 && c[k] <= 1)) throw EditError("colour components must be in [0, 1]");
}
Vec3 rgb_of(const Json& j, const Vec3& fallback) {
  if (!j.is_array() || j.size() != 3) return fallback;
  return Vec3(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
}
}  // namespace

void Document::set_background(const Vec3& rgb) {
  check_rgb(rgb);
  json_["background"] = vec(rgb);
}

Vec3 Document::background() const { return rgb_of(json_.value("background", Json()), Vec3(0.1, 0.1, 0.14)); }

void Document::set_object_color(std::size_t o, const Vec3& rgb) {
  check_rgb(rgb);
  Json& obj = object(o);
  obj["color"] = vec(rgb);
  if (obj.contains("parts"))  // the parts' own colours would hide it: the object is one colour now
    for (auto& p : obj["parts"]) p.erase("color");
}

Vec3 Document::object_color(std::size_t o) const {
  return rgb_of(object(o).value("color", Json()), Vec3(0.8, 0.8, 0.8));
}

std::size_t Document::light_count() const { return json_.contains("lights") ? json_["lights"].size() : 0; }

std::size_t Document::add_light(const Vec3& position, double intensity, bool headlight) {
  if (!(intensity >= 0 && intensity <= 10)) throw EditError("a light's intensity must be in [0, 10]");
  if (light_count() >= 16) throw EditError("a scene has at most 16 lights");
  if (!json_.contains("lights")) json_["lights"] = Json::array();
  Json l = headlight ? Json{{"headlight", true}, {"intensity", intensity}}
                     : Json{{"position", vec(position)}, {"intensity", intensity}};
  json_["lights"].push_back(l);
  return json_["lights"].size() - 1;
}

void Document::set_light(std::size_t i, double intensity, const Vec3& rgb) {
  if (i >= light_count()) throw EditError("no light " + std::to_string(i));
  if (!(intensity >= 0 && intensity <= 10)) throw EditError("a light's intensity must be in [0, 10]");
  check_rgb(rgb);
  json_["lights"][i]["intensity"] = intensity;
  json_["lights"][i]["color"] = vec(rgb);
}

void Document::remove_light(std::size_t i) {
  if (i >= light_count()) throw EditError("no light " + std::to_string(i));
  json_["lights"].erase(i);
  if (json_["lights"].empty()) json_.erase("lights");
}

std::string Document::light_label(std::size_t i) const {
  if (i >= light_count()) return {};
  const Json& l = json_["lights"][i];
  std::ostringstream o;
  if (l.value("headlight", false))
    o << "headlight";
  else if (l.contains("position"))
    o << "from (" << l["position"][0].get<double>() << ", " << l["position"][1].get<double>() << ", "
      << l["position"][2].get<double>() << ")";
  o << ", intensity " << l.value("intensity", 1.0);
  return o.str();
}

void Document::set_duration(double s) {
  if (!(s > 0) || !std::isfinite(s)) throw EditError("the duration must be > 0 s");
  json_["duration"] = s;
}

void Document::set_fps(double f) {
  if (!(f >= 0.1 && f <= 1000)) throw EditError("the frame rate must be in 0.1 .. 1000");
  json_["fps"] = f;
}

std::size_t Document::add_object(const fs::path& mesh) {
  const io::MeshDocument m = io::MeshDocument::load(mesh);  // throws FileError with the reason
  if (m.positions().empty()) throw EditError(mesh.string() + ": the mesh has no vertices");
  std::string name = mesh.stem().string();
  for (int k = 2;; ++k) {
    bool taken = false;
    for (const auto& o : json_["objects"]) taken = taken || o.value("name", "") == name;
    if (!taken) break;
    name = mesh.stem().string() + " " + std::to_string(k);
  }
  json_["objects"].push_back({{"name", name}, {"mesh", relative(mesh)}, {"color", {0.85, 0.75, 0.6}}});
  return json_["objects"].size() - 1;
}

void Document::remove_object(std::size_t i) {
  object(i);
  json_["objects"].erase(i);
}

Json& Document::keys(std::size_t o, Track track, std::size_t deformation) {
  Json& obj = object(o);
  switch (track) {
    case Track::Position:
      if (!obj.contains("trajectory")) obj["trajectory"] = {{"keys", Json::array()}};
      return obj["trajectory"]["keys"];
    case Track::Orientation:
      if (!obj.contains("orientation")) obj["orientation"] = {{"interpolation", "squad"}, {"keys", Json::array()}};
      return obj["orientation"]["keys"];
    case Track::Phase: {
      if (deformation >= deformation_count(o)) throw EditError("no deformation " + std::to_string(deformation));
      Json& d = obj["parts"][0]["deformations"][deformation];
      if (!d.contains("phase") || d["phase"].is_number())
        d["phase"] = {{"easing", "smooth"}, {"keys", {{{"time", 0.0}, {"phase", d.value("phase", 1.0)}}}}};
      return d["phase"]["keys"];
    }
  }
  throw EditError("unknown track");
}

std::size_t Document::add_position_key(std::size_t o, double t, const Vec3& p) {
  Json saved = json_;
  Json& k = keys(o, Track::Position, 0);
  try {
    const std::size_t i = insertion_index(k, t);
    k.insert(k.begin() + std::ptrdiff_t(i), Json{{"time", t}, {"position", vec(p)}});
    return i;
  } catch (...) {
    json_ = std::move(saved);
    throw;
  }
}

void Document::set_position(std::size_t o, std::size_t key, const Vec3& p) {
  Json& k = keys(o, Track::Position, 0);
  if (key >= k.size()) throw EditError("no trajectory key " + std::to_string(key));
  k[key]["position"] = vec(p);
}

void Document::set_tcb(std::size_t o, std::size_t key, double t, double c, double b) {
  for (const double v : {t, c, b})
    if (!(v >= -1 && v <= 1)) throw EditError("tension, continuity and bias must be in [-1, 1]");
  Json& k = keys(o, Track::Position, 0);
  if (key >= k.size()) throw EditError("no trajectory key " + std::to_string(key));
  k[key]["tension"] = t;
  k[key]["continuity"] = c;
  k[key]["bias"] = b;
}

void Document::remove_position_key(std::size_t o, std::size_t key) {
  Json& k = keys(o, Track::Position, 0);
  if (key >= k.size()) throw EditError("no trajectory key " + std::to_string(key));
  k.erase(key);
  if (k.empty()) object(o).erase("trajectory");
}

std::size_t Document::set_orientation_key(std::size_t o, double t, double yaw, double pitch, double roll) {
  const Eigen::Quaterniond q = quaternion_from_angles(yaw, pitch, roll);
  const Json value{{"time", t}, {"quaternion", {q.w(), q.x(), q.y(), q.z()}}};
  Json& k = keys(o, Track::Orientation, 0);
  for (std::size_t i = 0; i < k.size(); ++i)
    if (std::abs(k[i]["time"].get<double>() - t) < 1e-9) {
      k[i] = value;
      return i;
    }
  const std::size_t i = insertion_index(k, t);
  k.insert(k.begin() + std::ptrdiff_t(i), value);
  return i;
}

void Document::remove_orientation_key(std::size_t o, std::size_t key) {
  Json& k = keys(o, Track::Orientation, 0);
  if (key >= k.size()) throw EditError("no orientation key " + std::to_string(key));
  k.erase(key);
  if (k.empty()) object(o).erase("orientation");
}

std::size_t Document::deformation_count(std::size_t o) const {
  const Json& obj = object(o);
  if (!obj.contains("parts") || obj["parts"].empty() || !obj["parts"][0].contains("deformations")) return 0;
  return obj["parts"][0]["deformations"].size();
}

std::size_t Document::attach_deformation(std::size_t o, const fs::path& file) {
  {
    // A scene is the usual wrong pick here (both are .json): say what it is and where it goes,
    // before the scene's check names a key it does not expect.
    std::ifstream in(file, std::ios::binary);
    std::string head(1 << 16, '\0');
    in.read(head.data(), std::streamsize(head.size()));
    head.resize(std::size_t(in.gcount()));
    const Json peek = Json::parse(head, nullptr, false);
    const bool scene = peek.is_object() ? peek.contains("objects") || peek.contains("camera")
                                        : head.find("\"objects\"") != std::string::npos;
    if (scene)
      throw EditError(file.filename().string() +
                      " is a scene, not a deformation. Attach a deformation file (controls and a radius, as the "
                      "Picker saves them); open a scene with File > Open (Ctrl+O).");
  }
  Json& obj = object(o);
  if (!obj.contains("parts") || obj["parts"].empty()) obj["parts"] = Json::array({Json{{"name", "deformed"}}});
  Json& part = obj["parts"][0];
  if (!part.contains("deformations")) part["deformations"] = Json::array();
  Json keys = Json::array();
  keys.push_back(Json{{"time", 0.0}, {"phase", 0.0}});
  keys.push_back(Json{{"time", duration()}, {"phase", 1.0}});
  Json entry = Json::object();
  entry["name"] = file.stem().string();
  entry["deformation"] = relative(file);
  entry["phase"] = Json{{"easing", "smooth"}, {"keys", keys}};
  part["deformations"].push_back(entry);
  return part["deformations"].size() - 1;
}

std::size_t Document::add_phase_key(std::size_t o, std::size_t d, double t, double phase) {
  if (!std::isfinite(phase)) throw EditError("the phase must be a finite number");
  Json saved = json_;
  Json& k = keys(o, Track::Phase, d);
  try {
    const std::size_t i = insertion_index(k, t);
    k.insert(k.begin() + std::ptrdiff_t(i), Json{{"time", t}, {"phase", phase}});
    return i;
  } catch (...) {
    json_ = std::move(saved);
    throw;
  }
}

std::vector<double> Document::key_times(std::size_t o, Track track, std::size_t d) const {
  const Json& obj = object(o);
  const Json* k = nullptr;
  if (track == Track::Position && obj.contains("trajectory")) k = &obj["trajectory"]["keys"];
  if (track == Track::Orientation && obj.contains("orientation")) k = &obj["orientation"]["keys"];
  if (track == Track::Phase && d < deformation_count(o)) {
    const Json& def = obj["parts"][0]["deformations"][d];
    if (def.contains("phase") && def["phase"].is_object()) k = &def["phase"]["keys"];
  }
  std::vector<double> out;
  if (k)
    for (const auto& key : *k) out.push_back(key["time"].get<double>());
  return out;
}

void Document::set_key_time(std::size_t o, Track track, std::size_t d, std::size_t key, double t) {
  if (!std::isfinite(t) || t < 0) throw EditError("a key's time must be >= 0");
  Json& k = keys(o, track, d);
  if (key >= k.size()) throw EditError("no key " + std::to_string(key));
  const double lo = key > 0 ? k[key - 1]["time"].get<double>() : -1.0;
  const double hi = key + 1 < k.size() ? k[key + 1]["time"].get<double>() : 1e300;
  if (!(t > lo && t < hi)) {
    std::ostringstream m;
    m << "t = " << t << " s would pass a neighbouring key (keys stay in time order)";
    throw EditError(m.str());
  }
  k[key]["time"] = t;
}

}  // namespace csrbf::composer
