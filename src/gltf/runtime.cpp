// GltfRuntime: a glb's meshes as a client of CSRBF_deformation plays them (gltf_runtime.hpp).
#include "csrbf/gltf/runtime.hpp"

#include "csrbf/gltf/glb.hpp"
#include "csrbf/gltf/meshopt.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/space_map.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

namespace csrbf::gltf {
namespace {

using nlohmann::json;

std::string field(const char* what, std::size_t i) { return std::string(what) + "[" + std::to_string(i) + "]"; }

/// doc[key], an array, or an empty one where doc has no key (by reference: no copy of a deep
/// document); InvalidInput where it is not an array.
const json& array_of(const json& doc, const char* key) {
  static const json empty = json::array();
  if (!doc.is_object()) return empty;
  const auto it = doc.find(key);
  if (it == doc.end()) return empty;
  if (!it->is_array())
    throw InvalidInput(std::string("glTF: '") + key + "' is " + it->dump().substr(0, 40) + ", not an array");
  return *it;
}
/// A non-negative integer field (absent: fallback); InvalidInput naming it otherwise.
std::size_t index_of(const json& o, const char* key, const std::string& where, std::size_t fallback = SIZE_MAX) {
  const auto it = o.find(key);
  if (it == o.end()) {
    if (fallback != SIZE_MAX) return fallback;
    throw InvalidInput("glTF: " + where + " has no " + key);
  }
  if (!it->is_number_unsigned())
    throw InvalidInput("glTF: " + where + "." + key + " is " + it->dump().substr(0, 40) + ", not an integer >= 0");
  return it->get<std::size_t>();
}

/// An accessor's values as doubles (count x components), through its buffer view (byteOffset,
/// byteStride), or zero where it has none, with its sparse entries applied. Every range is checked
/// against the buffer before anything is allocated.
class Accessors {
 public:
  Accessors(const json& doc, std::span<const unsigned char> bin) : doc_(doc), bin_(bin) {}

  /// expect: the count the accessor must have (0: any). An accessor without data (no buffer view,
  /// no sparse values: all zero) is accepted only with expect given: its size is then known good.
  /// empty_if_zero: such an accessor comes back empty rather than as expect zeros.
  std::vector<double> read(std::size_t index, int components, const char* role, std::size_t expect = 0,
                           bool empty_if_zero = false) const {
    const json& accessors = array_of(doc_, "accessors");
    if (index >= accessors.size())
      throw InvalidInput("glTF: " + std::string(role) + " names accessor " + std::to_string(index) + " of " +
                         std::to_string(accessors.size()));
    const json& a = accessors[index];
    const std::string where = field("accessors", index);
    if (!a.is_object()) throw InvalidInput("glTF: " + where + " is not an object");
    const std::string type = a.contains("type") && a["type"].is_string() ? a["type"].get<std::string>() : "";
    const int width = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3 : type == "VEC4" ? 4 : 0;
    if (width != components)
      throw InvalidInput("glTF: " + where + " (" + role + ") has type '" + type + "', expected " +
                         (components == 1 ? "SCALAR" : "VEC" + std::to_string(components)));
    const std::size_t count = index_of(a, "count", where);
    if (count == 0 || count > (std::size_t(1) << 31) || (expect && count != expect))
      throw InvalidInput("glTF: " + where + ".count is " + std::to_string(count) +
                         (expect ? ", expected " + std::to_string(expect) + " (" + role + ")" : std::string()));
    const std::size_t ct = index_of(a, "componentType", where);
    const std::size_t size = component_size(ct, where);
    const std::size_t element = size * std::size_t(width);
    const bool has_view = a.contains("bufferView"), has_sparse = a.contains("sparse");
    if (!has_view && !expect)
      throw InvalidInput("glTF: " + where + " (" + role + ") has no bufferView: its values must be stored");
    if (!has_view && !has_sparse && empty_if_zero) return {};
    View v{};
    if (has_view) {
      v = view(index_of(a, "bufferView", where), index_of(a, "byteOffset", where, 0), element, where);
      // The last element's end, without overflow: (count - 1) * step + element <= available.
      if (v.available < element || (count - 1) > (v.available - element) / v.stride)
        throw InvalidInput("glTF: " + where + " runs past its buffer view (" + std::to_string(count) + " elements of " +
                           std::to_string(element) + " bytes, stride " + std::to_string(v.stride) + ", " +
                           std::to_string(v.available) + " bytes available)");
    }
    std::vector<double> out(count * std::size_t(width), 0.0);
    if (has_view)
      for (std::size_t i = 0; i < count; ++i)
        for (int c = 0; c < width; ++c)
          out[i * std::size_t(width) + std::size_t(c)] = value(v.p + i * v.stride + std::size_t(c) * size, ct);
    if (has_sparse) {
      const json& sp = a["sparse"];
      const std::string sw = where + ".sparse";
      if (!sp.is_object() || !sp.contains("indices") || !sp.contains("values") || !sp["indices"].is_object() ||
          !sp["values"].is_object())
        throw InvalidInput("glTF: " + sw + " needs indices and values objects");
      const std::size_t n = index_of(sp, "count", sw);
      if (n == 0 || n > count) throw InvalidInput("glTF: " + sw + ".count is " + std::to_string(n));
      const json& ix = sp["indices"];
      const json& vs = sp["values"];
      const std::size_t ict = index_of(ix, "componentType", sw + ".indices");
      if (!is_unsigned_integer(ict))
        throw InvalidInput("glTF: " + sw + ".indices.componentType " + std::to_string(ict) +
                           " is not an unsigned integer type");
      const std::size_t isize = component_size(ict, sw + ".indices");
      const View iv = view(index_of(ix, "bufferView", sw + ".indices"), index_of(ix, "byteOffset", sw + ".indices", 0),
                           isize, sw + ".indices");
      const View vv = view(index_of(vs, "bufferView", sw + ".values"), index_of(vs, "byteOffset", sw + ".values", 0),
                           element, sw + ".values");
      if (n > iv.available / isize || n > vv.available / element)
        throw InvalidInput("glTF: " + sw + " runs past its buffer views");
      for (std::size_t k = 0; k < n; ++k) {
        const auto i = std::size_t(value(iv.p + k * isize, ict));
        if (i >= count)
          throw InvalidInput("glTF: " + sw + " index " + std::to_string(i) + " is not below count " +
                             std::to_string(count));
        for (int c = 0; c < width; ++c)
          out[i * std::size_t(width) + std::size_t(c)] = value(vv.p + k * element + std::size_t(c) * size, ct);
      }
    }
    for (const double x : out)
      if (!std::isfinite(x)) throw InvalidInput("glTF: " + where + " (" + role + ") holds a value that is not finite");
    return out;
  }

