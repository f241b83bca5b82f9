// What the glTF exporter's phases share (export.cpp): the buffer and JSON builder, each object's
// plan, the memory the export predicts, and the phases' declarations. Private to csrbf_gltf.
#pragma once

#include "csrbf/anim/scene.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/gltf/detail/meshopt_compress.hpp"
#include "csrbf/gltf/glb.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/gltf/export.hpp"
#include "csrbf/space_map.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace csrbf::gltf::export_detail {

using gltf::MeshoptView;
using nlohmann::json;

// Component types as the JSON holds them (gltf::ComponentType); buffer view targets.
constexpr int kByte = int(gltf::code(gltf::ComponentType::Byte)), kShort = int(gltf::code(gltf::ComponentType::Short)),
              kFloat = int(gltf::code(gltf::ComponentType::Float)),
              kUnsignedShort = int(gltf::code(gltf::ComponentType::UnsignedShort)),
              kUnsignedInt = int(gltf::code(gltf::ComponentType::UnsignedInt)), kArrayBuffer = 34962,
              kElementArrayBuffer = 34963;

/// A buffer view's bytes for indices below `limit`: 16-bit where every index fits, else 32-bit.
struct Indices {
  std::vector<unsigned char> bytes;
  int component = kUnsignedInt;
  Indices(const std::vector<std::uint32_t>& index, std::size_t limit) {
    if (limit <= 65536) {
      component = kUnsignedShort;
      std::vector<std::uint16_t> v(index.begin(), index.end());
      bytes.assign(reinterpret_cast<const unsigned char*>(v.data()),
                   reinterpret_cast<const unsigned char*>(v.data() + v.size()));
    } else {
      bytes.assign(reinterpret_cast<const unsigned char*>(index.data()),
                   reinterpret_cast<const unsigned char*>(index.data() + index.size()));
    }
  }
};

/// The binary buffer and the JSON's accessors and buffer views that point into it.
struct Builder {
  json doc;
  std::vector<unsigned char> bin;
  std::string where;  // what is being written, for messages

  void check_finite(const std::vector<float>& v, const char* what) const {
    for (const float x : v)
      if (!std::isfinite(x))
        throw InvalidInput("export: " + where + ": " + what +
                           " has a value beyond single precision (glTF stores float32): " + std::to_string(x));
  }

  std::vector<MeshoptView> hints;  // per buffer view: how --meshopt compresses it

