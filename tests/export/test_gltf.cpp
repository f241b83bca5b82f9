// csrbf export against the scene it came from: a small glTF reader of our own (node TRS at time t,
// the morph weights at time t, base plus weighted sparse targets) gives every vertex of every object,
// which must equal the Player's (what `csrbf animate` draws) at every frame time, and between frames
// within the deviation the export reports.
#include "csrbf/errors.hpp"
#include "csrbf/io/scene.hpp"
#include "csrbf/render/gltf_export.hpp"
#include "csrbf/render/gltf_meshopt.hpp"
#include "csrbf/render/gltf_runtime.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

using namespace csrbf;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

/// A glb read back: its JSON and binary chunk, and what a player of it needs.
struct Glb {
  json doc;
  std::vector<unsigned char> bin;

  explicit Glb(const std::vector<unsigned char>& bytes) {
    auto u32 = [&](std::size_t at) {
      std::uint32_t v;
      std::memcpy(&v, bytes.data() + at, 4);
      return v;
    };
    EXPECT_EQ(u32(0), 0x46546C67u);
    EXPECT_EQ(u32(4), 2u);
    EXPECT_EQ(u32(8), bytes.size());
    const std::uint32_t jl = u32(12);
    EXPECT_EQ(u32(16), 0x4E4F534Au);
    doc = json::parse(bytes.begin() + 20, bytes.begin() + 20 + jl);
    const std::size_t b = 20 + jl;
    EXPECT_EQ(u32(b + 4), 0x004E4942u);
    bin.assign(bytes.begin() + std::ptrdiff_t(b + 8), bytes.begin() + std::ptrdiff_t(b + 8 + u32(b)));
  }

  static int width(const std::string& type) {
    return type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3 : type == "VEC4" ? 4 : 0;
  }
  template <class T>
  std::vector<T> view(std::size_t v, std::size_t count) const {
    const json& bv = doc["bufferViews"][v];
    const std::size_t off = bv.value("byteOffset", std::size_t(0));
    EXPECT_LE(count * sizeof(T), bv["byteLength"].get<std::size_t>());
    std::vector<T> out(count);
    std::memcpy(out.data(), bin.data() + off, count * sizeof(T));
    return out;
  }
  /// count elements of w components of type ct from view v (its byteStride, else packed), as float:
  /// normalized SHORT and BYTE (KHR_mesh_quantization) as max(q / 32767 or 127, -1).
  std::vector<float> elements(std::size_t v, std::size_t count, std::size_t w, int ct, bool packed) const {
    const json& bv = doc["bufferViews"][v];
    const std::size_t cs = ct == 5126 ? 4 : ct == 5122 ? 2 : 1;
    const std::size_t stride = !packed && bv.contains("byteStride") ? bv["byteStride"].get<std::size_t>() : cs * w;
    const std::size_t off = bv.value("byteOffset", std::size_t(0));
    EXPECT_LE(count ? (count - 1) * stride + cs * w : 0, bv["byteLength"].get<std::size_t>());
    std::vector<float> out(count * w);
    for (std::size_t i = 0; i < count; ++i)
      for (std::size_t c = 0; c < w; ++c) {
        const unsigned char* p = bin.data() + off + i * stride + c * cs;
        if (ct == 5126) {
          std::memcpy(&out[i * w + c], p, 4);
        } else if (ct == 5122) {
          std::int16_t q;
          std::memcpy(&q, p, 2);
          out[i * w + c] = std::max(float(q) / 32767.0f, -1.0f);
        } else {
          out[i * w + c] = std::max(float(std::int8_t(*p)) / 127.0f, -1.0f);
        }
      }
    return out;
  }
  /// A float (or normalized SHORT or BYTE) accessor, dense, with its sparse values applied.
  std::vector<float> floats(std::size_t a, std::size_t* sparse_count = nullptr) const {
    const json& acc = doc["accessors"][a];
    const int ct = acc["componentType"];
    EXPECT_TRUE(ct == 5126 || (acc.value("normalized", false) && (ct == 5122 || ct == 5120))) << ct;
    const std::size_t w = std::size_t(width(acc["type"])), n = acc["count"];
    std::vector<float> out(n * w, 0.0f);
    if (acc.contains("bufferView")) out = elements(acc["bufferView"], n, w, ct, false);
    if (acc.contains("sparse")) {
      const json& sp = acc["sparse"];
      const std::size_t k = sp["count"];
      std::vector<std::uint32_t> idx;
      if (sp["indices"]["componentType"] == 5123) {
        const auto i16 = view<std::uint16_t>(sp["indices"]["bufferView"], k);
        idx.assign(i16.begin(), i16.end());
      } else {
        EXPECT_EQ(sp["indices"]["componentType"], 5125);
        idx = view<std::uint32_t>(sp["indices"]["bufferView"], k);
      }
      const auto val = elements(sp["values"]["bufferView"], k, w, ct, true);
      for (std::size_t i = 0; i < k; ++i)
        for (std::size_t c = 0; c < w; ++c) out[idx[i] * w + c] = val[i * w + c];
      if (sparse_count) *sparse_count = k;
    }
    return out;
  }

