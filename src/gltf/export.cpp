// glTF 2.0 export of a scene: see csrbf/gltf/export.hpp for what is exact and what is sampled. The export
// runs in phases over a plan (export_detail.hpp): sample times, which parts are baked, exact
// targets and memory bounds (export_plan.cpp), the player's pass, each object written
// (export_object.cpp), the error of baking between frames, camera and lights, the glb.
#include "csrbf/gltf/export.hpp"

#include "export_detail.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/scene.hpp"

#include <numbers>

namespace csrbf::gltf {
namespace {

using namespace export_detail;
namespace fs = std::filesystem;

/// The document's skeleton: the asset, the scene (its duration, frame rate, background and view
/// angle in extras) and the arrays the objects fill.
void start_document(Builder& b, const ExportPlan& plan) {
  const anim::Scene& scene = plan.scene;
  // Reserved whole (pages not written are not resident), so that the buffer never grows by copying
  // and the glb's header goes in front of it in place; 1 MiB for that header and the JSON.
  b.bin.reserve(std::size_t(plan.need.buffer) + (1u << 20));
  b.doc["asset"] = {{"version", "2.0"}, {"generator", "csrbf export"}};
  b.doc["scene"] = 0;
  b.doc["scenes"] = json::array({json{{"name", "scene"}, {"nodes", json::array()}}});
  b.doc["scenes"][0]["extras"] = {{"csrbf",
                                   {{"duration", plan.duration},
                                    {"fps", plan.fps},
                                    {"background", vec_json(scene.background)},
                                    {"view_angle", scene.camera.view_angle}}}};
  b.doc["nodes"] = json::array();
  b.doc["meshes"] = json::array();
  b.doc["materials"] = json::array();
  b.doc["accessors"] = json::array();
  b.doc["bufferViews"] = json::array();
}

// Baking's error between frames: the player at seven points of every frame interval against the
// cross-fade of the two frames' targets; added to the sampled rotation's and weights' errors.
void add_bake_error(const ExportPlan& plan, anim::Player& player, const PlayedFrames& played) {
  const anim::Scene& scene = plan.scene;
  const std::vector<ObjectPlan>& plans = plan.plans;
  const std::vector<double>& frame_t = plan.frame_t;
  const std::size_t frames = plan.frames;
  GltfReport& report = plan.report;
  bool any_baked = false;
  for (const auto& p : plans) any_baked |= p.any_baked();
  std::vector<double> bake_error(scene.objects.size(), 0.0);
  if (any_baked && frames > 1)
    for (std::size_t k = 0; k + 1 < frames; ++k)
      for (int step = 1; step < 8; ++step) {
        const double s = step / 8.0;
        player.evaluate(frame_t[k] + s * (frame_t[k + 1] - frame_t[k]));
        for (std::size_t o = 0; o < scene.objects.size(); ++o) {
          if (!plans[o].any_baked()) continue;
          const auto& model = player.deformed(o);
          const auto& a = played.baked[o][k];
          const auto& c = played.baked[o][k + 1];
          double e = 0;
          for (std::size_t v = 0; v < model.size(); ++v)
            if (plans[o].owner[v] >= 0 && plans[o].baked[std::size_t(plans[o].owner[v])])
              e = std::max(e, (scene.objects[o].rest[v] + (1 - s) * a[v] + s * c[v] - model[v]).norm());
          bake_error[o] = std::max(bake_error[o], e);
        }
      }
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    report.objects[o].max_deviation += bake_error[o];
    if (!std::isfinite(report.objects[o].max_deviation) || !std::isfinite(report.scene_size))
      throw InvalidInput(
          "export: objects[" + std::to_string(o) + "] '" + scene.objects[o].name +
          "': its vertices or their deviation are not finite numbers (a deformation or trajectory beyond "
          "double precision?)");
  }
}

// The camera, looking from its position to its focal point, and the lights (KHR_lights_punctual).
json write_camera_and_lights(Builder& b, const anim::Scene& scene, double scene_size) {
  const anim::Camera& cam = scene.camera;
  const double distance = (cam.focal_point - cam.position).norm();
  b.doc["cameras"] = json::array({json{{"name", "camera"},
                                       {"type", "perspective"},
                                       {"perspective",
                                        {{"yfov", cam.view_angle * std::numbers::pi / 180},
                                         {"znear", std::max(1e-6, 0.01 * distance)},
                                         {"zfar", std::max(1.0, 100 * std::max(distance, scene_size))}}}}});
  const std::size_t cam_node = b.doc["nodes"].size();
  b.doc["nodes"].push_back({{"name", "camera"},
                            {"camera", 0},
                            {"translation", vec_json(cam.position)},
                            {"rotation", quat_json(look_along(cam.focal_point - cam.position, cam.view_up))}});
  b.doc["scenes"][0]["nodes"].push_back(cam_node);
  std::vector<anim::Light> lights = scene.lights;
  if (lights.empty()) lights.push_back(anim::Light{Vec3(1, 1, 1), Vec3(1, 1, 1), 1.0, true});
  json khr = json::array();
  for (std::size_t i = 0; i < lights.size(); ++i) {
    const auto& l = lights[i];
    khr.push_back({{"name", l.headlight ? "headlight" : "light " + std::to_string(i)},
                   {"type", "directional"},
                   {"color", vec_json(l.color)},
                   {"intensity", l.intensity}});
    const std::size_t node = b.doc["nodes"].size();
    json n = {{"name", l.headlight ? "headlight" : "light " + std::to_string(i)},
              {"extensions", {{"KHR_lights_punctual", {{"light", i}}}}}};
    if (l.headlight) {
      b.doc["nodes"][cam_node]["children"].push_back(node);
    } else {
      n["translation"] = vec_json(l.position);
      n["rotation"] = quat_json(look_along(cam.focal_point - l.position, cam.view_up));
      b.doc["scenes"][0]["nodes"].push_back(node);
    }
    b.doc["nodes"].push_back(n);
  }
  return khr;
}

// Node names as three.js binds animations to them: two equal after sanitizing would animate the
// wrong node (an object "a pivot" beside an object "a", or "x y" beside "x_y").
void check_node_names(const json& doc) {
  std::map<std::string, std::string> seen;
  for (const auto& n : doc["nodes"]) {
    const std::string name = n.value("name", "");
    const auto [it, fresh] = seen.emplace(sanitized(name), name);
    if (!fresh)
      throw InvalidInput("export: the nodes '" + it->second + "' and '" + name +
                         "' have the same name once engines sanitize it (three.js: '" + it->first +
                         "'); rename the object so that animations reach the right node");
  }
}

/// The extensions, the animation and the buffer; then the glb: header, the JSON chunk (padded with
/// spaces), the binary chunk.
std::vector<unsigned char> finish(Document& doc, const GltfOptions& options, const json& khr, GltfReport& report) {
  Builder& b = doc.b;
  const json& animation = doc.animation;
  const bool any_compact = doc.any_compact;
  b.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  if (options.quantize) {
    b.doc["extensionsUsed"].push_back("KHR_mesh_quantization");
    b.doc["extensionsRequired"].push_back("KHR_mesh_quantization");
  }
  if (any_compact) {
    b.doc["extensionsUsed"].push_back("CSRBF_deformation");
    if (options.compact == Compact::Only) b.doc["extensionsRequired"].push_back("CSRBF_deformation");
  }
  b.doc["extensions"] = {{"KHR_lights_punctual", {{"lights", khr}}}};
  if (!animation["channels"].empty()) b.doc["animations"] = json::array({animation});
  for (const char* key : {"materials", "accessors", "bufferViews", "meshes"})
    if (b.doc[key].empty()) b.doc.erase(key);
  while (b.bin.size() % 4) b.bin.push_back(0);
  b.doc["buffers"] = json::array({json{{"byteLength", b.bin.size()}}});
  if (options.meshopt) gltf::meshopt_compress(b.doc, b.bin, b.hints);

  const std::vector<unsigned char> head = gltf::glb_head(b.doc.dump(), b.bin.size(), "export");
  // In front of the binary chunk, in place where the reserve has room (no second copy of the buffer).
  std::vector<unsigned char> glb = std::move(b.bin);
  glb.insert(glb.begin(), head.begin(), head.end());
  report.bytes = glb.size();
  return glb;
}

}  // namespace