  /// The component type of accessor index (checked by read()).
  std::size_t component_type(std::size_t index) const {
    return index_of(array_of(doc_, "accessors").at(index), "componentType", field("accessors", index));
  }

 private:
  struct View {
    const unsigned char* p;
    std::size_t stride, available;
  };
  /// bufferViews[index] from offset; its stride checked as glTF bounds it (4 to 252, a multiple of
  /// 4, at least the element).
  View view(std::size_t index, std::size_t offset, std::size_t element, const std::string& who) const {
    const json& views = array_of(doc_, "bufferViews");
    if (index >= views.size())
      throw InvalidInput("glTF: " + who + " names bufferViews[" + std::to_string(index) + "] of " +
                         std::to_string(views.size()));
    const json& v = views[index];
    const std::string where = field("bufferViews", index);
    if (!v.is_object()) throw InvalidInput("glTF: " + where + " is not an object");
    if (index_of(v, "buffer", where) != 0) throw InvalidInput("glTF: " + where + " is not in the glb's buffer");
    const std::size_t start = index_of(v, "byteOffset", where, 0), length = index_of(v, "byteLength", where);
    if (start > bin_.size() || length > bin_.size() - start)
      throw InvalidInput("glTF: " + where + " (offset " + std::to_string(start) + ", length " + std::to_string(length) +
                         ") lies outside the " + std::to_string(bin_.size()) + "-byte binary chunk");
    if (offset > length)
      throw InvalidInput("glTF: " + who + ".byteOffset " + std::to_string(offset) + " lies beyond " + where + "'s " +
                         std::to_string(length) + " bytes");
    const std::size_t stride = index_of(v, "byteStride", where, 0);
    if (stride && (stride < 4 || stride > 252 || stride % 4 || stride < element))
      throw InvalidInput("glTF: " + where + ".byteStride " + std::to_string(stride) +
                         " is not a multiple of 4 in [4, 252] of at least the " + std::to_string(element) +
                         "-byte element");
    return {bin_.data() + start + offset, stride ? stride : element, length - offset};
  }
  /// The components read here: unsigned integers and floats.
  static std::size_t component_size(std::size_t ct, const std::string& where) {
    if (!is_unsigned_integer(ct) && ct != code(ComponentType::Float))
      throw InvalidInput("glTF: " + where + ".componentType " + std::to_string(ct) + " is not read here");
    return gltf::component_size(ct);
  }
  static double value(const unsigned char* p, std::size_t ct) {
    if (ct == code(ComponentType::Float)) {
      float f;
      std::memcpy(&f, p, 4);
      return double(f);
    }
    if (ct == code(ComponentType::UnsignedInt)) {
      std::uint32_t u;
      std::memcpy(&u, p, 4);
      return double(u);
    }
    if (ct == code(ComponentType::UnsignedShort)) {
      std::uint16_t u;
      std::memcpy(&u, p, 2);
      return double(u);
    }
    return double(*p);
  }
  const json& doc_;
  std::span<const unsigned char> bin_;
};

std::vector<Vec3> vec3s(const std::vector<double>& v) {
  std::vector<Vec3> out(v.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
  return out;
}

struct Term {
  std::size_t weight;
  SpaceMap map;
};
struct Deformation {
  std::size_t stage = 0;
  std::vector<std::uint32_t> vertices;  // the vertices it moves (its groups'), ascending
  std::vector<Term> terms;
};
struct Mesh {
  std::string name;
  std::vector<Vec3> rest, normal;
  std::vector<std::uint32_t> triangles;  // every primitive's, three vertices each
  std::vector<std::vector<Vec3>> target_position, target_normal;
  std::vector<double> default_weights;
  std::vector<Deformation> deformations;
  std::vector<char> replaced;  // per target: named by a term
  // The weights channel: key times, values (a row of targets a key), interpolation.
  std::vector<double> times, values;
  std::string interpolation;
};

/// A mesh's rest positions, normals and every primitive's triangles (load's first phase). Every
/// primitive of a csrbf mesh shares its attributes and targets: the first stands for all.
void load_geometry(const Accessors& acc, const json& m, const std::string& where, Mesh& out) {
  const json& prims = array_of(m, "primitives");
  if (prims.empty() || !prims[0].is_object()) throw InvalidInput("glTF: " + where + " has no primitives");
  const json& prim = prims[0];
  if (!prim.contains("attributes") || !prim["attributes"].is_object())
    throw InvalidInput("glTF: " + where + ".primitives[0] has no attributes");
  const json& attrs = prim["attributes"];
  const std::string aw = where + ".primitives[0].attributes";
  out.rest = vec3s(acc.read(index_of(attrs, "POSITION", aw), 3, "POSITION"));
  const std::size_t nv = out.rest.size();
  out.normal = attrs.contains("NORMAL") ? vec3s(acc.read(index_of(attrs, "NORMAL", aw), 3, "NORMAL", nv))
                                        : std::vector<Vec3>(nv, Vec3::Zero());
  for (std::size_t pi = 0; pi < prims.size(); ++pi) {
    const json& pr = prims[pi];
    const std::string pw = where + ".primitives[" + std::to_string(pi) + "]";
    if (!pr.is_object()) throw InvalidInput("glTF: " + pw + " is not an object");
    if (pr.contains("mode") && !(pr["mode"].is_number_unsigned() && pr["mode"].get<std::uint64_t>() == 4))
      throw InvalidInput("glTF: " + pw + ".mode " + pr["mode"].dump() + " is not 4 (triangles)");
    std::vector<double> idx;
    if (!pr.contains("attributes") || !pr["attributes"].is_object() ||
        index_of(pr["attributes"], "POSITION", pw + ".attributes") != index_of(attrs, "POSITION", aw))
      throw InvalidInput("glTF: " + pw +
                         ": its POSITION is not the first primitive's (a csrbf mesh's primitives "
                         "share their vertices)");
    if (pr.contains("indices")) {
      const std::size_t ia = index_of(pr, "indices", pw);
      if (const std::size_t ct = acc.component_type(ia); !is_unsigned_integer(ct))
        throw InvalidInput("glTF: " + pw + ".indices: componentType " + std::to_string(ct) +
                           " is not an unsigned integer type");
      idx = acc.read(ia, 1, "indices");
    } else {
      idx.resize(nv);
      for (std::size_t i = 0; i < nv; ++i) idx[i] = double(i);
    }
    if (idx.size() % 3 != 0)
      throw InvalidInput("glTF: " + pw + " draws " + std::to_string(idx.size()) + " vertices" +
                         (pr.contains("indices") ? " (indices)" : " (no indices: every vertex)") +
                         ", not whole triangles");
    for (std::size_t i = 0; i < idx.size(); ++i) {
      if (!(idx[i] >= 0 && idx[i] < double(nv)))
        throw InvalidInput("glTF: " + pw + ": index " + std::to_string(i) + " is " + std::to_string(idx[i]) +
                           ", past the " + std::to_string(nv) + " vertices");
      out.triangles.push_back(std::uint32_t(idx[i]));
    }
  }
}

/// The first primitive's morph targets and the mesh's default weights (load's second phase).
void load_targets(const Accessors& acc, const json& m, const std::string& where, Mesh& out) {
  const json& prim = array_of(m, "primitives")[0];
  const std::size_t nv = out.rest.size();
  const json& targets = array_of(prim, "targets");
  for (std::size_t ti = 0; ti < targets.size(); ++ti) {
    const json& t = targets[ti];
    const std::string tw = where + ".primitives[0].targets[" + std::to_string(ti) + "]";
    if (!t.is_object()) throw InvalidInput("glTF: " + tw + " is not an object");
    // Empty: a target without data (all zero), as --compact=only writes the replaced ones.
    out.target_position.push_back(t.contains("POSITION")
                                      ? vec3s(acc.read(index_of(t, "POSITION", tw), 3, "a target's POSITION", nv, true))
                                      : std::vector<Vec3>{});
    out.target_normal.push_back(t.contains("NORMAL")
                                    ? vec3s(acc.read(index_of(t, "NORMAL", tw), 3, "a target's NORMAL", nv, true))
                                    : std::vector<Vec3>{});
  }
  const std::size_t nt = out.target_position.size();
  out.default_weights.assign(nt, 0.0);
  if (m.contains("weights")) {
    const json& w = m["weights"];
    if (!w.is_array() || w.size() != nt)
      throw InvalidInput("glTF: " + where + ".weights is not an array of " + std::to_string(nt) +
                         " numbers (one a morph target)");
    for (std::size_t j = 0; j < nt; ++j) {
      if (!w[j].is_number())
        throw InvalidInput("glTF: " + where + ".weights[" + std::to_string(j) + "] is not a number");
      out.default_weights[j] = w[j].get<double>();
    }
  }
  out.replaced.assign(nt, 0);
}

/// A deformation's term: its weight's index (below nt) and its map from the sources, the term's
/// coefficients and its polynomial.
Term read_term(const Accessors& acc, const json& t, const std::string& tw, std::size_t nt,
               const std::vector<Vec3>& sources, double radius, Kernel kernel) {
  if (!t.is_object()) throw InvalidInput("glTF: " + tw + " is not an object");
  const std::size_t w = index_of(t, "weight", tw);
  if (w >= nt)
    throw InvalidInput("glTF: " + tw + ": weight " + std::to_string(w) + " is not below the mesh's " +
                       std::to_string(nt) + " weights");
  const std::vector<double> c = acc.read(index_of(t, "coefficients", tw), 3, "coefficients", sources.size());
  Eigen::Matrix<double, Eigen::Dynamic, 3> alpha(Eigen::Index(sources.size()), 3);
  for (std::size_t i = 0; i < sources.size(); ++i)
    for (int k = 0; k < 3; ++k) alpha(Eigen::Index(i), k) = c[3 * i + std::size_t(k)];
  Eigen::Matrix<double, 4, 3> beta = Eigen::Matrix<double, 4, 3>::Zero();
  FitOptions fo;
  fo.radius = radius;
  fo.kernel = kernel;
  fo.polynomial = Polynomial::None;
  if (t.contains("polynomial")) {
    const json& p = t["polynomial"];
    if (!p.is_array() || p.size() != 12)
      throw InvalidInput("glTF: " + tw + ".polynomial is not an array of 12 numbers");
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 3; ++k) {
        const json& x = p[std::size_t(3 * r + k)];
        if (!x.is_number() || !std::isfinite(x.get<double>()))
          throw InvalidInput("glTF: " + tw + ".polynomial holds " + x.dump().substr(0, 40) + ", not a number");
        beta(r, k) = x.get<double>();
      }
    fo.polynomial = Polynomial::Linear;
  }
  return {w, SpaceMap::from_solution(sources, alpha, beta, Vec3::Zero(), 1.0, fo)};
}

/// One deformation of CSRBF_deformation: its kernel, radius, stage, the vertices its groups move
/// (group: each vertex's _CSRBF_GROUP, empty where the mesh has none) and its terms, each marked
/// in out.replaced.
Deformation read_deformation(const Accessors& acc, const json& d, const std::string& dw,
                             const std::vector<double>& group, Mesh& out) {
  const std::size_t nv = out.rest.size(), nt = out.target_position.size();
  if (!d.is_object()) throw InvalidInput("glTF: " + dw + " is not an object");
  const std::string given = d.contains("kernel") && d["kernel"].is_string() ? d["kernel"].get<std::string>() : "";
  std::string kname = given;
  for (char& ch : kname) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  const auto kernel = parse_kernel(kname);
  if (!kernel || kname.size() != 2)
    throw InvalidInput("glTF: " + dw + ".kernel '" + given + "' is not C0, C2, C4 or C6");
  const double radius = d.contains("radius") && d["radius"].is_number() ? d["radius"].get<double>() : 0.0;
  // Clients evaluate in single precision: R, 1/R and R^2 must be normal floats.
  if (!(radius >= 1e-18 && radius <= 1e18))
    throw InvalidInput("glTF: " + dw + ".radius " + (d.contains("radius") ? d["radius"].dump() : "(none)") +
                       " is not a number in [1e-18, 1e18]");
  const json& terms = array_of(d, "terms");
  if (terms.empty()) throw InvalidInput("glTF: " + dw + " has no terms");
  const std::vector<Vec3> sources = vec3s(acc.read(index_of(d, "sources", dw), 3, "sources"));
  Deformation def;
  def.stage = index_of(d, "stage", dw, 0);
  if (def.stage > 65535) throw InvalidInput("glTF: " + dw + ".stage " + std::to_string(def.stage) + " is past 65535");
  if (d.contains("groups")) {
    const json& g = d["groups"];
    if (!g.is_array() || g.empty()) throw InvalidInput("glTF: " + dw + ".groups is not a non-empty array");
    if (group.empty()) throw InvalidInput("glTF: " + dw + " has groups but the mesh has no _CSRBF_GROUP");
    std::vector<char> in(65536, 0);
    for (const json& x : g) {
      if (!x.is_number_unsigned() || x.get<std::size_t>() > 65535)
        throw InvalidInput("glTF: " + dw + ".groups holds " + x.dump().substr(0, 40) + ", not a group number");
      in[x.get<std::size_t>()] = 1;
    }
    for (std::size_t v = 0; v < nv; ++v)
      if (in[std::size_t(group[v])]) def.vertices.push_back(std::uint32_t(v));
  } else {
    for (std::size_t v = 0; v < nv; ++v) def.vertices.push_back(std::uint32_t(v));
  }
  for (std::size_t ti = 0; ti < terms.size(); ++ti) {
    def.terms.push_back(
        read_term(acc, terms[ti], dw + ".terms[" + std::to_string(ti) + "]", nt, sources, radius, *kernel));
    out.replaced[def.terms.back().weight] = 1;
  }
  return def;
}

/// The mesh's CSRBF_deformation, where it has one (load's third phase): its deformations in the
/// order of their stages.
void load_extension(const Accessors& acc, const json& m, const std::string& where, Mesh& out) {
  if (!m.contains("extensions") || !m["extensions"].is_object() || !m["extensions"].contains("CSRBF_deformation"))
    return;
  const json& ext = m["extensions"]["CSRBF_deformation"];
  const json& attrs = array_of(m, "primitives")[0]["attributes"];
  const std::string aw = where + ".primitives[0].attributes";
  const std::string ew = where + ".extensions.CSRBF_deformation";
  std::vector<double> group;
  if (attrs.contains("_CSRBF_GROUP")) {
    const std::size_t ga = index_of(attrs, "_CSRBF_GROUP", aw);
    group = acc.read(ga, 1, "_CSRBF_GROUP", out.rest.size());
    if (const std::size_t ct = acc.component_type(ga);
        ct != code(ComponentType::UnsignedByte) && ct != code(ComponentType::UnsignedShort))
      throw InvalidInput("glTF: " + aw + "._CSRBF_GROUP's componentType " + std::to_string(ct) +
                         " is not UNSIGNED_BYTE or UNSIGNED_SHORT");
  }
  const json& defs = array_of(ext, "deformations");
  if (defs.empty()) throw InvalidInput("glTF: " + ew + " has no deformations");
  for (std::size_t di = 0; di < defs.size(); ++di)
    out.deformations.push_back(
        read_deformation(acc, defs[di], ew + ".deformations[" + std::to_string(di) + "]", group, out));
  std::stable_sort(out.deformations.begin(), out.deformations.end(),
                   [](const Deformation& a, const Deformation& b) { return a.stage < b.stage; });
}

/// The weights channels of the nodes that hold each mesh (load's last phase): the first channel
/// that animates a mesh is its.
void load_channels(const Accessors& acc, const json& doc, std::vector<Mesh>& result) {
  const json& nodes = array_of(doc, "nodes");
  const json& animations = array_of(doc, "animations");
  for (std::size_t ai = 0; ai < animations.size(); ++ai) {
    const json& anim = animations[ai];
    const std::string aw = field("animations", ai);
    if (!anim.is_object()) throw InvalidInput("glTF: " + aw + " is not an object");
    const json& channels = array_of(anim, "channels");
    const json& samplers = array_of(anim, "samplers");
    for (std::size_t ci = 0; ci < channels.size(); ++ci) {
      const json& ch = channels[ci];
      const std::string cw = aw + ".channels[" + std::to_string(ci) + "]";
      if (!ch.is_object() || !ch.contains("target") || !ch["target"].is_object())
        throw InvalidInput("glTF: " + cw + " has no target object");
      const json& target = ch["target"];
      if (!target.contains("path") || target["path"] != "weights" || !target.contains("node")) continue;
      const std::size_t node = index_of(target, "node", cw + ".target");
      if (node >= nodes.size() || !nodes[node].is_object() || !nodes[node].contains("mesh")) continue;
      const std::size_t mi = index_of(nodes[node], "mesh", field("nodes", node));
      if (mi >= result.size() || !result[mi].times.empty()) continue;
      const std::size_t si = index_of(ch, "sampler", cw);
      if (si >= samplers.size() || !samplers[si].is_object())
        throw InvalidInput("glTF: " + cw + ".sampler " + std::to_string(si) + " is not one of the " +
                           std::to_string(samplers.size()) + " samplers");
      const json& sampler = samplers[si];
      const std::string sw = aw + ".samplers[" + std::to_string(si) + "]";
      Mesh& m = result[mi];
      m.interpolation = sampler.contains("interpolation") && sampler["interpolation"].is_string()
                            ? sampler["interpolation"].get<std::string>()
                            : "LINEAR";
      if (m.interpolation != "LINEAR" && m.interpolation != "STEP" && m.interpolation != "CUBICSPLINE")
        throw InvalidInput("glTF: " + sw + ".interpolation '" + m.interpolation +
                           "' is not LINEAR, STEP or CUBICSPLINE");
      m.times = acc.read(index_of(sampler, "input", sw), 1, "an animation's times");
      const std::size_t per = (m.interpolation == "CUBICSPLINE" ? 3 : 1) * m.default_weights.size();
      if (per == 0)
        throw InvalidInput("glTF: " + sw + " animates the weights of mesh '" + m.name + "', which has no targets");
      m.values = acc.read(index_of(sampler, "output", sw), 1, "an animation's weights", m.times.size() * per);
      if (!(m.times[0] >= 0))
        throw InvalidInput("glTF: " + sw + ": its first time is " + std::to_string(m.times[0]) +
                           "; an animation's times are >= 0");
      for (std::size_t k = 1; k < m.times.size(); ++k)
        if (!(m.times[k] > m.times[k - 1]))
          throw InvalidInput("glTF: " + sw + ": its times do not increase at key " + std::to_string(k));
    }
  }
}

/// The meshes of a glb's JSON and binary chunk (GltfRuntime's constructor), phase by phase.
void load(const json& doc, std::span<const unsigned char> bin, std::vector<Mesh>& result) {
  const Accessors acc(doc, bin);
  const json& meshes = array_of(doc, "meshes");
  for (std::size_t mi = 0; mi < meshes.size(); ++mi) {
    const json& m = meshes[mi];
    const std::string where = field("meshes", mi);
    if (!m.is_object()) throw InvalidInput("glTF: " + where + " is not an object");
    Mesh out;
    out.name = m.contains("name") && m["name"].is_string() ? m["name"].get<std::string>() : "";
    load_geometry(acc, m, where, out);
    load_targets(acc, m, where, out);
    load_extension(acc, m, where, out);
    result.push_back(std::move(out));
  }
  load_channels(acc, doc, result);
}

}  // namespace

struct GltfRuntime::Data {
  std::vector<Mesh> meshes;
};

namespace {

/// The meshes of a glb (GltfRuntime's constructor). One whose views EXT_meshopt_compression
/// compresses is decoded first (gltf_without_meshopt) and read again; others are read in place.
void load_glb(const std::vector<unsigned char>& glb, std::vector<Mesh>& meshes) {
  const GlbChunks chunks = split_glb(glb);
  const json doc = json::parse(chunks.json.begin(), chunks.json.end(), nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) throw InvalidInput("glTF: the glb's JSON chunk does not parse");
  if (doc.contains("extensionsUsed") && doc["extensionsUsed"].is_array()) {
    const json& used = doc["extensionsUsed"];
    if (std::find(used.begin(), used.end(), "EXT_meshopt_compression") != used.end())
      return load_glb(gltf_without_meshopt(glb), meshes);  // the decoded file lists it no more
  }
  const std::span<const unsigned char> bin = chunks.bin;
  try {
    load(doc, bin, meshes);
  } catch (const json::exception& e) {
    // A value of the wrong JSON type where the reads above did not check it first.
    throw InvalidInput(std::string("glTF: a value of the wrong type: ") + e.what());
  }
}

}  // namespace

GltfRuntime::GltfRuntime(const std::vector<unsigned char>& glb) : d_(std::make_unique<Data>()) {
  load_glb(glb, d_->meshes);
}

GltfRuntime::~GltfRuntime() = default;
GltfRuntime::GltfRuntime(GltfRuntime&&) noexcept = default;
GltfRuntime& GltfRuntime::operator=(GltfRuntime&&) noexcept = default;

std::size_t GltfRuntime::meshes() const noexcept { return d_->meshes.size(); }
std::size_t GltfRuntime::mesh_named(const std::string& name) const {
  for (std::size_t i = 0; i < d_->meshes.size(); ++i)
    if (d_->meshes[i].name == name) return i;
  throw InvalidInput("glTF: no mesh named '" + name + "'");
}
bool GltfRuntime::compact(std::size_t mesh) const { return !d_->meshes.at(mesh).deformations.empty(); }
std::span<const Vec3> GltfRuntime::rest(std::size_t mesh) const { return d_->meshes.at(mesh).rest; }
std::span<const std::uint32_t> GltfRuntime::triangles(std::size_t mesh) const { return d_->meshes.at(mesh).triangles; }
const std::string& GltfRuntime::name(std::size_t mesh) const { return d_->meshes.at(mesh).name; }
double GltfRuntime::duration(std::size_t mesh) const {
  const Mesh& m = d_->meshes.at(mesh);
  return m.times.empty() ? 0.0 : m.times.back();
}

std::vector<double> GltfRuntime::weights(std::size_t mesh, double t) const {
  const Mesh& m = d_->meshes.at(mesh);
  const std::size_t nt = m.default_weights.size();
  if (m.times.empty()) return m.default_weights;
  const bool cubic = m.interpolation == "CUBICSPLINE";
  const auto key = [&](std::size_t k, std::size_t part) {  // part: 0 in-tangent, 1 value, 2 out-tangent
    return &m.values[(cubic ? 3 * k + part : k) * nt];
  };
  const std::size_t last = m.times.size() - 1;
  std::vector<double> w(nt);
  if (t <= m.times.front() || t >= m.times.back()) {
    const double* v = key(t <= m.times.front() ? 0 : last, 1);
    w.assign(v, v + nt);
    return w;
  }
  const std::size_t k = std::size_t(std::upper_bound(m.times.begin(), m.times.end(), t) - m.times.begin()) - 1;
  const double dt = m.times[k + 1] - m.times[k], s = (t - m.times[k]) / dt;
  for (std::size_t j = 0; j < nt; ++j) {
    if (m.interpolation == "STEP") {
      w[j] = key(k, 1)[j];
    } else if (cubic) {
      const double s2 = s * s, s3 = s2 * s;
      w[j] = (2 * s3 - 3 * s2 + 1) * key(k, 1)[j] + (s3 - 2 * s2 + s) * dt * key(k, 2)[j] +
             (-2 * s3 + 3 * s2) * key(k + 1, 1)[j] + (s3 - s2) * dt * key(k + 1, 0)[j];
    } else {
      w[j] = (1 - s) * key(k, 1)[j] + s * key(k + 1, 1)[j];
    }
  }
  return w;
}

void GltfRuntime::deform(std::size_t mesh, std::span<const float> weights, std::span<float> positions,
                         std::span<float> normals, bool use_extension) const {
  const Mesh& m = d_->meshes.at(mesh);
  const std::size_t want = 3 * m.rest.size();
  for (const auto& [what, size] : {std::pair{"positions", positions.size()}, std::pair{"normals", normals.size()}})
    if (size != want)
      throw InvalidInput("GltfRuntime::deform: " + std::to_string(size) + " floats of " + what + " for mesh '" +
                         m.name + "', which needs " + std::to_string(want) + " (xyz for each of its " +
                         std::to_string(m.rest.size()) + " vertices)");
  const std::vector<double> w(weights.begin(), weights.end());
  std::vector<Vec3> p, n;
  deform(mesh, w, p, n, use_extension);
  for (std::size_t v = 0; v < p.size(); ++v)
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(float(p[v][c])))
        throw InvalidInput("GltfRuntime::deform: mesh '" + m.name + "' vertex " + std::to_string(v) +
                           " moves beyond float (" + std::to_string(p[v][c]) + ")");
  for (std::size_t v = 0; v < p.size(); ++v)
    for (int c = 0; c < 3; ++c) {
      positions[3 * v + std::size_t(c)] = float(p[v][c]);
      normals[3 * v + std::size_t(c)] = float(n[v][c]);
    }
}