  /// A channel's value at t (glTF's rules: clamped outside the keys; LINEAR lerps, or slerps
  /// rotations; CUBICSPLINE is Hermite with the tangents scaled by the key interval).
  std::vector<double> sample(const json& sampler, bool rotation, double t) const {
    const auto in = floats(sampler["input"]);
    const auto out = floats(sampler["output"]);
    const bool cubic = sampler["interpolation"] == "CUBICSPLINE";
    const std::size_t keys = in.size(), w = out.size() / keys / (cubic ? 3 : 1);
    const auto value = [&](std::size_t k, int part) {  // part: 0 in-tangent, 1 value, 2 out-tangent
      std::vector<double> v(w);
      for (std::size_t c = 0; c < w; ++c) v[c] = out[(cubic ? (3 * k + std::size_t(part)) * w : k * w) + c];
      return v;
    };
    if (t <= in.front()) return value(0, 1);
    if (t >= in.back()) return value(keys - 1, 1);
    std::size_t k = 0;
    while (k + 2 < keys && t >= in[k + 1]) ++k;
    const double td = double(in[k + 1]) - double(in[k]), s = (t - in[k]) / td;
    std::vector<double> r(w);
    if (cubic) {
      const auto p0 = value(k, 1), b0 = value(k, 2), p1 = value(k + 1, 1), a1 = value(k + 1, 0);
      const double s2 = s * s, s3 = s2 * s;
      for (std::size_t c = 0; c < w; ++c)
        r[c] = (2 * s3 - 3 * s2 + 1) * p0[c] + td * (s3 - 2 * s2 + s) * b0[c] + (-2 * s3 + 3 * s2) * p1[c] +
               td * (s3 - s2) * a1[c];
      return r;
    }
    const auto a = value(k, 1), b = value(k + 1, 1);
    if (rotation) {
      Eigen::Quaterniond qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
      const Eigen::Quaterniond q = qa.slerp(s, qb);
      return {q.x(), q.y(), q.z(), q.w()};
    }
    for (std::size_t c = 0; c < w; ++c) r[c] = (1 - s) * a[c] + s * b[c];
    return r;
  }
  /// The sampler that animates node's path, or null.
  const json* channel(std::size_t node, const std::string& path) const {
    if (!doc.contains("animations")) return nullptr;
    for (const auto& ch : doc["animations"][0]["channels"])
      if (ch["target"]["node"] == node && ch["target"]["path"] == path)
        return &doc["animations"][0]["samplers"][ch["sampler"].get<std::size_t>()];
    return nullptr;
  }
  /// A node's local matrix at t.
  Eigen::Affine3d local(std::size_t node, double t) const {
    const json& n = doc["nodes"][node];
    Vec3 tr = Vec3::Zero();
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    if (n.contains("translation")) tr = Vec3(n["translation"][0], n["translation"][1], n["translation"][2]);
    if (n.contains("rotation"))
      q = Eigen::Quaterniond(n["rotation"][3], n["rotation"][0], n["rotation"][1], n["rotation"][2]);
    if (const json* s = channel(node, "translation")) {
      const auto v = sample(*s, false, t);
      tr = Vec3(v[0], v[1], v[2]);
    }
    if (const json* s = channel(node, "rotation")) {
      const auto v = sample(*s, true, t);
      q = Eigen::Quaterniond(v[3], v[0], v[1], v[2]);
    }
    Eigen::Affine3d m = Eigen::Affine3d::Identity();
    m.translate(tr);
    m.rotate(q.normalized());
    if (n.contains("scale")) m.scale(Vec3(n["scale"][0], n["scale"][1], n["scale"][2]));
    return m;
  }
  std::size_t node_named(const std::string& name) const {
    for (std::size_t i = 0; i < doc["nodes"].size(); ++i)
      if (doc["nodes"][i].value("name", "") == name && doc["nodes"][i].contains("mesh")) return i;
    ADD_FAILURE() << "no mesh node named " << name;
    return 0;
  }
  std::size_t parent(std::size_t node) const {
    for (std::size_t i = 0; i < doc["nodes"].size(); ++i)
      for (const auto& c : doc["nodes"][i].value("children", json::array()))
        if (c == node) return i;
    return std::size_t(-1);
  }
  /// Every vertex of the mesh node named name, in world coordinates, at t.
  std::vector<Vec3> vertices(const std::string& name, double t) const {
    const std::size_t node = node_named(name);
    Eigen::Affine3d world = local(node, t);
    for (std::size_t p = parent(node); p != std::size_t(-1); p = parent(p)) world = local(p, t) * world;
    const json& mesh = doc["meshes"][doc["nodes"][node]["mesh"].get<std::size_t>()];
    const json& prim = mesh["primitives"][0];
    const auto base = floats(prim["attributes"]["POSITION"]);
    std::vector<double> acc(base.begin(), base.end());
    if (prim.contains("targets")) {
      std::vector<double> w = mesh["weights"].get<std::vector<double>>();
      if (const json* s = channel(node, "weights")) w = sample(*s, false, t);
      for (std::size_t j = 0; j < prim["targets"].size(); ++j) {
        if (w[j] == 0) continue;
        const auto d = floats(prim["targets"][j]["POSITION"]);
        for (std::size_t i = 0; i < acc.size(); ++i) acc[i] += w[j] * d[i];
      }
    }
    std::vector<Vec3> out(acc.size() / 3);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = world * Vec3(acc[3 * i], acc[3 * i + 1], acc[3 * i + 2]);
    return out;
  }
};

double worst_difference(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  EXPECT_EQ(a.size(), b.size());
  double w = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) w = std::max(w, (a[i] - b[i]).norm());
  return w;
}

/// Every object at every frame time (1e-5 of the scene size, plus the reported quantization error
/// where quantized), and at three points between frames (within the reported deviation, which
/// counts it, plus the same 1e-5).
void expect_plays_as_the_scene(const anim::Scene& scene, const render::GltfOptions& o, const Glb& glb,
                               const render::GltfReport& r) {
  anim::Player player(scene);
  const double tol = 1e-5 * r.scene_size;
  ASSERT_GT(r.scene_size, 0);
  for (std::size_t k = 0; k < r.frames; ++k)
    for (const double s : {0.0, 0.3, 0.5, 0.85}) {
      const double t = (double(k) + s) / r.fps;
      if (t > scene.duration) continue;
      player.evaluate(t);
      for (std::size_t obj = 0; obj < scene.objects.size(); ++obj) {
        const double w = worst_difference(glb.vertices(scene.objects[obj].name, t), player.positions(obj));
        const double allowed = (s == 0.0 ? r.objects[obj].quantization_error : r.objects[obj].max_deviation) + tol;
        ASSERT_LE(w, allowed) << scene.objects[obj].name << " at t = " << t << " (bake " << int(o.bake) << ")";
      }
    }
}