void export_detail::Document::add_channel(std::size_t node, const char* path, std::size_t input, std::size_t output,
                                          const char* interpolation) {
  animation["samplers"].push_back({{"input", input}, {"output", output}, {"interpolation", interpolation}});
  animation["channels"].push_back(
      {{"sampler", animation["samplers"].size() - 1}, {"target", {{"node", node}, {"path", path}}}});
}

std::size_t export_detail::Document::time_accessor(const std::vector<double>& t) {
  std::vector<float> f(t.begin(), t.end());
  return b.floats(f, 1, "the animation times");
}

std::size_t export_detail::Document::material(const anim::Material& m, const std::string& name) {
  json mat = {{"name", name},
              {"doubleSided", true},
              {"pbrMetallicRoughness",
               {{"baseColorFactor", {m.color.x(), m.color.y(), m.color.z(), m.opacity}},
                {"metallicFactor", 0.0},
                {"roughnessFactor", std::clamp(1.0 - 0.8 * m.specular, 0.05, 1.0)}}}};
  if (m.opacity < 1) mat["alphaMode"] = "BLEND";
  if (!m.texture.empty()) {
    auto it = images.find(m.texture);
    if (it == images.end()) {
      const std::vector<unsigned char> bytes = read_bytes(m.texture);
      const std::string mime = image_mime(bytes, m.texture);
      // Checked whole before VTK decodes it (libpng under VTK crashes on a PNG cut short): a
      // scene built without read_scene has not been.
      if (const std::string problem = io::texture_problem(m.texture); !problem.empty())
        throw io::FileError("texture '" + m.texture + "' is damaged: " + problem);
      if (!textures || !textures->check_decodes)
        throw InvalidInput("export: texture '" + m.texture +
                           "': the exporter was given no image check (GltfOptions::textures; "
                           "csrbf::render::export_gltf gives VTK's)");
      textures->check_decodes(m.texture);
      const std::size_t v = b.view(bytes.data(), bytes.size());
      b.doc["images"].push_back(
          {{"bufferView", v}, {"mimeType", mime}, {"name", fs::path(m.texture).filename().string()}});
      b.doc["samplers"] =
          json::array({json{{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 10497}, {"wrapT", 10497}}});
      b.doc["textures"].push_back({{"sampler", 0}, {"source", b.doc["images"].size() - 1}});
      it = images.emplace(m.texture, b.doc["textures"].size() - 1).first;
    }
    mat["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", it->second}};
  }
  b.doc["materials"].push_back(mat);
  return b.doc["materials"].size() - 1;
}

