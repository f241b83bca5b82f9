// glTF 2.0 export of a scene: see gltf_export.hpp for what is exact and what is sampled.
#include "csrbf/render/gltf_export.hpp"

#include "csrbf/gltf/detail/meshopt_compress.hpp"
#include "csrbf/gltf/glb.hpp"
#include "csrbf/io/memory.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/scene.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/units.hpp"
#include "texture_coordinates.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <numbers>
#include <sstream>
#include <string_view>

namespace csrbf::render {
namespace {

using gltf::MeshoptView;
using nlohmann::json;
namespace fs = std::filesystem;

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
std::vector<Vec3> vertex_normals(const std::vector<Vec3>& p, const PolygonList& faces) {
  std::vector<Vec3> n(p.size(), Vec3::Zero());
  for (const auto f : faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      const Vec3 w = (p[f[k]] - p[f[0]]).cross(p[f[k + 1]] - p[f[0]]);
      n[f[0]] += w;
      n[f[k]] += w;
      n[f[k + 1]] += w;
    }
  for (auto& v : n) {
    const double l = v.norm();
    v = l > 0 ? Vec3(v / l) : Vec3(0, 0, 1);
  }
  return n;
}

/// The (index, delta) pairs of a VEC3 field that differ from zero.
void nonzero(const std::vector<Vec3>& delta, double tolerance, std::vector<std::uint32_t>& index,
             std::vector<float>& value) {
  index.clear();
  value.clear();
  for (std::size_t i = 0; i < delta.size(); ++i)
    if (delta[i].cwiseAbs().maxCoeff() > tolerance) {
      index.push_back(std::uint32_t(i));
      for (int c = 0; c < 3; ++c) value.push_back(float(delta[i][c]));
    }
}

/// A rotation that turns -Z onto dir with +Y as near up as it can (glTF cameras and lights look down -Z).
Eigen::Quaterniond look_along(const Vec3& dir, const Vec3& up) {
  const Vec3 z = (-dir).normalized();
  Vec3 x = up.cross(z);
  if (x.norm() < 1e-12) x = Vec3(0, 1, 0).cross(z).norm() > 1e-12 ? Vec3(0, 1, 0).cross(z) : Vec3(1, 0, 0).cross(z);
  x.normalize();
  const Vec3 y = z.cross(x);
  Eigen::Matrix3d m;
  m.col(0) = x;
  m.col(1) = y;
  m.col(2) = z;
  return Eigen::Quaterniond(m).normalized();
}

json quat_json(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }
json vec_json(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return 2 * std::acos(std::min(1.0, std::abs(a.dot(b))));
}

/// Sorted, unique times in [0, end] as glTF stores them (float32): the given ones, rounded, merged
/// where they round to the same float.
/// The times in [0, end] (end as float32 may round up), sorted.
std::vector<double> sorted_within(std::vector<double> t, double end) {
  const double last = std::max(end, double(float(end)));
  t.erase(std::remove_if(t.begin(), t.end(), [&](double x) { return !(x >= 0 && x <= last); }), t.end());
  std::sort(t.begin(), t.end());
  return t;
}

std::vector<double> unique_times(std::vector<double> t, double end) {
  t = sorted_within(std::move(t), end);
  std::vector<double> out;
  for (const double x : t) {
    const double f = double(float(x));
    if (out.empty() || f > out.back()) out.push_back(f);
  }
  return out;
}

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
std::string sanitized(const std::string& name) {
  std::string out;
  for (const char c : name) {
    if (std::isspace(static_cast<unsigned char>(c)))
      out.push_back('_');
    else if (std::string_view("[].:/").find(c) == std::string_view::npos)
      out.push_back(c);
  }
  return out;
}

std::string image_mime(const std::vector<unsigned char>& bytes, const std::string& file) {
  static const unsigned char png[8] = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a};
  if (bytes.size() >= 8 && std::memcmp(bytes.data(), png, 8) == 0) return "image/png";
  if (bytes.size() >= 3 && bytes[0] == 0xff && bytes[1] == 0xd8 && bytes[2] == 0xff) return "image/jpeg";
  throw io::FileError("texture '" + file + "' is not a PNG or JPEG image (glTF takes only those)");
}

std::vector<unsigned char> read_bytes(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw io::FileError("texture '" + file + "' cannot be opened: " + std::strerror(errno));
  std::vector<unsigned char> b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw io::FileError("texture '" + file + "' could not be read");
  return b;
}

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
                           const std::vector<char>& baked, std::size_t frames, double weight_bytes) {
  ExportMemory m;
  m.player = anim::Player::bytes(scene);
  m.textures = io::decoded_texture_bytes(scene, true);  // each is decoded to be checked, one at a time
  m.weights = 2.0 * weight_bytes;                       // the samples as doubles, then as floats in the buffer
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const anim::Object& obj = scene.objects[o];
    const double nv = double(obj.rest.size());
    double tris = 0, textured = obj.material.texture.empty() ? 0 : 1, keys = 0;
    for (const auto& f : obj.faces) tris += f.size() >= 3 ? double(f.size() - 2) : 0.0;
    for (const auto& p : obj.parts) {
      textured += p.material.texture.empty() ? 0 : 1;
      for (const auto& d : p.deformations) keys += double(d.schedule.keys().size());
    }
    if (obj.trajectory) keys += double(obj.trajectory->keys().size());
    keys += double(obj.orientation.keys().size());
    const double targets = double(exact[o]) + (baked[o] ? double(frames) : 0.0);
    m.plans += 4.0 * nv;                                  // each vertex's part
    m.targets += double(exact[o]) * 24.0 * nv;            // each exact target's displacements, Vec3 a vertex
    if (baked[o]) m.baked += double(frames) * nv * 48.0;  // each frame's displacements, and its target's
    // Positions and normals (float xyz), each target's displacements and normals (index and xyz at
    // most a vertex each), texture coordinates, indices, the animation's samples.
    m.buffer +=
        24.0 * nv + targets * 32.0 * nv + textured * 8.0 * nv + 12.0 * tris + (double(frames) + keys + 2.0) * 64.0;
    // While written: the float copies and rest normals (48 a vertex), a moved mesh, its normals and
    // their difference (72), the target's non-zeros (16), the triangles and their faces (16 a triangle).
    m.work = std::max(m.work, 136.0 * nv + 16.0 * tris);
  }
  std::error_code ec;
  for (const auto& t : io::texture_files(scene)) {
    const auto size = fs::file_size(t, ec);
    if (!ec) m.buffer += double(size);
  }
  return m;
}

/// Whether exact target e's deformation may move vertex v: its part owns v, and v is in its area.
bool moves_vertex(const anim::Object& obj, const ObjectPlan& plan, const ObjectPlan::Exact& e, std::size_t v) {
  const auto& area = obj.parts[e.part].deformations[e.deformation].area;
  return plan.owner[v] == int(e.part) &&
         (area.empty() || std::binary_search(area.begin(), area.end(), std::uint32_t(v)));
}

/// A deformation of a baked part as CSRBF_deformation writes it: a fixed one with a term for each
/// baked frame where its phase is not 0; a contact's fit at one frame, with that frame's term.
struct BakedDeformation {
  std::size_t part, deformation, slot, stage;
  std::shared_ptr<const SpaceMap> map;
  std::vector<std::pair<std::size_t, double>> terms;  // (the baked target's index among them, phase)
};

/// Whether baked deformation bd may move vertex v: its part owns v, and v is in its area (a contact
/// moves its whole part).
bool baked_moves(const anim::Object& obj, const ObjectPlan& plan, const BakedDeformation& bd, std::size_t v) {
  const auto& def = obj.parts[bd.part].deformations[bd.deformation];
  return plan.owner[v] == int(bd.part) &&
         (def.contact || def.area.empty() || std::binary_search(def.area.begin(), def.area.end(), std::uint32_t(v)));
}