fs::path example(const std::string& name) { return fs::path(CSRBF_SOURCE_DIR) / "examples" / name; }

}  // namespace

TEST(GltfExport, EveryExamplePlaysAsTheScene) {
  for (const char* name : {"fish.scene.json", "face.scene.json", "ball.scene.json"}) {
    SCOPED_TRACE(name);
    const anim::Scene scene = io::read_scene(example(name));
    render::GltfReport r;
    const render::GltfOptions o;
    const Glb glb(render::gltf_binary(scene, o, r));
    EXPECT_EQ(r.frames, scene.frame_count(0, scene.duration));
    EXPECT_LE(r.max_active, 8u);
    expect_plays_as_the_scene(scene, o, glb, r);
    // The node that holds the mesh carries the object's name; its parent is the pivot.
    for (const auto& obj : scene.objects) EXPECT_NE(glb.parent(glb.node_named(obj.name)), std::size_t(-1));
  }
}

TEST(GltfExport, SummedDeformationsAreExactSparseTargets) {
  // The fish: four summed deformations, four targets, each holding only the vertices its controls
  // reach (compact support), and the trajectory as a cubic spline.
  const anim::Scene scene = io::read_scene(example("fish.scene.json"));
  render::GltfReport r;
  const Glb glb(render::gltf_binary(scene, {}, r));
  ASSERT_EQ(r.parts.size(), 1u);
  EXPECT_FALSE(r.parts[0].baked);
  EXPECT_EQ(r.parts[0].targets, 4u);
  const json& prim = glb.doc["meshes"][0]["primitives"][0];
  ASSERT_EQ(prim["targets"].size(), 4u);
  // Sparse only where that is smaller than dense (issue 33): the fish's deformations reach 967 to
  // 976 of its 977 vertices, so its targets are dense, 12 bytes a vertex. Indices are 16-bit.
  const std::size_t nv = scene.objects[0].rest.size();
  for (const auto& target : prim["targets"]) {
    const json& acc = glb.doc["accessors"][target["POSITION"].get<std::size_t>()];
    const auto d = glb.floats(target["POSITION"]);
    std::size_t moved = 0;
    for (std::size_t v = 0; v < nv; ++v) moved += d[3 * v] != 0 || d[3 * v + 1] != 0 || d[3 * v + 2] != 0;
    EXPECT_GT(moved, 0u);
    EXPECT_LT(moved, nv);
    EXPECT_EQ(acc.contains("sparse"), 14 * moved < 12 * nv) << moved;
  }
  EXPECT_EQ(glb.doc["accessors"][prim["indices"].get<std::size_t>()]["componentType"], 5123);
  EXPECT_EQ(glb.doc["meshes"][0]["extras"]["targetNames"][0], "tail left");
  const json* tr = glb.channel(glb.parent(glb.node_named("fish")), "translation");
  ASSERT_NE(tr, nullptr);
  EXPECT_EQ((*tr)["interpolation"], "CUBICSPLINE");
  // Squad is sampled, and says by how much it may be off between samples.
  EXPECT_GT(r.objects[0].rotation_deviation_deg, 0.0);
  EXPECT_LT(r.objects[0].rotation_deviation_deg, 0.1);
}

TEST(GltfExport, ContactIsBakedWithTwoTargetsActive) {
  const anim::Scene scene = io::read_scene(example("ball.scene.json"));
  render::GltfReport r;
  const Glb glb(render::gltf_binary(scene, {}, r));
  bool baked = false;
  for (const auto& p : r.parts) baked |= p.baked && p.object == "box";
  EXPECT_TRUE(baked);
  EXPECT_EQ(r.objects[0].max_active, 2u);
  EXPECT_GT(r.objects[0].targets, 2u);
  EXPECT_LT(r.objects[0].targets, r.frames);  // frames where the box is not dented have no target
  // The textured ball: its UVs come with it, v flipped to glTF's top-left origin.
  EXPECT_EQ(glb.doc["images"].size(), 1u);
  EXPECT_EQ(glb.doc["images"][0]["mimeType"], "image/png");
}

TEST(GltfExport, BakeAlwaysAndNever) {
  const anim::Scene fish = io::read_scene(example("fish.scene.json"));
  render::GltfOptions o;
  o.bake = render::Bake::Always;
  o.fps = 10;
  render::GltfReport r;
  const Glb glb(render::gltf_binary(fish, o, r));
  EXPECT_TRUE(r.parts[0].baked);
  EXPECT_EQ(r.objects[0].max_active, 2u);
  EXPECT_EQ(r.frames, 81u);
  expect_plays_as_the_scene(fish, o, glb, r);
  o.bake = render::Bake::Never;
  const anim::Scene ball = io::read_scene(example("ball.scene.json"));
  try {
    render::gltf_binary(ball, o, r);
    FAIL() << "a contact deformation cannot be exported without baking";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("'walls' needs baking"), std::string::npos) << e.what();
  }
}

TEST(GltfExport, BakingIsBoundedBeforeItStarts) {
  // 50001 frames of the face baked: 50001 targets weighted at 50001 times, and 14 GiB of frames,
  // refused before the first frame.
  anim::Scene face = io::read_scene(example("face.scene.json"));
  face.duration = 50;
  render::GltfOptions o;
  o.bake = render::Bake::Always;
  o.fps = 1000;
  render::GltfReport r;
  try {
    render::gltf_binary(face, o, r);
    FAIL() << "baking 50001 frames of 6158 vertices was not refused";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("would take"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("lower --fps"), std::string::npos) << e.what();
  }
}