  std::size_t view(const void* data, std::size_t bytes, int target = 0, MeshoptView hint = {}) {
    hints.push_back(hint);
    while (bin.size() % 4) bin.push_back(0);
    const std::size_t offset = bin.size();
    const auto* p = static_cast<const unsigned char*>(data);
    bin.insert(bin.end(), p, p + bytes);
    json v = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}};
    if (target) v["target"] = target;
    doc["bufferViews"].push_back(v);
    return doc["bufferViews"].size() - 1;
  }
  std::size_t accessor(json a) {
    doc["accessors"].push_back(std::move(a));
    return doc["accessors"].size() - 1;
  }
  /// count x width floats (VEC3, VEC4, SCALAR), with min and max.
  std::size_t floats(const std::vector<float>& v, int width, const char* what, int target = 0) {
    check_finite(v, what);
    const std::size_t count = v.size() / std::size_t(width);
    json mn = json::array(), mx = json::array();
    for (int c = 0; c < width; ++c) {
      float lo = std::numeric_limits<float>::infinity(), hi = -lo;
      for (std::size_t i = 0; i < count; ++i) {
        lo = std::min(lo, v[i * std::size_t(width) + std::size_t(c)]);
        hi = std::max(hi, v[i * std::size_t(width) + std::size_t(c)]);
      }
      mn.push_back(lo);
      mx.push_back(hi);
    }
    const char* type = width == 1 ? "SCALAR" : width == 2 ? "VEC2" : width == 3 ? "VEC3" : "VEC4";
    const MeshoptView hint{MeshoptView::Mode::Attributes, 4 * std::size_t(width)};
    return accessor({{"bufferView", view(v.data(), v.size() * 4, target, hint)},
                     {"componentType", kFloat},
                     {"count", count},
                     {"type", type},
                     {"min", mn},
                     {"max", mx}});
  }
  /// A VEC3 element's bytes: float (12), or KHR_mesh_quantization's normalized SHORT or BYTE (6 or
  /// 3), padded to 4-byte multiples where it is a vertex attribute (8 or 4).
  static std::size_t element_bytes(int component, bool padded) {
    if (component == kFloat) return 12;
    const std::size_t b = component == kShort ? 6 : 3;
    return padded ? (b + 3) / 4 * 4 : b;
  }
  /// values (xyz, in [-1, 1] for SHORT and BYTE) as count elements of component, padded or not.
  static std::vector<unsigned char> pack(const std::vector<float>& v, int component, bool padded) {
    if (component == kFloat)
      return {reinterpret_cast<const unsigned char*>(v.data()),
              reinterpret_cast<const unsigned char*>(v.data() + v.size())};
    const std::size_t n = v.size() / 3, eb = element_bytes(component, padded), cb = component == kShort ? 2 : 1;
    const double most = component == kShort ? 32767.0 : 127.0;
    std::vector<unsigned char> out(n * eb, 0);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3; ++c) {
        const auto q = std::int16_t(std::lround(std::clamp(double(v[3 * i + c]), -1.0, 1.0) * most));
        if (cb == 2)
          std::memcpy(&out[i * eb + 2 * c], &q, 2);
        else
          out[i * eb + c] = static_cast<unsigned char>(std::int8_t(q));
      }
    return out;
  }
  /// The integer a normalized SHORT or BYTE stores for x in [-1, 1] (glTF's min and max of such an
  /// accessor are these integers).
  static double stored(float x, int component) {
    if (component == kFloat) return x;
    return double(std::lround(std::clamp(double(x), -1.0, 1.0) * (component == kShort ? 32767.0 : 127.0)));
  }
  /// What a reader gets back from a normalized SHORT or BYTE: max(q / most, -1).
  static float dequantized(float x, int component) {
    if (component == kFloat) return x;
    const double most = component == kShort ? 32767.0 : 127.0;
    return float(std::max(double(std::lround(std::clamp(double(x), -1.0, 1.0) * most)) / most, -1.0));
  }
  /// The bytes of a VEC3 accessor of count entries, zero but for k listed ones: sparse (an index,
  /// 16- or 32-bit, and an element an entry; one explicit zero where none) or dense.
  static std::size_t sparse_bytes(std::size_t count, std::size_t k, int component = kFloat) {
    return std::max<std::size_t>(k, 1) * ((count <= 65536 ? 2 : 4) + element_bytes(component, false));
  }
  static std::size_t dense_bytes(std::size_t count, int component = kFloat) {
    return element_bytes(component, true) * count;
  }
  /// A VEC3 accessor of count entries, zero but for (index, value) pairs: sparse (no buffer view)
  /// where that takes fewer bytes than every entry, else dense. min and max over every entry (as a
  /// reader gets them). component: float, or normalized SHORT or BYTE with values in [-1, 1].
  std::size_t sparse_vec3(std::size_t count, std::vector<std::uint32_t> index, std::vector<float> value,
                          const char* what, int component = kFloat) {
    check_finite(value, what);
    // min and max of every entry: the zeros count only where some entry is not listed.
    const double inf = std::numeric_limits<double>::infinity();
    double lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf};
    if (index.size() < count || index.empty())
      for (int c = 0; c < 3; ++c) lo[c] = hi[c] = 0;
    for (std::size_t i = 0; i < index.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        const double x = stored(value[3 * i + std::size_t(c)], component);
        lo[c] = std::min(lo[c], x);
        hi[c] = std::max(hi[c], x);
      }
    json a = {{"componentType", component}, {"count", count}, {"type", "VEC3"}};
    if (component == kFloat) {
      a["min"] = {float(lo[0]), float(lo[1]), float(lo[2])};
      a["max"] = {float(hi[0]), float(hi[1]), float(hi[2])};
    } else {
      a["min"] = {std::lround(lo[0]), std::lround(lo[1]), std::lround(lo[2])};
      a["max"] = {std::lround(hi[0]), std::lround(hi[1]), std::lround(hi[2])};
    }
    if (component != kFloat) a["normalized"] = true;
    if (dense_bytes(count, component) < sparse_bytes(count, index.size(), component)) {
      std::vector<float> dense(3 * count, 0.0f);
      for (std::size_t i = 0; i < index.size(); ++i)
        for (int c = 0; c < 3; ++c) dense[3 * index[i] + std::size_t(c)] = value[3 * i + std::size_t(c)];
      const std::vector<unsigned char> bytes = pack(dense, component, true);
      const std::size_t eb = element_bytes(component, true);
      a["bufferView"] = view(bytes.data(), bytes.size(), 0, {MeshoptView::Mode::Attributes, eb});
      if (component != kFloat) doc["bufferViews"][a["bufferView"].get<std::size_t>()]["byteStride"] = eb;
      return accessor(std::move(a));
    }
    // Sparse with one explicit zero where nothing moves: three.js's loader (r111) drops an
    // accessor with neither a buffer view nor sparse values, and a target then fails to load.
    if (index.empty()) {
      index.push_back(0);
      value.assign(3, 0.0f);
    }
    const Indices ix(index, count);
    const std::size_t iv = view(ix.bytes.data(), ix.bytes.size(), 0,
                                {MeshoptView::Mode::Indices, ix.component == kUnsignedShort ? 2u : 4u});
    const std::vector<unsigned char> packed = pack(value, component, false);
    const std::size_t vb = element_bytes(component, false);
    const std::size_t vv =
        view(packed.data(), packed.size(), 0,
             vb % 4 == 0 ? MeshoptView{MeshoptView::Mode::Attributes, vb} : MeshoptView{MeshoptView::Mode::None, 0});
    a["sparse"] = {{"count", index.size()},
                   {"indices", {{"bufferView", iv}, {"componentType", ix.component}}},
                   {"values", {{"bufferView", vv}}}};
    return accessor(std::move(a));
  }
};