/// Whether a client can evaluate radius R in single precision (R, 1/R and R^2 normal floats): the
/// range CSRBF_deformation allows, [1e-18, 1e18].
bool float_radius(double r) { return r >= 1e-18 && r <= 1e18; }

/// The map as CSRBF_deformation stores it: sources, coefficients and polynomial (times scale, a
/// per-frame term's phase) rounded to float.
SpaceMap float_form(const SpaceMap& map, double scale = 1.0) {
  const std::size_t n = map.size();
  std::vector<Vec3> src(n);
  Eigen::Matrix<double, Eigen::Dynamic, 3> alpha(Eigen::Index(n), 3);
  for (std::size_t i = 0; i < n; ++i) {
    src[i] = map.sources()[i].cast<float>().cast<double>();
    alpha.row(Eigen::Index(i)) = (scale * map.coefficients().row(Eigen::Index(i))).cast<float>().cast<double>();
  }
  Eigen::Matrix<double, 4, 3> beta = Eigen::Matrix<double, 4, 3>::Zero();
  if (map.polynomial() != Polynomial::None) beta = (scale * map.polynomial_coefficients()).cast<float>().cast<double>();
  FitOptions fo;
  fo.radius = map.radius();
  fo.kernel = map.kernel();
  fo.polynomial = map.polynomial() == Polynomial::None ? Polynomial::None : Polynomial::Linear;
  return SpaceMap::from_solution(src, alpha, beta, Vec3::Zero(), 1.0, fo);
}

}  // namespace

