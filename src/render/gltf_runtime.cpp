// GltfRuntime: a glb's meshes as a client of CSRBF_deformation plays them (gltf_runtime.hpp).
#include "csrbf/render/gltf_runtime.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/space_map.hpp"

#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

namespace csrbf::render {
namespace {

using nlohmann::json;

std::string field(const char* what, std::size_t i) { return std::string(what) + "[" + std::to_string(i) + "]"; }

/// An accessor's values as doubles (count x components), through its buffer view (byteOffset,
/// byteStride) or zero where it has none, with its sparse entries applied. Every range is checked
/// against the buffer.
class Accessors {
 public:
  Accessors(const json& doc, std::span<const unsigned char> bin) : doc_(doc), bin_(bin) {}

  std::vector<double> read(std::size_t index, int components, const char* role) const {
    const json& accessors = doc_.value("accessors", json::array());
    if (index >= accessors.size())
      throw InvalidInput("glTF: " + std::string(role) + " names accessor " + std::to_string(index) + " of " +
                         std::to_string(accessors.size()));
    const json& a = accessors[index];
    const std::string where = field("accessors", index);
    const std::string type = a.value("type", "");
    const int width = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3 : type == "VEC4" ? 4 : 0;
    if (width != components)
      throw InvalidInput("glTF: " + where + " (" + role + ") has type '" + type + "', expected " +
                         (components == 1 ? "SCALAR" : "VEC" + std::to_string(components)));
    const std::size_t count = a.value("count", std::size_t(0));
    if (count == 0 || count > (std::size_t(1) << 31))
      throw InvalidInput("glTF: " + where + ".count is " + std::to_string(count));
    const int ct = a.value("componentType", 0);
    std::vector<double> out(count * std::size_t(width), 0.0);
    if (a.contains("bufferView")) {
      const auto [p, stride, avail] = view(a["bufferView"].get<std::size_t>(), a.value("byteOffset", std::size_t(0)));
      const std::size_t size = component_size(ct, where);
      const std::size_t element = size * std::size_t(width), step = stride ? stride : element;
      if (count > 0 && (count - 1) * step + element > avail)
        throw InvalidInput("glTF: " + where + " runs past its buffer view (" + std::to_string(count) + " elements of " +
                           std::to_string(element) + " bytes, stride " + std::to_string(step) + ")");
      for (std::size_t i = 0; i < count; ++i)
        for (int c = 0; c < width; ++c) out[i * std::size_t(width) + std::size_t(c)] = value(p + i * step + std::size_t(c) * size, ct);
    }
    if (a.contains("sparse")) {
      const json& sp = a["sparse"];
      const std::size_t n = sp.value("count", std::size_t(0));
      if (n == 0 || n > count) throw InvalidInput("glTF: " + where + ".sparse.count is " + std::to_string(n));
      const json& ix = sp["indices"];
      const json& vs = sp["values"];
      const int ict = ix.value("componentType", 0);
      const auto [ip, istride, iavail] = view(ix["bufferView"].get<std::size_t>(), ix.value("byteOffset", std::size_t(0)));
      const auto [vp, vstride, vavail] = view(vs["bufferView"].get<std::size_t>(), vs.value("byteOffset", std::size_t(0)));
      const std::size_t isize = component_size(ict, where + ".sparse.indices"), vsize = component_size(ct, where);
      if (n * isize > iavail || n * vsize * std::size_t(width) > vavail)
        throw InvalidInput("glTF: " + where + ".sparse runs past its buffer views");
      for (std::size_t k = 0; k < n; ++k) {
        const auto i = std::size_t(value(ip + k * isize, ict));
        if (i >= count)
          throw InvalidInput("glTF: " + where + ".sparse index " + std::to_string(i) + " is not below count " +
                             std::to_string(count));
        for (int c = 0; c < width; ++c)
          out[i * std::size_t(width) + std::size_t(c)] = value(vp + (k * std::size_t(width) + std::size_t(c)) * vsize, ct);
      }
    }
    for (const double x : out)
      if (!std::isfinite(x)) throw InvalidInput("glTF: " + where + " (" + role + ") holds a value that is not finite");
    return out;
  }