void GltfRuntime::deform(std::size_t mesh, std::span<const double> weights, std::vector<Vec3>& positions,
                         std::vector<Vec3>& normals, bool use_extension) const {
  const Mesh& m = d_->meshes.at(mesh);
  const std::size_t nv = m.rest.size(), nt = m.default_weights.size();
  if (weights.size() != nt)
    throw InvalidInput("GltfRuntime::deform: " + std::to_string(weights.size()) + " weights for mesh '" + m.name +
                       "', which has " + std::to_string(nt));
  // The morph targets that no term replaces, added to the rest shape as glTF adds them.
  positions = m.rest;
  normals = m.normal;
  for (std::size_t j = 0; j < nt; ++j) {
    if (weights[j] == 0 || (use_extension && m.replaced[j])) continue;
    for (std::size_t v = 0; v < m.target_position[j].size(); ++v) positions[v] += weights[j] * m.target_position[j][v];
    for (std::size_t v = 0; v < m.target_normal[j].size(); ++v) normals[v] += weights[j] * m.target_normal[j][v];
  }
  if (use_extension && !m.deformations.empty()) {
    // Stage by stage: every term of a stage at the stage's input points, J accumulated.
    std::vector<Eigen::Matrix3d> jac(nv, Eigen::Matrix3d::Identity());
    std::vector<char> moved(nv, 0);
    for (std::size_t d0 = 0; d0 < m.deformations.size();) {
      std::size_t d1 = d0;
      while (d1 < m.deformations.size() && m.deformations[d1].stage == m.deformations[d0].stage) ++d1;
      std::vector<Vec3> next = positions;
      std::vector<Eigen::Matrix3d> stage(nv, Eigen::Matrix3d::Identity());
      for (std::size_t di = d0; di < d1; ++di) {
        const Deformation& def = m.deformations[di];
        const std::size_t n = def.vertices.size();
        std::vector<double> x(3 * n), y(3 * n), j(9 * n);
        for (std::size_t i = 0; i < n; ++i)
          for (int c = 0; c < 3; ++c) x[3 * i + std::size_t(c)] = positions[def.vertices[i]][c];
        for (const Term& t : def.terms) {
          if (weights[t.weight] == 0) continue;
          t.map.apply_with_normals(x.data(), y.data(), n, weights[t.weight], nullptr, nullptr, j.data());
          for (std::size_t i = 0; i < n; ++i) {
            const std::size_t v = def.vertices[i];
            next[v] += Vec3(y[3 * i], y[3 * i + 1], y[3 * i + 2]) - Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
            stage[v] += Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(j.data() + 9 * i) -
                        Eigen::Matrix3d::Identity();
            moved[v] = 1;
          }
        }
      }
      for (std::size_t v = 0; v < nv; ++v)
        if (moved[v]) jac[v] = stage[v] * jac[v];
      positions = std::move(next);
      d0 = d1;
    }
    // J^-T n as cof(J) n with det's sign, finite where J is singular (a polynomial that flattens).
    for (std::size_t v = 0; v < nv; ++v) {
      if (!moved[v]) continue;
      const Vec3 a = jac[v].col(0), b = jac[v].col(1), c = jac[v].col(2), n = normals[v];
      const Vec3 m = n.x() * b.cross(c) + n.y() * c.cross(a) + n.z() * a.cross(b);
      if (m.squaredNorm() > 0) normals[v] = a.dot(b.cross(c)) < 0 ? Vec3(-m) : m;
    }
  }
  for (std::size_t v = 0; v < nv; ++v) {
    Vec3& n = normals[v];
    if (n.norm() > 0) n.normalize();
    if (!positions[v].allFinite() || !n.allFinite())
      throw InvalidInput("glTF: mesh '" + m.name + "': vertex " + std::to_string(v) +
                         " is not finite at these weights (coefficients or polynomial beyond what float sums hold)");
  }
}

}  // namespace csrbf::gltf