TEST(GltfExport, MoreThanEightActiveTargetsAreBaked) {
  // Ten summed deformations on at once: past the engines' 8, --bake auto bakes the part.
  const fs::path dir = fs::temp_directory_path() / ("csrbf-gltf-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::copy_file(example("sphere.obj"), dir / "sphere.obj", fs::copy_options::overwrite_existing);
  json defs = json::array();
  for (int i = 0; i < 10; ++i) {
    const double a = 0.6 * i;
    defs.push_back(
        {{"name", "bump " + std::to_string(i)},
         {"sources", {{0.2 * std::cos(a), 0.2 * std::sin(a), 0.0}}},
         {"destinations", {{0.22 * std::cos(a), 0.22 * std::sin(a), 0.0}}},
         {"radius", 0.15},
         {"phase", {{"easing", "linear"}, {"keys", {{{"time", 0}, {"phase", 0}}, {{"time", 1}, {"phase", 1}}}}}}});
  }
  json s = {{"duration", 1.0},
            {"fps", 10},
            {"objects",
             {{{"name", "ball"},
               {"mesh", "sphere.obj"},
               {"parts", {{{"name", "all"}, {"combine", "sum"}, {"deformations", defs}}}}}}}};
  std::ofstream(dir / "s.scene.json") << s.dump();
  const anim::Scene scene = io::read_scene(dir / "s.scene.json");
  render::GltfReport r;
  render::GltfOptions o;
  const Glb glb(render::gltf_binary(scene, o, r));
  EXPECT_TRUE(r.parts[0].baked);
  EXPECT_NE(r.parts[0].why.find("more than 8"), std::string::npos);
  EXPECT_LE(r.max_active, 2u);
  expect_plays_as_the_scene(scene, o, glb, r);
  // Allowed 10: exact targets, and linear schedules are exact between frames too.
  o.max_active = 10;
  const Glb exact(render::gltf_binary(scene, o, r));
  EXPECT_FALSE(r.parts[0].baked);
  EXPECT_EQ(r.max_active, 10u);
  EXPECT_LT(r.objects[0].max_deviation, 1e-12);  // rounding only
  expect_plays_as_the_scene(scene, o, exact, r);
  fs::remove_all(dir);
}

TEST(GltfExport, GltfTextHoldsTheSameBuffer) {
  const anim::Scene scene = io::read_scene(example("face.scene.json"));
  render::GltfReport r;
  const auto glb = render::gltf_binary(scene, {}, r);
  const json doc = json::parse(render::glb_to_gltf(glb));
  const std::string uri = doc["buffers"][0]["uri"];
  ASSERT_EQ(uri.rfind("data:application/octet-stream;base64,", 0), 0u);
  const Glb g(glb);
  EXPECT_EQ(uri.size() - 37, (g.bin.size() + 2) / 3 * 4);
  EXPECT_EQ(render::base64(reinterpret_cast<const unsigned char*>("csrbf"), 5), "Y3NyYmY=");
}

TEST(GltfExport, KeysThatMergeInFloatCountInTheDeviation) {
  // glTF stores times as float32: keys 1e-9 s apart are one sample there, which shows only one of
  // their values. A turn of 30 degrees, a step of 0.5 and a phase jump between such keys are what
  // the glTF loses, and the report says so (it said 0).
  const fs::path dir = fs::temp_directory_path() / ("csrbf-gltf-merge-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::copy_file(example("sphere.obj"), dir / "sphere.obj", fs::copy_options::overwrite_existing);
  const double a = 0.5, b = 0.5 + 1e-9;
  const json axis = {0, 0, 1};
  json ball = {{"name", "ball"}, {"mesh", "sphere.obj"}};
  ball["orientation"]["interpolation"] = "slerp";
  ball["orientation"]["keys"] = {{{"time", a}, {"axis", axis}, {"angle", 0}},
                                 {{"time", b}, {"axis", axis}, {"angle", 30}}};
  ball["trajectory"]["keys"] = {{{"time", a}, {"position", {0, 0, 0}}}, {{"time", b}, {"position", {0.5, 0, 0}}}};
  json s = {{"duration", 1.0}, {"fps", 10}, {"objects", json::array({ball})}};
  std::ofstream(dir / "s.scene.json") << s.dump();
  const anim::Scene scene = io::read_scene(dir / "s.scene.json");
  render::GltfReport r;
  render::GltfOptions o;
  const Glb glb(render::gltf_binary(scene, o, r));
  ASSERT_EQ(r.objects.size(), 1u);
  EXPECT_NEAR(r.objects[0].rotation_deviation_deg, 30.0, 1e-6);
  anim::Player player(scene);
  player.evaluate(0);
  double reach = 0;
  for (const Vec3& p : player.positions(0)) reach = std::max(reach, (p - scene.objects[0].centre).norm());
  EXPECT_GE(r.objects[0].max_deviation, 0.5 + 30.0 * std::numbers::pi / 180 * reach * (1 - 1e-9));
  // Where no keys merge, slerp keys and a trajectory add nothing.
  s["objects"][0]["orientation"]["keys"][1]["time"] = 0.6;
  s["objects"][0]["trajectory"]["keys"][1]["time"] = 0.6;
  std::ofstream(dir / "s.scene.json") << s.dump();
  render::gltf_binary(io::read_scene(dir / "s.scene.json"), o, r);
  EXPECT_LT(r.objects[0].rotation_deviation_deg, 1e-6);
  fs::remove_all(dir);
}

// Issue 33: CSRBF_deformation (docs/gltf/CSRBF_deformation.md). Every example exported with
// --compact and --compact=only, read back by GltfRuntime (the extension's evaluation: float
// sources and coefficients, vertex groups, the targets it does not replace) equals the Player's
// deformed mesh at every frame time to 1e-5 of the scene (and between frames within the reported
// deviation), and equals its own morph-target fallback; with --compact=only the replaced targets
// hold nothing. The extension is far smaller than the targets it replaces on the face (a mesh of
// many vertices a control).
TEST(GltfCompact, EveryExamplePlaysTheSameThroughTheExtension) {
  for (const char* name : {"fish.scene.json", "face.scene.json", "ball.scene.json"})
    for (const render::Compact mode : {render::Compact::WithFallback, render::Compact::Only}) {
      SCOPED_TRACE(std::string(name) + (mode == render::Compact::Only ? " only" : " with fallback"));
      const anim::Scene scene = io::read_scene(example(name));
      render::GltfOptions o;
      o.compact = mode;
      render::GltfReport r;
      const std::vector<unsigned char> bytes = render::gltf_binary(scene, o, r);
      const Glb glb(bytes);
      const render::GltfRuntime runtime(bytes);
      // The ball's only deforming part is a contact, refitted every frame: baked targets, replaced
      // by one deformation a frame.
      const bool baked_only = false;
      const auto& used = glb.doc["extensionsUsed"];
      EXPECT_EQ(std::find(used.begin(), used.end(), "CSRBF_deformation") != used.end(), !baked_only);
      EXPECT_EQ(glb.doc.contains("extensionsRequired"), mode == render::Compact::Only && !baked_only);
      anim::Player player(scene);
      const double tol = 1e-5 * r.scene_size;
      std::size_t compact_objects = 0;
      for (std::size_t obj = 0; obj < scene.objects.size(); ++obj) {
        const std::size_t mesh = runtime.mesh_named(scene.objects[obj].name);
        compact_objects += runtime.compact(mesh);
        EXPECT_LE(r.objects[obj].compact_error, tol) << scene.objects[obj].name;
      }
      EXPECT_EQ(compact_objects > 0, !baked_only);
      double worst = 0, worst_fallback = 0, worst_unit = 0;
      for (std::size_t k = 0; k < r.frames; ++k)
        for (const double s : {0.0, 0.5}) {
          const double t = (double(k) + s) / r.fps;
          if (t > scene.duration) continue;
          player.evaluate(t);
          for (std::size_t obj = 0; obj < scene.objects.size(); ++obj) {
            const std::size_t mesh = runtime.mesh_named(scene.objects[obj].name);
            const std::vector<double> w = runtime.weights(mesh, t);
            std::vector<Vec3> p, n, pf, nf;
            runtime.deform(mesh, w, p, n, true);
            const double allowed = (s == 0.0 ? 0.0 : r.objects[obj].max_deviation) + tol;
            const double e = worst_difference(p, player.deformed(obj));
            ASSERT_LE(e, allowed) << scene.objects[obj].name << " at t = " << t;
            worst = std::max(worst, e);
            for (const Vec3& x : n) worst_unit = std::max(worst_unit, std::abs(x.norm() - 1.0));
            runtime.deform(mesh, w, pf, nf, false);
            if (mode == render::Compact::WithFallback) {
              worst_fallback = std::max(worst_fallback, worst_difference(p, pf));
            } else if (runtime.compact(mesh)) {
              // Without the extension the replaced targets move nothing: only baked parts move.
              const auto rest = runtime.rest(mesh);
              bool exact_part_still = true;
              for (std::size_t v = 0; v < rest.size(); ++v)
                if ((p[v] - pf[v]).norm() > tol) exact_part_still &= (pf[v] - rest[v]).norm() <= tol;
              EXPECT_TRUE(exact_part_still);
            }
          }
        }
      EXPECT_LE(worst_fallback, 2 * tol);
      EXPECT_LT(worst_unit, 1e-9);
      std::printf("%s %s: extension %zu bytes in place of %zu of targets; largest vertex difference %.3g\n", name,
                  mode == render::Compact::Only ? "only" : "fallback", r.compact_bytes, r.replaced_target_bytes, worst);
      EXPECT_EQ(r.replaced_target_bytes > 0, !baked_only);
      if (std::string(name) == "face.scene.json") {
        EXPECT_LT(20 * r.compact_bytes, r.replaced_target_bytes);
      }
    }
}

/// A glb of this JSON and binary chunk.
std::vector<unsigned char> glb_of(const json& doc, const std::vector<unsigned char>& bin) {
  std::string text = doc.dump();
  while (text.size() % 4) text.push_back(' ');
  std::vector<unsigned char> out;
  const auto u32 = [&](std::size_t x) {
    for (int i = 0; i < 4; ++i) out.push_back((unsigned char)(x >> (8 * i)));
  };
  u32(0x46546C67);
  u32(2);
  u32(12 + 8 + text.size() + 8 + bin.size());
  u32(text.size());
  u32(0x4E4F534A);
  out.insert(out.end(), text.begin(), text.end());
  u32(bin.size());
  u32(0x004E4942);
  out.insert(out.end(), bin.begin(), bin.end());
  return out;
}

// GltfRuntime refuses malformed input, naming what is wrong, and never reads outside the file.
TEST(GltfCompact, TheRuntimeNamesWhatIsMalformed) {
  const anim::Scene scene = io::read_scene(example("face.scene.json"));
  render::GltfOptions o;
  o.compact = render::Compact::Only;
  render::GltfReport r;
  const std::vector<unsigned char> good = render::gltf_binary(scene, o, r);
  const auto with_doc = [&](const std::function<void(json&)>& edit) {
    const Glb g(good);
    json doc = g.doc;
    edit(doc);
    return glb_of(doc, g.bin);
  };
  const auto refused = [&](const std::vector<unsigned char>& bytes, const std::string& says) {
    try {
      render::GltfRuntime rt(bytes);
      ADD_FAILURE() << "accepted; expected an error saying " << says;
    } catch (const InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  const auto ext = [](json& doc) -> json& { return doc["meshes"][0]["extensions"]["CSRBF_deformation"]; };
  refused(with_doc([&](json& d) { ext(d)["deformations"][0]["kernel"] = "C3"; }), "kernel 'C3'");
  refused(with_doc([&](json& d) { ext(d)["deformations"][0]["radius"] = -1; }), ".radius");
  refused(with_doc([&](json& d) { ext(d)["deformations"][0]["terms"][0]["weight"] = 99; }), "weight 99");
  refused(with_doc([&](json& d) { ext(d)["deformations"][0]["sources"] = 100000; }), "accessor 100000");
  refused(with_doc([&](json& d) { d["bufferViews"][0]["byteLength"] = 1u << 30; }), "outside");
  // What single precision cannot evaluate, float indices, and a primitive with vertices of its own.
  refused(with_doc([&](json& d) { ext(d)["deformations"][0]["radius"] = 1e-160; }), "[1e-18, 1e18]");
  refused(with_doc([&](json& d) { ext(d)["deformations"][0]["stage"] = 70000; }), "stage 70000 is past 65535");
  refused(with_doc([&](json& d) {
            const std::size_t ia = d["meshes"][0]["primitives"][0]["indices"];
            d["accessors"][ia]["componentType"] = 5126;
            d["accessors"][ia]["count"] = d["accessors"][ia]["count"].get<std::size_t>() / 2;
          }),
          "not an unsigned integer type");
  refused(with_doc([&](json& d) {
            json p = d["meshes"][0]["primitives"][0];
            p["attributes"]["POSITION"] = p["attributes"]["NORMAL"];
            d["meshes"][0]["primitives"].push_back(p);
          }),
          "its POSITION is not the first primitive's");
  std::vector<unsigned char> cut(good.begin(), good.begin() + std::ptrdiff_t(good.size() / 2));
  refused(cut, "header says");
  std::vector<unsigned char> junk = good;
  junk[0] = 'x';
  refused(junk, "not a glb");
}

// Found by the attacker: two controls 1e-4 apart, moved in opposite directions, have coefficients
// far above their displacements, whose float form erred by 0.013 to 25.8 (exit 0, no warning). Such
// a deformation stays an ordinary morph target, named in the report, and the file plays exactly.
TEST(GltfCompact, ADeformationFloatCannotHoldStaysAMorphTarget) {
  const fs::path dir = fs::temp_directory_path() / "csrbf-test-compact-close";
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::copy_file(example("fish.obj"), dir / "fish.obj");
  const json close = {{"name", "close"},
                      {"sources", {{0.725, 0.550967, 0.5}, {0.7251, 0.550967, 0.5}}},
                      {"destinations", {{0.725, 0.600967, 0.5}, {0.7251, 0.500967, 0.5}}},
                      {"radius", 0.3},
                      {"phase", {{"keys", {{{"time", 0}, {"phase", 0}}, {{"time", 1.0}, {"phase", 1}}}}}}};
  const json s = {
      {"format", "csrbf-scene"},
      {"version", 1},
      {"duration", 1.0},
      {"fps", 10},
      {"objects",
       {{{"name", "fish"}, {"mesh", "fish.obj"}, {"parts", {{{"name", "body"}, {"deformations", {close}}}}}}}}};
  std::ofstream(dir / "s.scene.json") << s.dump();
  const anim::Scene scene = io::read_scene(dir / "s.scene.json");
  render::GltfOptions o;
  o.compact = render::Compact::Only;
  render::GltfReport r;
  const std::vector<unsigned char> bytes = render::gltf_binary(scene, o, r);
  ASSERT_EQ(r.compact_left_out, std::vector<std::string>{"fish/body/close"});
  EXPECT_EQ(r.compact_bytes, 0u);
  const Glb glb(bytes);
  EXPECT_FALSE(glb.doc.contains("extensionsRequired"));
  expect_plays_as_the_scene(scene, o, glb, r);
  fs::remove_all(dir);
}

// A Compose part (T2 o T1, not linear in its phases) is baked; --compact writes its deformations as
// stages with one term a baked frame, replacing every baked target, and plays as the scene.
TEST(GltfCompact, ComposedPartsAreStagesWithATermAFrame) {
  const fs::path dir = fs::temp_directory_path() / "csrbf-test-compact-compose";
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* f : {"fish.obj", "fish-tail-left.controls", "fish-fin.controls"}) fs::copy_file(example(f), dir / f);
  const auto deformation = [](const char* name, const char* controls, double at) {
    return json{
        {"name", name},
        {"controls", controls},
        {"radius", 0.3},
        {"phase",
         {{"keys", {{{"time", 0}, {"phase", 0}}, {{"time", at}, {"phase", 1}}, {{"time", 1.0}, {"phase", 0.2}}}}}}};
  };
  const json s = {{"format", "csrbf-scene"},
                  {"version", 1},
                  {"duration", 1.0},
                  {"fps", 10},
                  {"objects",
                   {{{"name", "fish"},
                     {"mesh", "fish.obj"},
                     {"parts",
                      {{{"name", "body"},
                        {"combine", "compose"},
                        {"deformations",
                         {deformation("tail", "fish-tail-left.controls", 0.4),
                          deformation("fin", "fish-fin.controls", 0.7)}}}}}}}}};
  std::ofstream(dir / "s.scene.json") << s.dump();
  const anim::Scene scene = io::read_scene(dir / "s.scene.json");
  for (const render::Compact mode : {render::Compact::WithFallback, render::Compact::Only}) {
    render::GltfOptions o;
    o.compact = mode;
    render::GltfReport r;
    const std::vector<unsigned char> bytes = render::gltf_binary(scene, o, r);
    ASSERT_TRUE(r.parts[0].baked);
    EXPECT_TRUE(r.compact_left_out.empty());
    const Glb glb(bytes);
    const json& defs = glb.doc["meshes"][0]["extensions"]["CSRBF_deformation"]["deformations"];
    ASSERT_EQ(defs.size(), 2u);
    EXPECT_FALSE(defs[0].contains("stage"));
    EXPECT_EQ(defs[1]["stage"], 1);
    // One term a baked frame where the phase is not 0: frames 1..10 of 11 (t = 0 is the rest).
    EXPECT_EQ(defs[0]["terms"].size(), 10u);
    EXPECT_GT(r.replaced_target_bytes, 2 * r.compact_bytes);
    const render::GltfRuntime runtime(bytes);
    anim::Player player(scene);
    const double tol = 1e-5 * r.scene_size;
    double worst = 0;
    for (std::size_t k = 0; k + 1 < 2 * r.frames; ++k) {
      const double t = double(k) / (2 * r.fps);
      player.evaluate(t);
      std::vector<Vec3> p, n;
      runtime.deform(0, runtime.weights(0, t), p, n, true);
      const double e = worst_difference(p, player.deformed(0));
      // Between frames the stages' phases are the frames' cross-faded, within the deviation.
      EXPECT_LE(e, (k % 2 ? r.objects[0].max_deviation : 0.0) + tol) << "t = " << t;
      if (k % 2 == 0) worst = std::max(worst, e);
    }
    std::printf("compose %s: %zu bytes of extension for %zu of baked targets; at frames %.3g\n",
                mode == render::Compact::Only ? "only" : "fallback", r.compact_bytes, r.replaced_target_bytes, worst);
  }
  fs::remove_all(dir);
}

// --meshopt: every vertex, index and animation view compressed (EXT_meshopt_compression). Decoded,
// each example plays as the scene, and the runtime reads the compressed file as the plain one.
TEST(GltfMeshopt, EveryExampleDecodesToWhatPlaysAsTheScene) {
  for (const char* name : {"fish.scene.json", "face.scene.json", "ball.scene.json"})
    for (const render::Compact mode : {render::Compact::Off, render::Compact::Only}) {
      SCOPED_TRACE(name);
      const anim::Scene scene = io::read_scene(example(name));
      render::GltfOptions o;
      o.compact = mode;
      render::GltfReport plain_report, r;
      const std::vector<unsigned char> plain = render::gltf_binary(scene, o, plain_report);
      o.meshopt = true;
      const std::vector<unsigned char> packed = render::gltf_binary(scene, o, r);
      EXPECT_LT(packed.size() * 5, plain.size() * 4) << "at least 20% smaller";
      const Glb glb(packed);
      const auto& required = glb.doc["extensionsRequired"];
      EXPECT_NE(std::find(required.begin(), required.end(), "EXT_meshopt_compression"), required.end());
      EXPECT_EQ(glb.doc["buffers"].size(), 2u);
      const std::vector<unsigned char> decoded = render::gltf_without_meshopt(packed);
      if (mode == render::Compact::Off) expect_plays_as_the_scene(scene, o, Glb(decoded), r);
      const render::GltfRuntime a(plain), b(packed);
      ASSERT_EQ(a.meshes(), b.meshes());
      for (std::size_t m = 0; m < a.meshes(); ++m)
        for (const double t : {0.0, 0.73, 1.48, 2.0}) {
          std::vector<Vec3> pa, na, pb, nb;
          a.deform(m, a.weights(m, t), pa, na);
          b.deform(m, b.weights(m, t), pb, nb);
          EXPECT_EQ(pa, pb) << "mesh " << m << " at t = " << t;
          EXPECT_EQ(na, nb);
          EXPECT_EQ(std::vector<std::uint32_t>(a.triangles(m).begin(), a.triangles(m).end()).size(),
                    b.triangles(m).size());
        }
      std::printf("%s%s: %zu bytes plain, %zu with --meshopt\n", name,
                  mode == render::Compact::Only ? " --compact=only" : "", plain.size(), packed.size());
    }
}

// A compressed view that does not decode, or lies outside the file, is an error naming it.
TEST(GltfMeshopt, DamagedDataIsAnErrorNamingTheView) {
  const anim::Scene scene = io::read_scene(example("fish.scene.json"));
  render::GltfOptions o;
  o.meshopt = true;
  render::GltfReport r;
  std::vector<unsigned char> packed = render::gltf_binary(scene, o, r);
  const Glb glb(packed);
  // The first compressed view's bytes, overwritten.
  std::size_t at = 0, length = 0;
  for (const auto& v : glb.doc["bufferViews"])
    if (v.contains("extensions")) {
      at = v["extensions"]["EXT_meshopt_compression"]["byteOffset"].get<std::size_t>();
      length = v["extensions"]["EXT_meshopt_compression"]["byteLength"].get<std::size_t>();
      break;
    }
  ASSERT_GT(length, 0u);
  std::uint32_t json_length;
  std::memcpy(&json_length, packed.data() + 12, 4);
  const std::size_t bin = 20 + json_length + 8;
  std::fill(packed.begin() + std::ptrdiff_t(bin + at), packed.begin() + std::ptrdiff_t(bin + at + length), 0xff);
  try {
    render::gltf_without_meshopt(packed);
    FAIL() << "damaged data decoded";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("bufferViews["), std::string::npos) << e.what();
  }
  EXPECT_THROW(render::GltfRuntime{packed}, InvalidInput);
}

// --quantize (KHR_mesh_quantization): 16-bit positions and displacements in each object's box, 8-bit
// normals. Every example plays as the scene within 1e-5 of its size, and the file is smaller.
TEST(GltfQuantize, EveryExamplePlaysAsTheScene) {
  for (const char* name : {"fish.scene.json", "face.scene.json", "ball.scene.json"}) {
    SCOPED_TRACE(name);
    const anim::Scene scene = io::read_scene(example(name));
    render::GltfOptions o;
    render::GltfReport plain_report, r;
    const std::size_t plain = render::gltf_binary(scene, o, plain_report).size();
    o.quantize = true;
    const std::vector<unsigned char> bytes = render::gltf_binary(scene, o, r);
    const Glb glb(bytes);
    const auto& required = glb.doc["extensionsRequired"];
    EXPECT_NE(std::find(required.begin(), required.end(), "KHR_mesh_quantization"), required.end());
    const json& pos =
        glb.doc["accessors"][glb.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"].get<std::size_t>()];
    EXPECT_EQ(pos["componentType"], 5122);
    EXPECT_LT(bytes.size() * 4, plain * 3) << "at least 25% smaller";
    for (const auto& ob : r.objects) {
      EXPECT_GT(ob.quantization_error, 0.0);
      EXPECT_LT(ob.quantization_error, 1e-5 * r.scene_size);
    }
    expect_plays_as_the_scene(scene, o, glb, r);
    std::printf("%s: %zu bytes plain, %zu quantized; largest quantization error %.3g (scene %.3g)\n", name, plain,
                bytes.size(), r.objects[0].quantization_error, r.scene_size);
  }
  // Not with --compact: the extension's sources are in float coordinates.
  render::GltfOptions o;
  o.quantize = true;
  o.compact = render::Compact::Only;
  render::GltfReport r;
  EXPECT_THROW(render::gltf_binary(io::read_scene(example("fish.scene.json")), o, r),
               InvalidInput);  // csrbf throws its own errors only
}

// An exact target's normals are fitted over its phases: the blend n0 + w dn (normalised) against the
// normals of the mesh moved by w d, at w = 1/4, 1/2, 3/4 and 1, measured here from the file with
// normals of the test's own (area-weighted over the triangles, as the Player's mesh has them).
TEST(GltfExport, TargetNormalsAreFittedOverThePhases) {
  const anim::Scene scene = io::read_scene(example("fish.scene.json"));
  render::GltfReport r;
  const Glb glb(render::gltf_binary(scene, render::GltfOptions{}, r));
  const anim::Object& fish = scene.objects[0];
  const auto normals = [&](const std::vector<Vec3>& p) {
    std::vector<Vec3> n(p.size(), Vec3::Zero());
    for (const auto f : fish.faces)
      for (std::size_t k = 1; k + 1 < f.size(); ++k) {
        const Vec3 a = (p[f[k]] - p[f[0]]).cross(p[f[k + 1]] - p[f[0]]);
        for (const std::size_t v : {std::size_t(f[0]), std::size_t(f[k]), std::size_t(f[k + 1])}) n[v] += a;
      }
    return n;
  };
  const json& prim = glb.doc["meshes"][0]["primitives"][0];
  const auto n0 = glb.floats(prim["attributes"]["NORMAL"]);
  double worst = 0;
  for (std::size_t j = 0; j < prim["targets"].size(); ++j) {
    const auto d = glb.floats(prim["targets"][j]["POSITION"]);
    const auto dn = glb.floats(prim["targets"][j]["NORMAL"]);
    for (const double w : {0.25, 0.5, 0.75, 1.0}) {
      std::vector<Vec3> p(fish.rest.size());
      for (std::size_t v = 0; v < p.size(); ++v) p[v] = fish.rest[v] + w * Vec3(d[3 * v], d[3 * v + 1], d[3 * v + 2]);
      const auto want = normals(p);
      for (std::size_t v = 0; v < p.size(); ++v) {
        const Vec3 got =
            Vec3(n0[3 * v], n0[3 * v + 1], n0[3 * v + 2]) + w * Vec3(dn[3 * v], dn[3 * v + 1], dn[3 * v + 2]);
        if (want[v].norm() == 0 || got.norm() == 0) continue;
        worst = std::max(worst, std::acos(std::clamp(got.normalized().dot(want[v].normalized()), -1.0, 1.0)));
      }
    }
  }
  worst *= 180 / std::numbers::pi;
  EXPECT_NEAR(worst, r.objects[0].normal_error_deg, 0.01);
  EXPECT_LT(r.objects[0].normal_error_deg, 0.75 * r.objects[0].normal_error_endpoint_deg);
  std::printf("fish: largest normal angle %.2f deg fitted, %.2f deg with the phase-1 normals\n",
              r.objects[0].normal_error_deg, r.objects[0].normal_error_endpoint_deg);
}

// A polynomial that flattens the mesh (J singular) gives finite normals (the cofactor of J, as the
// shader computes them), and coefficients past what double sums hold are an error, not NaN vertices.
TEST(GltfCompact, SingularAndOverflowingDeformationsGiveNoNaN) {
  const anim::Scene scene = io::read_scene(example("face.scene.json"));
  render::GltfOptions o;
  o.compact = render::Compact::Only;
  render::GltfReport r;
  const Glb g(render::gltf_binary(scene, o, r));
  const auto rebuilt = [&](const json& doc) { return glb_of(doc, g.bin); };
  json flat = g.doc;
  // d(x) = -x_0 e_0: at weight 1, x' = x with its first coordinate 0 (J = diag(0, 1, 1)).
  flat["meshes"][0]["extensions"]["CSRBF_deformation"]["deformations"][0]["terms"][0]["polynomial"] =
      json::array({0, 0, 0, -1, 0, 0, 0, 0, 0, 0, 0, 0});
  const render::GltfRuntime rt(rebuilt(flat));
  std::vector<double> w(rt.weights(0, 0).size(), 0.0);
  w[0] = 1;
  std::vector<Vec3> p, n;
  rt.deform(0, w, p, n);
  for (std::size_t v = 0; v < p.size(); ++v) {
    ASSERT_TRUE(p[v].allFinite() && n[v].allFinite()) << v;
    EXPECT_NEAR(n[v].norm(), 1.0, 1e-12);
  }
  json huge = g.doc;
  huge["meshes"][0]["extensions"]["CSRBF_deformation"]["deformations"][0]["terms"][0]["polynomial"] =
      json::array({1e308, 0, 0, 1e308, 0, 0, 0, 0, 0, 0, 0, 0});
  const render::GltfRuntime big(rebuilt(huge));
  w.assign(w.size(), 0.0);
  w[0] = 10;
  EXPECT_THROW(big.deform(0, w, p, n), InvalidInput);
}