std::vector<unsigned char> gltf_binary(const anim::Scene& scene, const GltfOptions& options, GltfReport& report) {
  if (options.quantize && options.compact != Compact::Off)
    throw InvalidInput(
        "gltf_binary: quantize with compact: CSRBF_deformation's sources and radius are in float coordinates");
  const double fps = options.fps > 0 ? options.fps : scene.fps;
  if (!(fps > 0) || !std::isfinite(fps)) throw InvalidInput("export: the frame rate must be > 0");
  const double duration = scene.duration;
  // The sample times: the frames k / fps, and the duration where it falls between two (so that
  // what is sampled or baked is measured to the end). Times as glTF keeps them, in float32.
  constexpr double kMaxFrames = 1e5;
  const double grid = std::floor(duration * fps + 1e-9) + 1;
  if (!(grid <= kMaxFrames)) {
    std::ostringstream m;
    m << "export: the scene's duration " << duration << " s at " << fps << " fps is " << grid
      << " frames; at most 100000 are sampled (lower --fps)";
    throw InvalidInput(m.str());
  }
  std::vector<double> frame_t;
  for (std::size_t k = 0; k < std::size_t(grid); ++k) frame_t.push_back(double(float(double(k) / fps)));
  if (double(float(duration)) > frame_t.back() && duration - frame_t.back() > 1e-9)
    frame_t.push_back(double(float(duration)));
  const std::size_t frames = frame_t.size();
  report = GltfReport{};
  report.fps = fps;
  report.frames = frames;

  // Which parts are exact and which are baked.
  std::vector<ObjectPlan> plans(scene.objects.size());
  const double plan_left = io::memory_left(options.memory_limit_bytes);
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const anim::Object& obj = scene.objects[o];
    ObjectPlan& plan = plans[o];
    plan.owner.assign(obj.rest.size(), -1);
    plan.baked.assign(obj.parts.size(), 0);
    plan.why.assign(obj.parts.size(), {});
    for (std::size_t p = 0; p < obj.parts.size(); ++p) {
      const anim::Part& part = obj.parts[p];
      if (part.deformations.empty()) continue;
      for (const auto v : part.vertices) plan.owner[v] = int(p);
      bool contact = false;
      for (const auto& d : part.deformations) contact |= d.contact.has_value();
      if (contact)
        plan.why[p] = "a contact deformation is refitted every frame";
      else if (part.combine == anim::Combine::Compose && part.deformations.size() > 1)
        plan.why[p] = "composed deformations (T2 o T1) are not linear in their phases";
      else if (options.bake == Bake::Always)
        plan.why[p] = "--bake always";
      if (!plan.why[p].empty()) {
        if (options.bake == Bake::Never)
          throw InvalidInput("export: objects[" + std::to_string(o) + "] '" + obj.name + "' part '" + part.name +
                             "' needs baking (" + plan.why[p] + "), and --bake never forbids it");
        plan.baked[p] = 1;
      }
    }
  }
  // The exact targets' displacements, bounded before they are computed (16384 deformations on a
  // mesh of 6158 vertices would be 2.4 GB): at most 2 GiB, and what the program leaves of the limit.
  // As planned so far, each deformation of a part not baked is an exact target.
  std::vector<std::size_t> candidates(scene.objects.size(), 0);
  std::vector<char> baked(scene.objects.size(), 0);
  for (std::size_t o = 0; o < scene.objects.size(); ++o)
    for (std::size_t p = 0; p < scene.objects[o].parts.size(); ++p) {
      if (plans[o].baked[p])
        baked[o] = 1;
      else
        candidates[o] += scene.objects[o].parts[p].deformations.size();
    }
  const ExportMemory planned = export_memory(scene, candidates, baked, frames, 0.0);
  if (planned.targets > 2.0 * kGiB)
    throw InvalidInput("export: the morph targets would take " +
                       std::to_string(std::llround(planned.targets / double(1 << 20))) +
                       " MiB (at most 2048): fewer deformations or smaller meshes");
  if (planned.targets > plan_left) {
    // The limit to give is the whole export's as planned (the weights not yet counted), so that the
    // advice is not followed by another.
    std::ostringstream m;
    m.precision(3);
    m << "export: the morph targets would take " << planned.targets / kGiB << " GiB, more than the " << plan_left / kGiB
      << " GiB that --memory-limit leaves after the scene; give --memory-limit "
      << std::ceil(100 * (options.memory_limit_bytes - plan_left + planned.total()) / kGiB) / 100
      << " or more (the whole glTF's, as planned)";
    throw InvalidInput(m.str());
  }
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const anim::Object& obj = scene.objects[o];
    ObjectPlan& plan = plans[o];
    // The exact targets, and the most active at once; over the limit, the object is baked.
    const auto exact_targets = [&] {
      plan.exact.clear();
      for (std::size_t p = 0; p < obj.parts.size(); ++p) {
        const anim::Part& part = obj.parts[p];
        if (part.deformations.empty() || plan.baked[p]) continue;
        for (std::size_t k = 0; k < part.deformations.size(); ++k) {
          const anim::Deformation& def = part.deformations[k];
          std::vector<Vec3> x;
          std::vector<std::uint32_t> which;
          for (const auto v : part.vertices) {
            if (plan.owner[v] != int(p)) continue;
            if (!def.area.empty() && !std::binary_search(def.area.begin(), def.area.end(), v)) continue;
            which.push_back(v);
            x.push_back(obj.rest[v]);
          }
          std::vector<Vec3> d(x.size());
          if (!x.empty()) def.map->displacements(x.data()->data(), d.data()->data(), x.size());
          ObjectPlan::Exact e{p, k, std::vector<Vec3>(obj.rest.size(), Vec3::Zero()), 0.0};
          for (std::size_t i = 0; i < which.size(); ++i) {
            if (!d[i].allFinite())
              throw InvalidInput("export: objects[" + std::to_string(o) + "] '" + obj.name + "' part '" + part.name +
                                 "' deformation '" + def.name + "' moves vertex " + std::to_string(which[i]) +
                                 " to a non-finite position");
            e.d[which[i]] = d[i];
            e.largest = std::max(e.largest, d[i].norm());
          }
          plan.exact.push_back(std::move(e));
        }
      }
    };
    exact_targets();
    const auto most_active = [&] {
      std::size_t most = 0;
      std::vector<double> times = frame_t;
      for (const auto& e : plan.exact)
        for (const auto& key : obj.parts[e.part].deformations[e.deformation].schedule.keys()) times.push_back(key.time);
      for (const double t : unique_times(times, duration)) {
        std::size_t n = plan.any_baked() ? 2 : 0;
        for (const auto& e : plan.exact)
          n += obj.parts[e.part].deformations[e.deformation].schedule.phase(t) != 0.0 && e.largest > 0;
        most = std::max(most, n);
      }
      return most;
    };
    if (most_active() > options.max_active && options.bake == Bake::Auto) {
      for (std::size_t p = 0; p < obj.parts.size(); ++p)
        if (!obj.parts[p].deformations.empty() && !plan.baked[p]) {
          plan.baked[p] = 1;
          plan.why[p] =
              "the object would have more than " + std::to_string(options.max_active) + " morph targets active at once";
        }
      exact_targets();
    }
  }

  // Memory, bounded before anything large is built: the weights (a value a target and sample
  // time), and baking's frames (the exact targets were bounded above).
  double weight_bytes = 0;
  {
    for (std::size_t o = 0; o < scene.objects.size(); ++o) {
      const double targets = double(plans[o].exact.size()) + (plans[o].any_baked() ? double(frames) : 0.0);
      double times = double(frames) + 1;
      for (const auto& part : scene.objects[o].parts)
        for (const auto& def : part.deformations) times += double(def.schedule.keys().size());
      weight_bytes += times * targets * 12.0;
    }
    if (weight_bytes > 0.5 * kGiB)
      throw InvalidInput("export: the morph weights would take " +
                         std::to_string(std::llround(weight_bytes / double(1 << 20))) +
                         " MiB (at most 512): fewer deformations, a lower --fps, or less baking");
  }
  // What the export holds beyond the scene, predicted before anything large is built and bounded
  // by what the program leaves of --memory-limit (and baking by 4 GiB): the player, each object's
  // plan, exact targets and baked frames, the binary buffer (an upper bound: every target dense,
  // which is also reserved, so that it grows without copies), the weights, and the largest object's
  // work while it is written (float copies, normals of a moved mesh, a target's non-zeros).
  std::vector<std::size_t> exact(scene.objects.size());
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    exact[o] = plans[o].exact.size();
    baked[o] = plans[o].any_baked();  // auto-baking may have baked more
  }
  const ExportMemory need = export_memory(scene, exact, baked, frames, weight_bytes);
  if (need.baked > 4.0 * kGiB)
    throw InvalidInput("export: baking " + std::to_string(frames) + " frames would take " +
                       std::to_string(std::llround(need.baked / double(1 << 20))) +
                       " MiB (at most 4096): lower --fps, or bake less (--bake auto or never)");
  {
    // The plans and the exact targets are made and held already: what the program holds counts them.
    const double left = io::memory_left(options.memory_limit_bytes) + need.plans + need.targets;
    if (need.total() > left) {
      std::ostringstream m;
      m.precision(3);
      m << "export: writing the glTF takes about " << need.total() / kGiB << " GiB (the player " << need.player / kGiB
        << ", the buffer " << need.buffer / kGiB << ", morph targets and baked frames "
        << (need.targets + need.baked) / kGiB << (need.textures > 0 ? ", a texture decoded " : "");
      if (need.textures > 0) m << need.textures / kGiB;
      m << "), more than the " << left / kGiB << " GiB that --memory-limit leaves after the scene; give --memory-limit "
        << std::ceil(100 * (options.memory_limit_bytes - left + need.total()) / kGiB) / 100 << " or more"
        << (need.baked > 0 ? ", a lower --fps, or bake less (--bake auto or never)" : "");
      throw InvalidInput(m.str());
    }
  }

  // One pass of the player over the frames: the baked parts' displacements, and the scene's size.
  anim::Player player(scene);
  std::vector<std::vector<std::vector<Vec3>>> baked_frames(scene.objects.size());  // [object][frame][vertex]
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  std::vector<double> reach(scene.objects.size(), 0.0);  // largest distance of a vertex from the centre
  for (std::size_t k = 0; k < frames; ++k) {
    player.evaluate(frame_t[k]);
    for (std::size_t o = 0; o < scene.objects.size(); ++o) {
      const anim::Object& obj = scene.objects[o];
      for (const auto& p : player.positions(o)) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      for (const auto& p : player.deformed(o)) reach[o] = std::max(reach[o], (p - obj.centre).norm());
      if (!plans[o].any_baked()) continue;
      std::vector<Vec3> d(obj.rest.size(), Vec3::Zero());
      const auto& model = player.deformed(o);
      for (std::size_t v = 0; v < obj.rest.size(); ++v)
        if (plans[o].owner[v] >= 0 && plans[o].baked[std::size_t(plans[o].owner[v])]) d[v] = model[v] - obj.rest[v];
      baked_frames[o].push_back(std::move(d));
    }
  }
  report.scene_size = (hi - lo).norm();

  Builder b;
  // Reserved whole (pages not written are not resident), so that the buffer never grows by copying
  // and the glb's header goes in front of it in place; 1 MiB for that header and the JSON.
  b.bin.reserve(std::size_t(need.buffer) + (1u << 20));
  b.doc["asset"] = {{"version", "2.0"}, {"generator", "csrbf export"}};
  b.doc["scene"] = 0;
  b.doc["scenes"] = json::array({json{{"name", "scene"}, {"nodes", json::array()}}});
  b.doc["scenes"][0]["extras"] = {{"csrbf",
                                   {{"duration", duration},
                                    {"fps", fps},
                                    {"background", vec_json(scene.background)},
                                    {"view_angle", scene.camera.view_angle}}}};
  b.doc["nodes"] = json::array();
  b.doc["meshes"] = json::array();
  b.doc["materials"] = json::array();
  b.doc["accessors"] = json::array();
  b.doc["bufferViews"] = json::array();
  json animation = {{"name", "scene"}, {"channels", json::array()}, {"samplers", json::array()}};
  const auto add_channel = [&](std::size_t node, const char* path, std::size_t input, std::size_t output,
                               const char* interpolation) {
    animation["samplers"].push_back({{"input", input}, {"output", output}, {"interpolation", interpolation}});
    animation["channels"].push_back(
        {{"sampler", animation["samplers"].size() - 1}, {"target", {{"node", node}, {"path", path}}}});
  };
  const auto time_accessor = [&](const std::vector<double>& t) {
    std::vector<float> f(t.begin(), t.end());
    return b.floats(f, 1, "the animation times");
  };
  std::map<std::string, std::size_t> images;  // file -> texture index
  const auto material = [&](const anim::Material& m, const std::string& name) {
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
        check_image_decodes(m.texture);
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
  };

  bool any_compact = false;
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const anim::Object& obj = scene.objects[o];
    const ObjectPlan& plan = plans[o];
    GltfObjectReport orep;
    orep.name = obj.name;
    orep.vertices = obj.rest.size();
    const std::size_t nv = obj.rest.size();
    b.where = "objects[" + std::to_string(o) + "] '" + obj.name + "'";
    bool triangles = false;
    for (const auto f : obj.faces) triangles |= f.size() >= 3;
    if (!triangles)
      throw InvalidInput("export: " + b.where +
                         " has no faces (polygons of 3 or more vertices): glTF draws meshes as triangles");
    report.frame_bytes += frames * nv * 12;

    // The shared attributes: rest positions and normals.
    std::vector<float> pos(3 * nv), nor(3 * nv);
    const std::vector<Vec3> rest_normals = vertex_normals(obj.rest, obj.faces);
    for (std::size_t v = 0; v < nv; ++v)
      for (int c = 0; c < 3; ++c) {
        pos[3 * v + std::size_t(c)] = float(obj.rest[v][c]);
        nor[3 * v + std::size_t(c)] = float(rest_normals[v][c]);
      }
    // --quantize (KHR_mesh_quantization): positions as normalized SHORT in the box's frame (centre
    // qc, half side qk: the mesh node scales them back), normals as normalized BYTE; the targets'
    // displacements as SHORT in the same frame, their normals' changes as BYTE, each where it fits
    // in [-1, 1] (else float). The largest vertex error this makes is reported.
    Vec3 qc = Vec3::Zero();
    double qk = 1.0;
    if (options.quantize) {
      Vec3 lo = obj.rest.front(), hi = lo;
      for (const Vec3& x : obj.rest) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
      qc = 0.5 * (lo + hi);
      qk = 0.5 * (hi - lo).maxCoeff();
      if (!(qk > 0)) qk = 1.0;
    }
    double quantization_error = 0;
    const auto quantized_attribute = [&](const std::vector<float>& v, int component, const char* what) {
      b.check_finite(v, what);
      const std::vector<unsigned char> bytes = Builder::pack(v, component, true);
      const std::size_t eb = Builder::element_bytes(component, true);
      const std::size_t view = b.view(bytes.data(), bytes.size(), kArrayBuffer, {MeshoptView::Mode::Attributes, eb});
      b.doc["bufferViews"][view]["byteStride"] = eb;
      json mn = json::array(), mx = json::array();
      for (std::size_t c = 0; c < 3; ++c) {
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (std::size_t i = 0; i < v.size() / 3; ++i) {
          lo = std::min(lo, Builder::stored(v[3 * i + c], component));
          hi = std::max(hi, Builder::stored(v[3 * i + c], component));
        }
        mn.push_back(std::lround(lo));
        mx.push_back(std::lround(hi));
      }
      return b.accessor({{"bufferView", view},
                         {"componentType", component},
                         {"normalized", true},
                         {"count", v.size() / 3},
                         {"type", "VEC3"},
                         {"min", mn},
                         {"max", mx}});
    };
    std::size_t pos_acc = 0, nor_acc = 0;
    if (options.quantize) {
      std::vector<float> qp(pos.size());
      for (std::size_t v = 0; v < nv; ++v)
        for (int c = 0; c < 3; ++c) {
          const double x = (obj.rest[v][c] - qc[c]) / qk;
          qp[3 * v + std::size_t(c)] = float(x);
          quantization_error =
              std::max(quantization_error, std::abs(double(Builder::dequantized(float(x), kShort)) - x) * qk);
        }
      pos_acc = quantized_attribute(qp, kShort, "the rest positions");
      nor_acc = quantized_attribute(nor, kByte, "the rest normals");
    } else {
      pos_acc = b.floats(pos, 3, "the rest positions", kArrayBuffer);
      nor_acc = b.floats(nor, 3, "the rest normals", kArrayBuffer);
    }

    // The morph targets: exact ones, then one a frame for the baked parts (frames where nothing
    // moves have none).
    json targets = json::array();
    std::vector<std::uint32_t> index, nindex;
    std::vector<float> value, nvalue;
    // A target's displacements and its normals' change, as (index, value) lists, and their bytes as
    // sparse accessors (an index and a float xyz an entry; one explicit zero where none).
    int pcomp = kFloat, ncomp = kFloat;  // the last target_data's components (--quantize)
    // A target's normals: a client blends n0 + w dn (then normalises) at weight w. For an exact
    // target (w is its phase, anywhere in [0, 1]), dn is fitted by least squares to the deformed
    // mesh's normals at w = 1/4, 1/2, 3/4 and 1, which lowers the largest angle against them
    // (dn = n(1) - n0 is right at w = 1 only); a baked frame's target (w is 1 at its frame) keeps
    // n(1) - n0. The largest angle at those weights is reported, with the endpoint's for comparison.
    std::vector<Vec3> moved(nv), dn(nv);
    const auto target_data = [&](const std::vector<Vec3>& d, bool fit_phases = false) {
      nonzero(d, 0.0, index, value);
      for (std::size_t v = 0; v < nv; ++v) moved[v] = obj.rest[v] + d[v];
      const std::vector<Vec3> n1 = vertex_normals(moved, obj.faces);
      for (std::size_t v = 0; v < nv; ++v) dn[v] = n1[v] - rest_normals[v];
      if (fit_phases) {
        constexpr double ws[] = {0.25, 0.5, 0.75, 1.0};
        std::vector<std::vector<Vec3>> at;
        for (const double w : ws) {
          if (w == 1.0) {
            at.push_back(n1);  // the mesh moved by d, as computed above
            continue;
          }
          for (std::size_t v = 0; v < nv; ++v) moved[v] = obj.rest[v] + w * d[v];
          at.push_back(vertex_normals(moved, obj.faces));
        }
        const auto angle = [](const Vec3& a, const Vec3& b) {
          const double na = a.norm(), nb = b.norm();
          if (!(na > 0 && nb > 0)) return 0.0;
          return std::acos(std::clamp(a.dot(b) / (na * nb), -1.0, 1.0)) * 180.0 / std::numbers::pi;
        };
        for (std::size_t v = 0; v < nv; ++v) {
          Vec3 num = Vec3::Zero();
          double den = 0;
          for (std::size_t k = 0; k < 4; ++k) {
            num += ws[k] * (at[k][v] - rest_normals[v]);
            den += ws[k] * ws[k];
          }
          const Vec3 fitted = num / den;
          for (std::size_t k = 0; k < 4; ++k) {
            orep.normal_error_endpoint_deg =
                std::max(orep.normal_error_endpoint_deg, angle(rest_normals[v] + ws[k] * dn[v], at[k][v]));
            orep.normal_error_deg = std::max(orep.normal_error_deg, angle(rest_normals[v] + ws[k] * fitted, at[k][v]));
          }
          dn[v] = fitted;
        }
      }
      nonzero(dn, 1e-6, nindex, nvalue);
      pcomp = ncomp = kFloat;
      if (options.quantize) {
        // In the quantized frame, where every value fits [-1, 1]: SHORT displacements, BYTE normals.
        double most = 0, nmost = 0, err = 0;
        for (float& x : value) {
          x = float(double(x) / qk);
          most = std::max(most, double(std::abs(x)));
        }
        for (const float x : nvalue) nmost = std::max(nmost, double(std::abs(x)));
        if (most <= 1.0) {
          pcomp = kShort;
          for (const float x : value) err = std::max(err, std::abs(double(Builder::dequantized(x, kShort)) - x) * qk);
          quantization_error = std::max(quantization_error, 2 * err);  // the rest's and the target's
        } else {
          for (float& x : value) x = float(double(x) * qk);  // back: a float target
        }
        if (nmost <= 1.0) ncomp = kByte;
      }
      const auto bytes = [&](std::size_t k, int component) {
        return std::min(Builder::sparse_bytes(nv, k, component), Builder::dense_bytes(nv, component));
      };
      return bytes(index.size(), pcomp) + bytes(nindex.size(), ncomp);
    };
    // Targets whose displacements are identical (a baked part at rest over several frames) share
    // their accessors: stored once.
    // Keyed by a hash of the float values; a hit is compared whole with the earlier target's
    // displacements (held by the plan or the baked frames: nothing is copied).
    std::multimap<std::uint64_t, std::pair<const std::vector<Vec3>*, json>> written;
    // Returns the target's bytes as target_data gives them.
    const auto add_target = [&](const std::vector<Vec3>& d, bool fit_phases = false) {
      const std::size_t bytes = target_data(d, fit_phases);
      std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the listed indices and float values
      const auto mix = [&](const void* p, std::size_t n) {
        for (std::size_t i = 0; i < n; ++i) h = (h ^ static_cast<const unsigned char*>(p)[i]) * 1099511628211ull;
      };
      mix(index.data(), index.size() * sizeof(std::uint32_t));
      mix(value.data(), value.size() * sizeof(float));
      for (auto [it, end] = written.equal_range(h); it != end; ++it)
        if (*it->second.first == d) {
          targets.push_back(it->second.second);
          ++report.shared_targets;
          return bytes;
        }
      const std::size_t pa = b.sparse_vec3(nv, index, value, "a morph target's displacements", pcomp);
      const std::size_t na = b.sparse_vec3(nv, nindex, nvalue, "a morph target's normals", ncomp);
      const json t = {{"POSITION", pa}, {"NORMAL", na}};
      targets.push_back(t);
      written.emplace(h, std::make_pair(&d, t));
      return bytes;
    };
    std::vector<std::string> target_names;
    // --compact: which exact deformations the extension holds. Each is evaluated the way a client
    // evaluates it, from float sources and coefficients at the float rest positions, against the
    // exact displacement; one whose float form errs by more than 1e-5 of the object's rest size
    // (coefficients far above the displacements: controls nearly on top of each other) stays an
    // ordinary morph target, and the report says so.
    std::vector<char> in_extension(plan.exact.size(), 0);
    std::vector<double> float_error(plan.exact.size(), 0.0);
    if (options.compact != Compact::Off && !plan.exact.empty()) {
      Vec3 lo = obj.rest.front(), hi = lo;
      for (const Vec3& p : obj.rest) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
      const double tolerance = 1e-5 * (hi - lo).norm();
      for (std::size_t j = 0; j < plan.exact.size(); ++j) {
        const auto& e = plan.exact[j];
        const SpaceMap written = float_form(*obj.parts[e.part].deformations[e.deformation].map);
        std::vector<Vec3> x;
        std::vector<std::size_t> which;
        for (std::size_t v = 0; v < nv; ++v)
          if (e.d[v] != Vec3::Zero() || moves_vertex(obj, plan, e, v)) {
            which.push_back(v);
            x.push_back(obj.rest[v].cast<float>().cast<double>());
          }
        std::vector<Vec3> dw(x.size());
        if (!x.empty()) written.displacements(x.data()->data(), dw.data()->data(), x.size());
        double err = 0;
        for (std::size_t i = 0; i < x.size(); ++i) {
          const double d = (dw[i] - e.d[which[i]]).norm();
          err = std::isnan(d) ? std::numeric_limits<double>::infinity() : std::max(err, d);
        }
        float_error[j] = err;
        in_extension[j] = err <= tolerance && float_radius(written.radius());
        if (!in_extension[j]) {
          const auto& def = obj.parts[e.part].deformations[e.deformation];
          report.compact_left_out.push_back(obj.name + "/" + obj.parts[e.part].name + "/" + def.name);
        }
      }
    }
    // The baked frames (frames where nothing moves have no target); their targets follow the exact ones.
    std::vector<std::size_t> baked_frame;  // the frame of each baked target
    if (plan.any_baked())
      for (std::size_t k = 0; k < frames; ++k) {
        bool moves = false;
        for (const auto& d : baked_frames[o][k]) moves |= d != Vec3::Zero();
        if (moves) baked_frame.push_back(k);
      }
    // --compact: the baked parts as CSRBF_deformation too. Each baked target's frame becomes terms
    // of its weight: a fixed deformation keeps its sources, with one term a frame, its coefficients
    // times the frame's phase; a contact, refitted every frame, is a deformation a frame (its
    // sources move) with one term. A Compose part's deformations are stages, in order. The baked
    // targets are replaced only where every frame's float form, evaluated as a client evaluates
    // it, is within the tolerance of the baked displacement.
    std::vector<BakedDeformation> baked_defs;
    std::vector<std::pair<std::size_t, std::size_t>> baked_slots;  // (part, deformation) for vertex groups
    bool baked_in_extension = false;
    double baked_error = 0;
    if (options.compact != Compact::Off && !baked_frame.empty()) {
      for (std::size_t p = 0; p < obj.parts.size(); ++p) {
        const anim::Part& part = obj.parts[p];
        if (!plan.baked[p]) continue;
        for (std::size_t i = 0; i < part.deformations.size(); ++i) {
          const anim::Deformation& def = part.deformations[i];
          const std::size_t stage = part.combine == anim::Combine::Compose ? i : 0;
          const std::size_t slot = baked_slots.size();
          baked_slots.emplace_back(p, i);
          if (def.map) baked_defs.push_back({p, i, slot, stage, std::make_shared<SpaceMap>(*def.map), {}});
          for (std::size_t j = 0; j < baked_frame.size(); ++j) {
            const double t = frame_t[baked_frame[j]];
            const double phase = def.schedule.phase(t);
            if (phase == 0.0) continue;
            if (def.map) {
              baked_defs.back().terms.emplace_back(j, phase);
            } else if (auto fit = player.contact_map(o, p, i, t)) {
              baked_defs.push_back({p, i, slot, stage, std::make_shared<SpaceMap>(std::move(*fit)), {{j, phase}}});
            }
          }
        }
      }
      Vec3 lo = obj.rest.front(), hi = lo;
      for (const Vec3& x : obj.rest) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
      const double tolerance = 1e-5 * (hi - lo).norm();
      for (std::size_t j = 0; j < baked_frame.size() && baked_error <= tolerance; ++j) {
        const auto& want = baked_frames[o][baked_frame[j]];
        for (std::size_t p = 0; p < obj.parts.size(); ++p) {
          if (!plan.baked[p]) continue;
          std::vector<std::size_t> verts;
          for (std::size_t v = 0; v < nv; ++v)
            if (plan.owner[v] == int(p)) verts.push_back(v);
          std::vector<Vec3> x(verts.size()), y, dw;
          for (std::size_t i = 0; i < verts.size(); ++i) x[i] = obj.rest[verts[i]].cast<float>().cast<double>();
          std::size_t stage_count = 0;
          for (const auto& bd : baked_defs)
            if (bd.part == p) stage_count = std::max(stage_count, bd.stage + 1);
          for (std::size_t stage = 0; stage < stage_count; ++stage) {
            y = x;
            for (const auto& bd : baked_defs) {
              if (bd.part != p || bd.stage != stage) continue;
              const auto term =
                  std::find_if(bd.terms.begin(), bd.terms.end(), [&](const auto& t) { return t.first == j; });
              if (term == bd.terms.end()) continue;
              const SpaceMap form = float_form(*bd.map, term->second);
              std::vector<Vec3> at;
              std::vector<std::size_t> which;
              for (std::size_t i = 0; i < verts.size(); ++i)
                if (baked_moves(obj, plan, bd, verts[i])) {
                  which.push_back(i);
                  at.push_back(x[i]);
                }
              dw.resize(at.size());
              if (!at.empty()) form.displacements(at.data()->data(), dw.data()->data(), at.size());
              for (std::size_t i = 0; i < at.size(); ++i) y[which[i]] += dw[i];
            }
            x = y;
          }
          for (std::size_t i = 0; i < verts.size(); ++i) {
            const double d = (x[i] - (obj.rest[verts[i]] + want[verts[i]])).norm();
            baked_error = std::isnan(d) ? std::numeric_limits<double>::infinity() : std::max(baked_error, d);
          }
        }
      }
      bool radii = true;
      for (const auto& bd : baked_defs) radii = radii && float_radius(bd.map->radius());
      baked_in_extension = baked_error <= tolerance && radii;
      if (!baked_in_extension) {
        baked_defs.clear();
        baked_slots.clear();
        for (std::size_t p = 0; p < obj.parts.size(); ++p)
          if (plan.baked[p]) report.compact_left_out.push_back(obj.name + "/" + obj.parts[p].name + " (baked)");
      }
    }
    const bool compact =
        std::find(in_extension.begin(), in_extension.end(), 1) != in_extension.end() || baked_in_extension;
    std::size_t zero_target = 0;  // --compact=only: the accessor of the targets the extension replaces
    if (compact && options.compact == Compact::Only)
      zero_target = b.accessor({{"componentType", kFloat},
                                {"count", nv},
                                {"type", "VEC3"},
                                {"min", {0.0, 0.0, 0.0}},
                                {"max", {0.0, 0.0, 0.0}}});
    for (std::size_t j = 0; j < plan.exact.size(); ++j) {
      const auto& e = plan.exact[j];
      // The target's displacements and normals are computed once: written as fallback, or only
      // measured where --compact=only leaves the target empty.
      std::size_t bytes = 0;
      if (in_extension[j] && options.compact == Compact::Only) {
        bytes = target_data(e.d, true);
        targets.push_back({{"POSITION", zero_target}, {"NORMAL", zero_target}});
      } else {
        bytes = add_target(e.d, true);
      }
      if (in_extension[j]) report.replaced_target_bytes += bytes;
      target_names.push_back(obj.parts[e.part].deformations[e.deformation].name);
    }
    // CSRBF_deformation (--compact): each exact target's deformation as its sources, coefficients,
    // radius and polynomial, its term's weight the target's, which it replaces. Where deformations
    // move only some vertices (their part's, their area's), a vertex group a vertex: the set of
    // deformations that move it, numbered.
    json compact_json;
    std::size_t group_accessor = 0;
    bool grouped = false;
    if (compact) {
      // Slots: the exact targets j, then each baked part's deformations (plan.exact.size() + slot).
      const auto moves = [&](std::size_t j, std::size_t v) {
        return in_extension[j] && moves_vertex(obj, plan, plan.exact[j], v);
      };
      std::map<std::vector<std::uint32_t>, std::uint32_t> ids;
      std::vector<std::uint32_t> group(nv), signature;
      for (std::size_t v = 0; v < nv; ++v) {
        signature.clear();
        for (std::size_t j = 0; j < plan.exact.size(); ++j)
          if (moves(j, v)) signature.push_back(std::uint32_t(j));
        for (std::size_t k = 0; k < baked_slots.size(); ++k) {
          const BakedDeformation probe{baked_slots[k].first, baked_slots[k].second, k, 0, nullptr, {}};
          if (baked_moves(obj, plan, probe, v)) signature.push_back(std::uint32_t(plan.exact.size() + k));
        }
        group[v] = ids.emplace(signature, std::uint32_t(ids.size())).first->second;
      }
      const auto held = std::size_t(std::count(in_extension.begin(), in_extension.end(), 1)) + baked_slots.size();
      grouped = !(ids.size() == 1 && ids.begin()->first.size() == held);
      if (grouped && ids.size() > 65536)
        throw InvalidInput("export: " + b.where + " --compact: its deformations split the vertices into " +
                           std::to_string(ids.size()) +
                           " groups (each a set of deformations that move a vertex); CSRBF_deformation numbers at "
                           "most 65536 (_CSRBF_GROUP is UNSIGNED_SHORT)");
      std::vector<json> groups_of(plan.exact.size() + baked_slots.size(), json::array());
      for (const auto& [set, id] : ids)
        for (const std::uint32_t j : set) groups_of[j].push_back(id);
      if (grouped) {
        // UNSIGNED_SHORT, one a vertex at a stride of 4 bytes: glTF aligns every vertex attribute's
        // elements to 4 bytes.
        std::vector<std::uint16_t> packed(2 * nv, 0);
        for (std::size_t v = 0; v < nv; ++v) packed[2 * v] = std::uint16_t(group[v]);
        const std::size_t view =
            b.view(packed.data(), packed.size() * 2, kArrayBuffer, {MeshoptView::Mode::Attributes, 4});
        b.doc["bufferViews"][view]["byteStride"] = 4;
        group_accessor =
            b.accessor({{"bufferView", view}, {"componentType", kUnsignedShort}, {"count", nv}, {"type", "SCALAR"}});
        report.compact_bytes += packed.size() * 2;
        orep.groups = ids.size();
      }
      json defs = json::array();
      // A deformation: its sources, kernel and radius, and one term a (weight, phase) of terms:
      // the coefficients and polynomial times the phase, in float.
      const auto write = [&](const SpaceMap& map, const std::vector<std::pair<std::size_t, double>>& terms,
                             std::size_t stage, std::size_t slot, const std::string& name, const std::string& part) {
        const std::size_t n = map.size();
        std::vector<float> src(3 * n), coef(3 * n);
        for (std::size_t i = 0; i < n; ++i)
          for (int c = 0; c < 3; ++c) src[3 * i + std::size_t(c)] = float(map.sources()[i][c]);
        json term_list = json::array();
        for (const auto& [weight, phase] : terms) {
          for (std::size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c)
              coef[3 * i + std::size_t(c)] = float(phase * map.coefficients()(Eigen::Index(i), c));
          json term = {{"weight", weight}};
          if (map.polynomial() != Polynomial::None) {
            json poly = json::array();
            const Eigen::Matrix<double, 4, 3> pc = map.polynomial_coefficients();
            for (int r = 0; r < 4; ++r)
              for (int c = 0; c < 3; ++c) poly.push_back(float(phase * pc(r, c)));
            term["polynomial"] = poly;
          }
          term["coefficients"] = b.floats(coef, 3, "a deformation's coefficients");
          report.compact_bytes += 12 * n;
          term_list.push_back(std::move(term));
        }
        const std::size_t sa = b.floats(src, 3, "a deformation's sources");
        report.compact_bytes += 12 * n;
        std::string kernel(kernel_name(map.kernel()));
        for (char& ch : kernel) ch = char(std::toupper(static_cast<unsigned char>(ch)));
        json d = {{"kernel", kernel}, {"radius", map.radius()}, {"sources", sa}, {"terms", std::move(term_list)}};
        if (stage > 0) d["stage"] = stage;
        d["extras"] = {{"name", name}, {"part", part}};
        if (grouped) d["groups"] = groups_of[slot];
        defs.push_back(std::move(d));
        ++orep.compact_deformations;
      };
      for (std::size_t j = 0; j < plan.exact.size(); ++j) {
        if (!in_extension[j]) continue;
        const auto& e = plan.exact[j];
        const anim::Deformation& def = obj.parts[e.part].deformations[e.deformation];
        orep.compact_error = std::max(orep.compact_error, float_error[j]);
        write(*def.map, {{j, 1.0}}, 0, j, def.name, obj.parts[e.part].name);
      }
      for (const auto& bd : baked_defs) {
        if (bd.terms.empty()) continue;  // a fixed deformation whose phase is 0 at every baked frame
        std::vector<std::pair<std::size_t, double>> terms;
        for (const auto& [j, phase] : bd.terms) terms.emplace_back(plan.exact.size() + j, phase);
        write(*bd.map, terms, bd.stage, plan.exact.size() + bd.slot,
              obj.parts[bd.part].deformations[bd.deformation].name, obj.parts[bd.part].name);
      }
      if (baked_in_extension) orep.compact_error = std::max(orep.compact_error, baked_error);
      compact_json = {{"deformations", defs}};
      if (!std::isfinite(orep.compact_error))
        throw InvalidInput("export: " + b.where +
                           " --compact: a deformation evaluated from its float sources and "
                           "coefficients is not finite (coefficients beyond single precision?)");
    }
    for (const std::size_t k : baked_frame) {
      std::size_t bytes = 0;
      if (baked_in_extension && options.compact == Compact::Only) {
        bytes = target_data(baked_frames[o][k]);
        targets.push_back({{"POSITION", zero_target}, {"NORMAL", zero_target}});
      } else {
        bytes = add_target(baked_frames[o][k]);
      }
      if (baked_in_extension) report.replaced_target_bytes += bytes;
      char name[64];
      std::snprintf(name, sizeof name, "baked frame %zu (t = %.4g s)", k, frame_t[k]);
      target_names.push_back(name);
    }
    const std::size_t ntargets = targets.size();
    orep.targets = ntargets;

    // Weights at time t: the phases of the exact targets, and the baked frames' cross-fade.
    const auto weights_at = [&](double t, std::vector<double>& w) {
      w.assign(ntargets, 0.0);
      for (std::size_t j = 0; j < plan.exact.size(); ++j) {
        const auto& e = plan.exact[j];
        w[j] = obj.parts[e.part].deformations[e.deformation].schedule.phase(t);
      }
      if (baked_frame.empty()) return;
      // The sample interval [f0, f0 + 1] holding t, and how far into it.
      std::size_t f0 = frames - 1;
      double s = 0;
      if (t <= frame_t.front()) {
        f0 = 0;
      } else if (t < frame_t.back()) {
        f0 = std::size_t(std::upper_bound(frame_t.begin(), frame_t.end(), t) - frame_t.begin()) - 1;
        s = (t - frame_t[f0]) / (frame_t[f0 + 1] - frame_t[f0]);
      }
      for (std::size_t j = 0; j < baked_frame.size(); ++j) {
        if (baked_frame[j] == f0) w[plan.exact.size() + j] = 1 - s;
        if (baked_frame[j] == f0 + 1) w[plan.exact.size() + j] = s;
      }
    };

    // The primitives: faces in no part with the object's look, then each part's own faces.
    json primitives = json::array();
    std::vector<int> face_owner(obj.faces.size(), -1);
    for (std::size_t p = 0; p < obj.parts.size(); ++p)
      for (const auto f : obj.parts[p].faces) face_owner[f] = int(p);
    for (int p = -1; p < int(obj.parts.size()); ++p) {
      std::vector<std::uint32_t> tri;
      std::vector<std::uint32_t> face_list;
      for (std::size_t f = 0; f < obj.faces.size(); ++f)
        if (face_owner[f] == p) {
          face_list.push_back(std::uint32_t(f));
          const auto poly = obj.faces[f];
          for (std::size_t k = 1; k + 1 < poly.size(); ++k) tri.insert(tri.end(), {poly[0], poly[k], poly[k + 1]});
        }
      if (tri.empty()) continue;
      const anim::Material& m = p < 0 ? obj.material : obj.parts[std::size_t(p)].material;
      const std::string mname = obj.name + (p < 0 ? std::string() : " / " + obj.parts[std::size_t(p)].name);
      json attrs = {{"POSITION", pos_acc}, {"NORMAL", nor_acc}};
      if (grouped) attrs["_CSRBF_GROUP"] = group_accessor;
      if (!m.texture.empty()) {
        std::vector<float> uv;
        try {
          uv = texture_coordinates(obj, face_list, m.mapping);
        } catch (const InvalidInput& e) {
          throw InvalidInput("export: " + b.where + " " +
                             (p < 0 ? std::string() : "part '" + obj.parts[std::size_t(p)].name + "' ") + e.what());
        }
        attrs["TEXCOORD_0"] = b.floats(uv, 2, "the texture coordinates", kArrayBuffer);
      }
      // 16-bit where every vertex index fits (65535 is primitive restart in some APIs: kept out).
      const Indices ix(tri, nv <= 65535 ? nv : std::size_t(65537));
      const std::size_t iv = b.view(ix.bytes.data(), ix.bytes.size(), kElementArrayBuffer,
                                    {MeshoptView::Mode::Triangles, ix.component == kUnsignedShort ? 2u : 4u});
      const std::size_t ia = b.accessor({{"bufferView", iv},
                                         {"componentType", ix.component},
                                         {"count", tri.size()},
                                         {"type", "SCALAR"},
                                         {"min", {*std::min_element(tri.begin(), tri.end())}},
                                         {"max", {*std::max_element(tri.begin(), tri.end())}}});
      json prim = {{"attributes", attrs}, {"indices", ia}, {"material", material(m, mname)}, {"mode", 4}};
      if (ntargets) prim["targets"] = targets;
      primitives.push_back(prim);
    }
    json mesh = {{"name", obj.name}, {"primitives", primitives}};
    std::vector<double> w0;
    if (ntargets) {
      weights_at(0.0, w0);
      mesh["weights"] = w0;
      mesh["extras"] = {{"targetNames", target_names}};
    }
    if (compact) {
      mesh["extensions"] = {{"CSRBF_deformation", compact_json}};
      any_compact = true;
    }
    b.doc["meshes"].push_back(mesh);
    const std::size_t mesh_index = b.doc["meshes"].size() - 1;

    // The pivot (the centre of gravity, moved and turned) and, under it, the mesh (model coordinates).
    const std::size_t pivot = b.doc["nodes"].size();
    b.doc["nodes"].push_back({{"name", obj.name + " pivot"}, {"children", {pivot + 1}}});
    json mesh_json = {{"name", obj.name}, {"mesh", mesh_index}, {"translation", vec_json(qc - obj.centre)}};
    if (options.quantize) mesh_json["scale"] = {qk, qk, qk};  // KHR_mesh_quantization's positions back
    b.doc["nodes"].push_back(std::move(mesh_json));
    b.doc["scenes"][0]["nodes"].push_back(pivot);
    const std::size_t mesh_node = pivot + 1;

    // Translation: the trajectory, key for key (cut at 0 and at the duration), as CUBICSPLINE.
    if (obj.trajectory && obj.trajectory->keys().size() > 1) {
      const anim::PositionTrack& tr = *obj.trajectory;
      const auto& keys = tr.keys();
      std::vector<double> times = {0.0, duration};
      for (const auto& k : keys) times.push_back(k.time);
      orep.max_deviation +=
          merged_gap(times, duration, [&](double a, double c) { return (tr.position(a) - tr.position(c)).norm(); });
      times = unique_times(times, duration);
      std::vector<float> out;
      for (const double t : times) {
        Vec3 in_tangent = Vec3::Zero(), out_tangent = Vec3::Zero();
        const std::ptrdiff_t at = key_at(keys, t);
        const auto key = at < 0 ? keys.end() : keys.begin() + at;
        if (key != keys.end()) {
          const auto i = std::size_t(at);
          if (i > 0) in_tangent = tr.in_tangents()[i] / (keys[i].time - keys[i - 1].time);
          if (i + 1 < keys.size()) out_tangent = tr.out_tangents()[i] / (keys[i + 1].time - keys[i].time);
        } else if (t > keys.front().time && t < keys.back().time) {
          in_tangent = out_tangent = tr.velocity(t);
        }
        const Vec3 p = key != keys.end() ? key->position : tr.position(t);
        for (const Vec3& v : {in_tangent, p, out_tangent})
          for (int c = 0; c < 3; ++c) out.push_back(float(v[c]));
      }
      // Between samples the engine evaluates the cubic Hermite spline of what is written: measured
      // against the trajectory at 7 points of each interval.
      const auto written = [&](std::size_t i, int part) {
        return Vec3(out[9 * i + 3 * part], out[9 * i + 3 * part + 1], out[9 * i + 3 * part + 2]);
      };
      double spline_error = 0;
      for (std::size_t i = 0; i + 1 < times.size(); ++i)
        for (int s = 1; s < 8; ++s) {
          const double h = s / 8.0, dt = times[i + 1] - times[i], h2 = h * h, h3 = h2 * h;
          const Vec3 p = (2 * h3 - 3 * h2 + 1) * written(i, 1) + (h3 - 2 * h2 + h) * dt * written(i, 2) +
                         (-2 * h3 + 3 * h2) * written(i + 1, 1) + (h3 - h2) * dt * written(i + 1, 0);
          spline_error = std::max(spline_error, (p - tr.position(times[i] + h * dt)).norm());
        }
      orep.max_deviation += spline_error;
      add_channel(pivot, "translation", time_accessor(times), b.floats(out, 3, "the trajectory"), "CUBICSPLINE");
      b.doc["nodes"][pivot]["translation"] = vec_json(tr.position(0.0));
    } else {
      b.doc["nodes"][pivot]["translation"] = vec_json(anim::pose_at(obj, 0.0).position);
    }

    // Rotation: slerp tracks key for key; squad sampled at the frame rate (and at its keys).
    const anim::OrientationTrack& ot = obj.orientation;
    if (ot.keys().size() > 1) {
      std::vector<double> times = {0.0, duration};
      for (const auto& k : ot.keys()) times.push_back(k.time);
      if (ot.interpolation() == anim::Rotation::Squad) times.insert(times.end(), frame_t.begin(), frame_t.end());
      double worst = merged_gap(times, duration,
                                [&](double a, double c) { return angle_between(ot.rotation(a), ot.rotation(c)); });
      times = unique_times(times, duration);
      std::vector<Eigen::Quaterniond> q;
      for (const double t : times) {
        Eigen::Quaterniond r = ot.rotation(t);
        if (!q.empty() && q.back().dot(r) < 0) r.coeffs() = -r.coeffs();
        q.push_back(r);
      }
      if (ot.interpolation() == anim::Rotation::Squad)
        for (std::size_t i = 0; i + 1 < times.size(); ++i)
          for (int s = 1; s < 8; ++s) {
            const double h = s / 8.0;
            worst = std::max(worst, angle_between(anim::slerp(q[i], q[i + 1], h),
                                                  ot.rotation(times[i] + h * (times[i + 1] - times[i]))));
          }
      orep.rotation_deviation_deg = worst * 180 / std::numbers::pi;
      orep.max_deviation += worst * reach[o];
      std::vector<float> out;
      for (const auto& r : q)
        for (const double c : {r.x(), r.y(), r.z(), r.w()}) out.push_back(float(c));
      add_channel(pivot, "rotation", time_accessor(times), b.floats(out, 4, "the orientation"), "LINEAR");
      b.doc["nodes"][pivot]["rotation"] = quat_json(q.front());
    } else {
      b.doc["nodes"][pivot]["rotation"] = quat_json(ot.rotation(0.0));
    }

    // Weights: at the frames, the phase keys and the duration, LINEAR.
    if (ntargets) {
      std::vector<double> times = frame_t;
      times.push_back(duration);
      for (const auto& e : plan.exact)
        for (const auto& key : obj.parts[e.part].deformations[e.deformation].schedule.keys()) times.push_back(key.time);
      const auto weights_gap = [&](double a, double c) {
        double e = 0;
        for (const auto& x : plan.exact) {
          const auto& schedule = obj.parts[x.part].deformations[x.deformation].schedule;
          e += std::abs(schedule.phase(a) - schedule.phase(c)) * x.largest;
        }
        return e;
      };
      orep.max_deviation += merged_gap(times, duration, weights_gap);
      times = unique_times(times, duration);
      std::vector<float> out;
      std::vector<std::vector<double>> w(times.size());
      for (std::size_t i = 0; i < times.size(); ++i) {
        weights_at(times[i], w[i]);
        for (const double x : w[i]) out.push_back(float(x));
      }
      add_channel(mesh_node, "weights", time_accessor(times), b.floats(out, 1, "the morph weights"), "LINEAR");
      // Between samples the engine interpolates the weights linearly: a smooth schedule's error,
      // times its target's largest displacement.
      double weight_error = 0;
      for (std::size_t i = 0; i + 1 < times.size(); ++i)
        for (int s = 1; s < 8; ++s) {
          const double h = s / 8.0, t = times[i] + h * (times[i + 1] - times[i]);
          double e = 0;
          for (std::size_t j = 0; j < plan.exact.size(); ++j) {
            const auto& x = plan.exact[j];
            const double truth = obj.parts[x.part].deformations[x.deformation].schedule.phase(t);
            e += std::abs(truth - ((1 - h) * w[i][j] + h * w[i + 1][j])) * x.largest;
          }
          weight_error = std::max(weight_error, e);
        }
      orep.max_deviation += weight_error;
      // The most targets active at once.
      for (const auto& wi : w) {
        std::size_t n = 0;
        for (const double x : wi) n += x != 0.0;
        orep.max_active = std::max(orep.max_active, n);
      }
      if (!baked_frame.empty()) orep.max_active = std::max<std::size_t>(orep.max_active, 2);
    }
    report.targets += ntargets;
    report.max_active = std::max(report.max_active, orep.max_active);
    for (std::size_t p = 0; p < obj.parts.size(); ++p) {
      if (obj.parts[p].deformations.empty()) continue;
      GltfPartReport pr{obj.name, obj.parts[p].name, 0, plan.baked[p] != 0, plan.why[p]};
      for (const auto& e : plan.exact) pr.targets += e.part == p;
      if (pr.baked) pr.targets = baked_frame.size();
      report.parts.push_back(pr);
      for (const auto& def : obj.parts[p].deformations) {
        // The deformation as csrbf keeps it: sources and coefficients (doubles) and the radius;
        // a contact deformation's 13 controls.
        const std::size_t n = def.map ? def.map->size() : 13;
        report.csrbf_bytes += n * 48 + 8;
      }
    }
    orep.quantization_error = quantization_error;
    orep.max_deviation += quantization_error;
    report.objects.push_back(orep);
  }

  // Baking's error between frames: the player at seven points of every frame interval against the
  // cross-fade of the two frames' targets; added to the sampled rotation's and weights' errors.
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
          const auto& a = baked_frames[o][k];
          const auto& c = baked_frames[o][k + 1];
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

  // The camera, looking from its position to its focal point, and the lights (KHR_lights_punctual).
  const anim::Camera& cam = scene.camera;
  const double distance = (cam.focal_point - cam.position).norm();
  b.doc["cameras"] = json::array({json{{"name", "camera"},
                                       {"type", "perspective"},
                                       {"perspective",
                                        {{"yfov", cam.view_angle * std::numbers::pi / 180},
                                         {"znear", std::max(1e-6, 0.01 * distance)},
                                         {"zfar", std::max(1.0, 100 * std::max(distance, report.scene_size))}}}}});
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
  // Node names as three.js binds animations to them: two equal after sanitizing would animate the
  // wrong node (an object "a pivot" beside an object "a", or "x y" beside "x_y").
  std::map<std::string, std::string> seen;
  for (const auto& n : b.doc["nodes"]) {
    const std::string name = n.value("name", "");
    const auto [it, fresh] = seen.emplace(sanitized(name), name);
    if (!fresh)
      throw InvalidInput("export: the nodes '" + it->second + "' and '" + name +
                         "' have the same name once engines sanitize it (three.js: '" + it->first +
                         "'); rename the object so that animations reach the right node");
  }
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

  // The glb: header, the JSON chunk (padded with spaces), the binary chunk.
  const std::vector<unsigned char> head = gltf::glb_head(b.doc.dump(), b.bin.size(), "export");
  // In front of the binary chunk, in place where the reserve has room (no second copy of the buffer).
  std::vector<unsigned char> glb = std::move(b.bin);
  glb.insert(glb.begin(), head.begin(), head.end());
  report.bytes = glb.size();
  return glb;
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

}  // namespace csrbf::render