std::vector<unsigned char> gltf_binary(const anim::Scene& scene, const GltfOptions& options, GltfReport& report) {
  ExportPlan plan{scene, options, report};
  plan_sample_times(plan);
  plan_parts(plan);
  check_target_memory(plan);
  plan_exact_targets(plan);
  check_export_memory(plan);
  anim::Player player(scene);
  const PlayedFrames played = play_frames(plan, player);
  Document doc;
  doc.textures = &options.textures;
  start_document(doc.b, plan);
  for (std::size_t o = 0; o < scene.objects.size(); ++o) write_object(plan, doc, player, played, o);
  add_bake_error(plan, player, played);
  const json khr = write_camera_and_lights(doc.b, scene, report.scene_size);
  check_node_names(doc.b.doc);
  return finish(doc, options, khr, report);
}

void write_base64(std::ostream& out, const unsigned char* p, std::size_t n) {
  static const char* a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  char chunk[4096];  // 3072 bytes a chunk, so that no copy of the whole is made
  std::size_t used = 0;
  for (std::size_t i = 0; i < n; i += 3) {
    const std::uint32_t v = std::uint32_t(p[i]) << 16 | (i + 1 < n ? std::uint32_t(p[i + 1]) << 8 : 0) |
                            (i + 2 < n ? std::uint32_t(p[i + 2]) : 0);
    chunk[used++] = a[v >> 18 & 63];
    chunk[used++] = a[v >> 12 & 63];
    chunk[used++] = i + 1 < n ? a[v >> 6 & 63] : '=';
    chunk[used++] = i + 2 < n ? a[v & 63] : '=';
    if (used == sizeof chunk) {
      out.write(chunk, std::streamsize(used));
      used = 0;
    }
  }
  out.write(chunk, std::streamsize(used));
}

std::string base64(const unsigned char* p, std::size_t n) {
  std::ostringstream out;
  write_base64(out, p, n);
  return std::move(out).str();
}

namespace {
/// glb as .gltf text, streamed: its JSON with the binary chunk as a base64 data URI, written where
/// a placeholder stands in the JSON's text (so that neither the base64 nor the text is held whole).
std::size_t write_gltf_text(std::ostream& out, const std::vector<unsigned char>& glb) {
  const gltf::GlbChunks chunks = gltf::split_glb(glb);
  json doc = json::parse(chunks.json.begin(), chunks.json.end());
  const std::string mark = "@CSRBF-BASE64@";
  doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + mark;
  std::string text = doc.dump(1);
  text.push_back('\n');
  const std::size_t at = text.find(mark);
  out.write(text.data(), std::streamsize(at));
  write_base64(out, chunks.bin.data(), chunks.bin.size());
  out.write(text.data() + at + mark.size(), std::streamsize(text.size() - at - mark.size()));
  return text.size() - mark.size() + (chunks.bin.size() + 2) / 3 * 4;
}
}  // namespace

std::string glb_to_gltf(const std::vector<unsigned char>& glb) {
  std::ostringstream out;
  write_gltf_text(out, glb);
  return std::move(out).str();
}

std::size_t write_gltf(const std::vector<unsigned char>& glb, const fs::path& path,
                       const std::function<void()>& before_commit) {
  const std::string ext = path.extension().string();
  if (ext != ".glb" && ext != ".gltf")
    throw InvalidInput("export: the output must end in .glb or .gltf, got '" + path.string() + "'");
  std::size_t bytes = glb.size();
  io::write_atomically(
      path,
      [&](std::ostream& s) {
        if (ext == ".glb")
          s.write(reinterpret_cast<const char*>(glb.data()), std::streamsize(glb.size()));
        else
          bytes = write_gltf_text(s, glb);
      },
      before_commit);
  return bytes;
}

GltfReport export_gltf(const anim::Scene& scene, const fs::path& path, const GltfOptions& options) {
  io::check_output_path(path);
  GltfReport report;
  const std::vector<unsigned char> glb = gltf_binary(scene, options, report);
  report.bytes = write_gltf(glb, path);
  return report;
}

}  // namespace csrbf::gltf