/// Area-weighted vertex normals of a surface (polygons as fans).
std::vector<Vec3> vertex_normals(const std::vector<Vec3>& p, const PolygonList& faces);

/// The (index, delta) pairs of a VEC3 field that differ from zero.
void nonzero(const std::vector<Vec3>& delta, double tolerance, std::vector<std::uint32_t>& index,
             std::vector<float>& value);

/// A rotation that turns -Z onto dir with +Y as near up as it can (glTF cameras and lights look down -Z).
Eigen::Quaterniond look_along(const Vec3& dir, const Vec3& up);

json quat_json(const Eigen::Quaterniond& q);
json vec_json(const Vec3& v);
double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

/// Sorted, unique times in [0, end] as glTF stores them (float32): the given ones, rounded, merged
/// where they round to the same float.
/// The times in [0, end] (end as float32 may round up), sorted.
inline std::vector<double> sorted_within(std::vector<double> t, double end) {
  const double last = std::max(end, double(float(end)));
  t.erase(std::remove_if(t.begin(), t.end(), [&](double x) { return !(x >= 0 && x <= last); }), t.end());
  std::sort(t.begin(), t.end());
  return t;
}

std::vector<double> unique_times(std::vector<double> t, double end);

/// What merging costs: times that round to the same float32 are one sample in the glTF, which can
/// show only one of their values. The largest gap(a, b) between the first time of such a group and
/// each other one (a track that jumps between two keys 1e-9 s apart would turn the glTF by the jump).
template <class Gap>
double merged_gap(std::vector<double> t, double end, const Gap& gap) {
  t = sorted_within(std::move(t), end);
  double worst = 0;
  for (std::size_t first = 0, i = 1; i < t.size(); ++i) {
    if (float(t[i]) != float(t[first])) {
      first = i;
      continue;
    }
    if (t[i] != t[first]) worst = std::max(worst, gap(t[first], t[i]));
  }
  return worst;
}

/// The index of the key at time t (within float rounding), or -1. Keys sorted by time.
template <class Keys>
std::ptrdiff_t key_at(const Keys& keys, double t) {
  const auto it = std::lower_bound(keys.begin(), keys.end(), t, [](const auto& k, double x) { return k.time < x; });
  const double tol = 1e-6 * std::max(1.0, std::abs(t));
  if (it != keys.end() && std::abs(it->time - t) <= tol) return it - keys.begin();
  if (it != keys.begin() && std::abs((it - 1)->time - t) <= tol) return (it - 1) - keys.begin();
  return -1;
}

/// three.js binds animation tracks by node name after PropertyBinding.sanitizeNodeName (white
/// space to '_', "[].:/" removed): names that become equal there would animate the wrong node.
std::string sanitized(const std::string& name);
std::string image_mime(const std::vector<unsigned char>& bytes, const std::string& file);
std::vector<unsigned char> read_bytes(const std::string& file);

/// What one object's deforming parts become.
struct ObjectPlan {
  std::vector<int> owner;        // per vertex: the last deforming part that holds it, or -1
  std::vector<char> baked;       // per part
  std::vector<std::string> why;  // per part: why baked
  struct Exact {
    std::size_t part, deformation;
    std::vector<Vec3> d;  // per object vertex (zero where it does not move)
    double largest = 0;   // max |d|
  };
  std::vector<Exact> exact;
  bool any_baked() const { return std::find(baked.begin(), baked.end(), 1) != baked.end(); }
};