 private:
  struct View {
    const unsigned char* p;
    std::size_t stride, available;
  };
  View view(std::size_t index, std::size_t offset) const {
    const json& views = doc_.value("bufferViews", json::array());
    if (index >= views.size()) throw InvalidInput("glTF: no bufferViews[" + std::to_string(index) + "]");
    const json& v = views[index];
    if (v.value("buffer", 0) != 0) throw InvalidInput("glTF: " + field("bufferViews", index) + " is not in the glb's buffer");
    const std::size_t start = v.value("byteOffset", std::size_t(0)), length = v.value("byteLength", std::size_t(0));
    if (start > bin_.size() || length > bin_.size() - start || offset > length)
      throw InvalidInput("glTF: " + field("bufferViews", index) + " (offset " + std::to_string(start) + ", length " +
                         std::to_string(length) + ") lies outside the " + std::to_string(bin_.size()) +
                         "-byte binary chunk");
    return {bin_.data() + start + offset, v.value("byteStride", std::size_t(0)), length - offset};
  }
  static std::size_t component_size(int ct, const std::string& where) {
    switch (ct) {
      case 5121:
        return 1;
      case 5123:
        return 2;
      case 5125:
      case 5126:
        return 4;
      default:
        throw InvalidInput("glTF: " + where + ".componentType " + std::to_string(ct) + " is not read here");
    }
  }
  static double value(const unsigned char* p, int ct) {
    if (ct == 5126) {
      float f;
      std::memcpy(&f, p, 4);
      return double(f);
    }
    if (ct == 5125) {
      std::uint32_t u;
      std::memcpy(&u, p, 4);
      return double(u);
    }
    if (ct == 5123) {
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
  std::vector<std::vector<Vec3>> target_position, target_normal;
  std::vector<double> default_weights;
  std::vector<Deformation> deformations;
  std::vector<char> replaced;  // per target: named by a term
  // The weights channel: key times, values (a row of targets a key), interpolation.
  std::vector<double> times, values;
  std::string interpolation;
};

}  // namespace

struct GltfRuntime::Data {
  std::vector<Mesh> meshes;
};

GltfRuntime::GltfRuntime(const std::vector<unsigned char>& glb) : d_(std::make_unique<Data>()) {
  const auto u32 = [&](std::size_t at) {
    if (at + 4 > glb.size()) throw InvalidInput("glTF: the glb ends at byte " + std::to_string(glb.size()) + " inside its header");
    std::uint32_t v;
    std::memcpy(&v, glb.data() + at, 4);
    return std::size_t(v);
  };
  if (u32(0) != 0x46546C67u) throw InvalidInput("glTF: not a glb (its first four bytes are not 'glTF')");
  if (u32(4) != 2) throw InvalidInput("glTF: glb version " + std::to_string(u32(4)) + ", expected 2");
  if (u32(8) != glb.size())
    throw InvalidInput("glTF: the glb's header says " + std::to_string(u32(8)) + " bytes, the file has " +
                       std::to_string(glb.size()));
  const std::size_t jl = u32(12);
  if (u32(16) != 0x4E4F534Au || jl > glb.size() - 20) throw InvalidInput("glTF: the glb's first chunk is not its JSON");
  const json doc = json::parse(glb.begin() + 20, glb.begin() + 20 + std::ptrdiff_t(jl), nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) throw InvalidInput("glTF: the glb's JSON chunk does not parse");
  std::span<const unsigned char> bin;
  const std::size_t b0 = 20 + jl;
  if (b0 + 8 <= glb.size()) {
    const std::size_t bl = u32(b0);
    if (u32(b0 + 4) != 0x004E4942u || bl > glb.size() - b0 - 8)
      throw InvalidInput("glTF: the glb's second chunk is not a binary chunk within the file");
    bin = std::span<const unsigned char>(glb.data() + b0 + 8, bl);
  }
  const Accessors acc(doc, bin);
  const json& meshes = doc.value("meshes", json::array());
  for (std::size_t mi = 0; mi < meshes.size(); ++mi) {
    const json& m = meshes[mi];
    Mesh out;
    out.name = m.value("name", "");
    const std::string where = field("meshes", mi);
    if (!m.contains("primitives") || m["primitives"].empty()) throw InvalidInput("glTF: " + where + " has no primitives");
    // Every primitive of a csrbf mesh shares its attributes and targets: the first stands for all.
    const json& prim = m["primitives"][0];
    const json& attrs = prim.value("attributes", json::object());
    if (!attrs.contains("POSITION")) throw InvalidInput("glTF: " + where + ".primitives[0] has no POSITION");
    out.rest = vec3s(acc.read(attrs["POSITION"].get<std::size_t>(), 3, "POSITION"));
    const std::size_t nv = out.rest.size();
    out.normal = attrs.contains("NORMAL") ? vec3s(acc.read(attrs["NORMAL"].get<std::size_t>(), 3, "NORMAL"))
                                          : std::vector<Vec3>(nv, Vec3::Zero());
    for (const json& t : prim.value("targets", json::array())) {
      out.target_position.push_back(t.contains("POSITION")
                                        ? vec3s(acc.read(t["POSITION"].get<std::size_t>(), 3, "a target's POSITION"))
                                        : std::vector<Vec3>(nv, Vec3::Zero()));
      out.target_normal.push_back(t.contains("NORMAL")
                                      ? vec3s(acc.read(t["NORMAL"].get<std::size_t>(), 3, "a target's NORMAL"))
                                      : std::vector<Vec3>(nv, Vec3::Zero()));
      if (out.target_position.back().size() != nv || out.target_normal.back().size() != nv)
        throw InvalidInput("glTF: " + where + ": a morph target's count is not the vertices' " + std::to_string(nv));
    }
    const std::size_t nt = out.target_position.size();
    out.default_weights = m.value("weights", std::vector<double>(nt, 0.0));
    if (out.default_weights.size() != nt)
      throw InvalidInput("glTF: " + where + ".weights holds " + std::to_string(out.default_weights.size()) +
                         " values for " + std::to_string(nt) + " morph targets");
    out.replaced.assign(nt, 0);
    if (m.contains("extensions") && m["extensions"].contains("CSRBF_deformation")) {
      std::vector<double> group;
      if (attrs.contains("_CSRBF_GROUP")) {
        group = acc.read(attrs["_CSRBF_GROUP"].get<std::size_t>(), 1, "_CSRBF_GROUP");
        if (group.size() != nv) throw InvalidInput("glTF: " + where + ": _CSRBF_GROUP's count is not the vertices'");
      }
      const json& defs = m["extensions"]["CSRBF_deformation"].value("deformations", json::array());
      if (defs.empty()) throw InvalidInput("glTF: " + where + ".extensions.CSRBF_deformation has no deformations");
      for (std::size_t di = 0; di < defs.size(); ++di) {
        const json& d = defs[di];
        const std::string dw = where + ".extensions.CSRBF_deformation.deformations[" + std::to_string(di) + "]";
        std::string kname = d.value("kernel", "");
        for (char& ch : kname) ch = char(std::tolower(static_cast<unsigned char>(ch)));
        const auto kernel = parse_kernel(kname);
        if (!kernel || kname.size() != 2) throw InvalidInput("glTF: " + dw + ".kernel '" + d.value("kernel", "") + "' is not C0, C2, C4 or C6");
        const double radius = d.value("radius", 0.0);
        if (!(radius > 0) || !std::isfinite(radius)) throw InvalidInput("glTF: " + dw + ".radius " + std::to_string(radius) + " is not > 0");
        if (!d.contains("sources") || !d.contains("terms") || d["terms"].empty())
          throw InvalidInput("glTF: " + dw + " needs sources and terms");
        const std::vector<Vec3> sources = vec3s(acc.read(d["sources"].get<std::size_t>(), 3, "sources"));
        Deformation def;
        def.stage = d.value("stage", std::size_t(0));
        if (d.contains("groups")) {
          const auto groups = d["groups"].get<std::vector<double>>();
          if (group.empty()) throw InvalidInput("glTF: " + dw + " has groups but the mesh has no _CSRBF_GROUP");
          for (std::size_t v = 0; v < nv; ++v)
            if (std::find(groups.begin(), groups.end(), group[v]) != groups.end()) def.vertices.push_back(std::uint32_t(v));
        } else {
          for (std::size_t v = 0; v < nv; ++v) def.vertices.push_back(std::uint32_t(v));
        }
        for (const json& t : d["terms"]) {
          const std::size_t w = t.value("weight", std::size_t(-1));
          if (w >= nt)
            throw InvalidInput("glTF: " + dw + ": a term's weight " + std::to_string(w) + " is not below the mesh's " +
                               std::to_string(nt) + " weights");
          const std::vector<double> c = acc.read(t.at("coefficients").get<std::size_t>(), 3, "coefficients");
          if (c.size() != 3 * sources.size())
            throw InvalidInput("glTF: " + dw + ": a term has " + std::to_string(c.size() / 3) + " coefficients for " +
                               std::to_string(sources.size()) + " sources");
          Eigen::Matrix<double, Eigen::Dynamic, 3> alpha(Eigen::Index(sources.size()), 3);
          for (std::size_t i = 0; i < sources.size(); ++i)
            for (int k = 0; k < 3; ++k) alpha(Eigen::Index(i), k) = c[3 * i + std::size_t(k)];
          Eigen::Matrix<double, 4, 3> beta = Eigen::Matrix<double, 4, 3>::Zero();
          FitOptions fo;
          fo.radius = radius;
          fo.kernel = *kernel;
          fo.polynomial = Polynomial::None;
          if (t.contains("polynomial")) {
            const auto p = t["polynomial"].get<std::vector<double>>();
            if (p.size() != 12) throw InvalidInput("glTF: " + dw + ": a term's polynomial has " + std::to_string(p.size()) + " numbers, not 12");
            for (int r = 0; r < 4; ++r)
              for (int k = 0; k < 3; ++k) beta(r, k) = p[std::size_t(3 * r + k)];
            fo.polynomial = Polynomial::Linear;
          }
          def.terms.push_back({w, SpaceMap::from_solution(sources, alpha, beta, Vec3::Zero(), 1.0, fo)});
          out.replaced[w] = 1;
        }
        out.deformations.push_back(std::move(def));
      }
      std::stable_sort(out.deformations.begin(), out.deformations.end(),
                       [](const Deformation& a, const Deformation& b) { return a.stage < b.stage; });
    }
    d_->meshes.push_back(std::move(out));
  }
  // The weights channels of the nodes that hold each mesh.
  const json& nodes = doc.value("nodes", json::array());
  for (const json& anim : doc.value("animations", json::array()))
    for (const json& ch : anim.value("channels", json::array())) {
      const json& target = ch.value("target", json::object());
      if (target.value("path", "") != "weights" || !target.contains("node")) continue;
      const std::size_t node = target["node"].get<std::size_t>();
      if (node >= nodes.size() || !nodes[node].contains("mesh")) continue;
      const std::size_t mi = nodes[node]["mesh"].get<std::size_t>();
      if (mi >= d_->meshes.size() || !d_->meshes[mi].times.empty()) continue;
      const json& sampler = anim["samplers"].at(ch.at("sampler").get<std::size_t>());
      Mesh& m = d_->meshes[mi];
      m.times = acc.read(sampler.at("input").get<std::size_t>(), 1, "an animation's times");
      m.values = acc.read(sampler.at("output").get<std::size_t>(), 1, "an animation's weights");
      m.interpolation = sampler.value("interpolation", "LINEAR");
      const std::size_t per = (m.interpolation == "CUBICSPLINE" ? 3 : 1) * m.default_weights.size();
      if (per == 0 || m.values.size() != m.times.size() * per)
        throw InvalidInput("glTF: the weights channel of mesh '" + m.name + "' has " + std::to_string(m.values.size()) +
                           " values for " + std::to_string(m.times.size()) + " times and " +
                           std::to_string(m.default_weights.size()) + " targets");
    }
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
    for (std::size_t v = 0; v < nv; ++v) {
      positions[v] += weights[j] * m.target_position[j][v];
      normals[v] += weights[j] * m.target_normal[j][v];
    }
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
    for (std::size_t v = 0; v < nv; ++v)
      if (moved[v]) normals[v] = jac[v].inverse().transpose() * normals[v];
  }
  for (Vec3& n : normals)
    if (n.norm() > 0) n.normalize();
}

}  // namespace csrbf::render