/// What gltf_binary holds beyond the scene, in bytes (see its use).
struct ExportMemory {
  double player = 0, plans = 0, targets = 0, baked = 0, buffer = 0, weights = 0, work = 0, textures = 0;
  double total() const { return player + plans + targets + baked + buffer + weights + work + textures; }
};

/// exact[o]: object o's exact morph targets; baked[o]: whether any of its parts is baked.
ExportMemory export_memory(const anim::Scene& scene, const std::vector<std::size_t>& exact,
                           const std::vector<char>& baked, std::size_t frames, double weight_bytes);

/// Whether exact target e's deformation may move vertex v: its part owns v, and v is in its area.
bool moves_vertex(const anim::Object& obj, const ObjectPlan& plan, const ObjectPlan::Exact& e, std::size_t v);

/// A deformation of a baked part as CSRBF_deformation writes it: a fixed one with a term for each
/// baked frame where its phase is not 0; a contact's fit at one frame, with that frame's term.
struct BakedDeformation {
  std::size_t part, deformation, slot, stage;
  std::shared_ptr<const SpaceMap> map;
  std::vector<std::pair<std::size_t, double>> terms;  // (the baked target's index among them, phase)
};

/// Whether baked deformation bd may move vertex v: its part owns v, and v is in its area (a contact
/// moves its whole part).
bool baked_moves(const anim::Object& obj, const ObjectPlan& plan, const BakedDeformation& bd, std::size_t v);

/// Whether a client can evaluate radius R in single precision (R, 1/R and R^2 normal floats): the
/// range CSRBF_deformation allows, [1e-18, 1e18].
bool float_radius(double r);

/// The map as CSRBF_deformation stores it: sources, coefficients and polynomial (times scale, a
/// per-frame term's phase) rounded to float.
SpaceMap float_form(const SpaceMap& map, double scale = 1.0);

/// The export's plan, which its phases fill in order and then read: the sample times, each
/// object's plan, and the memory it predicts.
struct ExportPlan {
  ExportPlan(const anim::Scene& s, const GltfOptions& o, GltfReport& r) : scene(s), options(o), report(r) {}
  const anim::Scene& scene;
  const GltfOptions& options;
  GltfReport& report;
  double fps = 0, duration = 0;
  std::vector<double> frame_t;  // the sample times, as float32 keeps them
  std::size_t frames = 0;
  std::vector<ObjectPlan> plans;
  double plan_left = 0;  // what --memory-limit left when the plans began
  ExportMemory need;
};

/// What one pass of the player over the frames gives: the baked parts' displacements
/// ([object][frame][vertex]) and each object's largest distance of a vertex from its centre.
struct PlayedFrames {
  std::vector<std::vector<std::vector<Vec3>>> baked;
  std::vector<double> reach;
};

/// The glTF being written: the builder, the animation's channels, the textures written so far.
struct Document {
  Builder b;
  json animation = {{"name", "scene"}, {"channels", json::array()}, {"samplers", json::array()}};
  std::map<std::string, std::size_t> images;  // file -> texture index
  bool any_compact = false;
  const TextureSupport* textures = nullptr;  // the options' (texture coordinates, image check)

  void add_channel(std::size_t node, const char* path, std::size_t input, std::size_t output,
                   const char* interpolation);
  std::size_t time_accessor(const std::vector<double>& t);
  /// The material's index, its texture (checked whole, then decoded) written once.
  std::size_t material(const anim::Material& m, const std::string& name);
};

// The phases, in order (export_plan.cpp): sample times, which parts are baked, the exact
// targets, the memory bounds, the player's pass over the frames.
void plan_sample_times(ExportPlan& plan);
void plan_parts(ExportPlan& plan);
void check_target_memory(const ExportPlan& plan);
void plan_exact_targets(ExportPlan& plan);
void check_export_memory(ExportPlan& plan);
PlayedFrames play_frames(const ExportPlan& plan, anim::Player& player);

/// Writes object o (export_object.cpp): its attributes, morph targets, CSRBF_deformation,
/// primitives, nodes and channels; its report goes to plan.report.
void write_object(const ExportPlan& plan, Document& doc, anim::Player& player, const PlayedFrames& played,
                  std::size_t o);

}  // namespace csrbf::gltf::export_detail
