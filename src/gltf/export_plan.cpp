// The glTF exporter's plan (see export_detail.hpp): the sample times, which parts are exact
// and which baked, the exact targets, the memory bounds checked before anything large is built,
// and the player's pass over the frames; and the small helpers the phases share.
#include "export_detail.hpp"

#include "csrbf/io/memory.hpp"
#include "csrbf/io/scene.hpp"
#include "csrbf/units.hpp"

#include <fstream>
#include <iterator>
#include <sstream>
#include <string_view>

namespace csrbf::gltf::export_detail {

namespace fs = std::filesystem;

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

std::vector<double> unique_times(std::vector<double> t, double end) {
  t = sorted_within(std::move(t), end);
  std::vector<double> out;
  for (const double x : t) {
    const double f = double(float(x));
    if (out.empty() || f > out.back()) out.push_back(f);
  }
  return out;
}

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
SpaceMap float_form(const SpaceMap& map, double scale) {
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

// The sample times: the frames k / fps, and the duration where it falls between two (so that
// what is sampled or baked is measured to the end). Times as glTF keeps them, in float32.
void plan_sample_times(ExportPlan& plan) {
  const anim::Scene& scene = plan.scene;
  const GltfOptions& options = plan.options;
  if (options.quantize && options.compact != Compact::Off)
    throw InvalidInput(
        "gltf_binary: quantize with compact: CSRBF_deformation's sources and radius are in float coordinates");
  const double fps = options.fps > 0 ? options.fps : scene.fps;
  if (!(fps > 0) || !std::isfinite(fps)) throw InvalidInput("export: the frame rate must be > 0");
  const double duration = scene.duration;
  constexpr double kMaxFrames = 1e5;
  const double grid = std::floor(duration * fps + 1e-9) + 1;
  if (!(grid <= kMaxFrames)) {
    std::ostringstream m;
    m << "export: the scene's duration " << duration << " s at " << fps << " fps is " << grid
      << " frames; at most 100000 are sampled (lower --fps)";
    throw InvalidInput(m.str());
  }
  std::vector<double>& frame_t = plan.frame_t;
  frame_t.clear();
  for (std::size_t k = 0; k < std::size_t(grid); ++k) frame_t.push_back(double(float(double(k) / fps)));
  if (double(float(duration)) > frame_t.back() && duration - frame_t.back() > 1e-9)
    frame_t.push_back(double(float(duration)));
  plan.fps = fps;
  plan.duration = duration;
  plan.frames = frame_t.size();
  plan.report = GltfReport{};
  plan.report.fps = fps;
  plan.report.frames = plan.frames;
}

// Which parts are exact and which are baked.
void plan_parts(ExportPlan& plan) {
  const anim::Scene& scene = plan.scene;
  const GltfOptions& options = plan.options;
  plan.plans.assign(scene.objects.size(), ObjectPlan{});
  plan.plan_left = io::memory_left(options.memory_limit_bytes);
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const anim::Object& obj = scene.objects[o];
    ObjectPlan& op = plan.plans[o];
    op.owner.assign(obj.rest.size(), -1);
    op.baked.assign(obj.parts.size(), 0);
    op.why.assign(obj.parts.size(), {});
    for (std::size_t p = 0; p < obj.parts.size(); ++p) {
      const anim::Part& part = obj.parts[p];
      if (part.deformations.empty()) continue;
      for (const auto v : part.vertices) op.owner[v] = int(p);
      bool contact = false;
      for (const auto& d : part.deformations) contact |= d.contact.has_value();
      if (contact)
        op.why[p] = "a contact deformation is refitted every frame";
      else if (part.combine == anim::Combine::Compose && part.deformations.size() > 1)
        op.why[p] = "composed deformations (T2 o T1) are not linear in their phases";
      else if (options.bake == Bake::Always)
        op.why[p] = "--bake always";
      if (!op.why[p].empty()) {
        if (options.bake == Bake::Never)
          throw InvalidInput("export: objects[" + std::to_string(o) + "] '" + obj.name + "' part '" + part.name +
                             "' needs baking (" + op.why[p] + "), and --bake never forbids it");
        op.baked[p] = 1;
      }
    }
  }
}

// The exact targets' displacements, bounded before they are computed (16384 deformations on a
// mesh of 6158 vertices would be 2.4 GB): at most 2 GiB, and what the program leaves of the limit.
// As planned so far, each deformation of a part not baked is an exact target.
void check_target_memory(const ExportPlan& plan) {
  const anim::Scene& scene = plan.scene;
  const GltfOptions& options = plan.options;
  const double plan_left = plan.plan_left;
  std::vector<std::size_t> candidates(scene.objects.size(), 0);
  std::vector<char> baked(scene.objects.size(), 0);
  for (std::size_t o = 0; o < scene.objects.size(); ++o)
    for (std::size_t p = 0; p < scene.objects[o].parts.size(); ++p) {
      if (plan.plans[o].baked[p])
        baked[o] = 1;
      else
        candidates[o] += scene.objects[o].parts[p].deformations.size();
    }
  const ExportMemory planned = export_memory(scene, candidates, baked, plan.frames, 0.0);
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
}

namespace {

/// Object o's exact targets: each deformation of a part not baked, its displacements computed.
void exact_targets(const anim::Object& obj, std::size_t o, ObjectPlan& plan) {
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
}

/// The most morph targets active at once in the object, at the sample times and its phase keys.
std::size_t most_active(const ExportPlan& export_plan, const anim::Object& obj, const ObjectPlan& plan) {
  std::size_t most = 0;
  std::vector<double> times = export_plan.frame_t;
  for (const auto& e : plan.exact)
    for (const auto& key : obj.parts[e.part].deformations[e.deformation].schedule.keys()) times.push_back(key.time);
  for (const double t : unique_times(times, export_plan.duration)) {
    std::size_t n = plan.any_baked() ? 2 : 0;
    for (const auto& e : plan.exact)
      n += obj.parts[e.part].deformations[e.deformation].schedule.phase(t) != 0.0 && e.largest > 0;
    most = std::max(most, n);
  }
  return most;
}

}  // namespace

// The exact targets, and the most active at once; over the limit, the object is baked.
void plan_exact_targets(ExportPlan& plan) {
  const GltfOptions& options = plan.options;
  for (std::size_t o = 0; o < plan.scene.objects.size(); ++o) {
    const anim::Object& obj = plan.scene.objects[o];
    ObjectPlan& op = plan.plans[o];
    exact_targets(obj, o, op);
    if (most_active(plan, obj, op) > options.max_active && options.bake == Bake::Auto) {
      for (std::size_t p = 0; p < obj.parts.size(); ++p)
        if (!obj.parts[p].deformations.empty() && !op.baked[p]) {
          op.baked[p] = 1;
          op.why[p] =
              "the object would have more than " + std::to_string(options.max_active) + " morph targets active at once";
        }
      exact_targets(obj, o, op);
    }
  }
}

// Memory, bounded before anything large is built: the weights (a value a target and sample
// time), and baking's frames (the exact targets were bounded above). Then what the export holds
// beyond the scene, predicted and bounded by what the program leaves of --memory-limit (and baking
// by 4 GiB): the player, each object's plan, exact targets and baked frames, the binary buffer (an
// upper bound: every target dense, which is also reserved, so that it grows without copies), the
// weights, and the largest object's work while it is written (float copies, normals of a moved
// mesh, a target's non-zeros).
void check_export_memory(ExportPlan& plan) {
  const anim::Scene& scene = plan.scene;
  const GltfOptions& options = plan.options;
  const std::size_t frames = plan.frames;
  double weight_bytes = 0;
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const double targets = double(plan.plans[o].exact.size()) + (plan.plans[o].any_baked() ? double(frames) : 0.0);
    double times = double(frames) + 1;
    for (const auto& part : scene.objects[o].parts)
      for (const auto& def : part.deformations) times += double(def.schedule.keys().size());
    weight_bytes += times * targets * 12.0;
  }
  if (weight_bytes > 0.5 * kGiB)
    throw InvalidInput("export: the morph weights would take " +
                       std::to_string(std::llround(weight_bytes / double(1 << 20))) +
                       " MiB (at most 512): fewer deformations, a lower --fps, or less baking");
  std::vector<std::size_t> exact(scene.objects.size());
  std::vector<char> baked(scene.objects.size(), 0);
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    exact[o] = plan.plans[o].exact.size();
    baked[o] = plan.plans[o].any_baked();  // auto-baking may have baked more
  }
  const ExportMemory need = export_memory(scene, exact, baked, frames, weight_bytes);
  if (need.baked > 4.0 * kGiB)
    throw InvalidInput("export: baking " + std::to_string(frames) + " frames would take " +
                       std::to_string(std::llround(need.baked / double(1 << 20))) +
                       " MiB (at most 4096): lower --fps, or bake less (--bake auto or never)");
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
  plan.need = need;
}

// One pass of the player over the frames: the baked parts' displacements, and the scene's size.
PlayedFrames play_frames(const ExportPlan& plan, anim::Player& player) {
  const anim::Scene& scene = plan.scene;
  PlayedFrames played;
  played.baked.resize(scene.objects.size());
  played.reach.assign(scene.objects.size(), 0.0);
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t k = 0; k < plan.frames; ++k) {
    player.evaluate(plan.frame_t[k]);
    for (std::size_t o = 0; o < scene.objects.size(); ++o) {
      const anim::Object& obj = scene.objects[o];
      const ObjectPlan& op = plan.plans[o];
      for (const auto& p : player.positions(o)) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      for (const auto& p : player.deformed(o)) played.reach[o] = std::max(played.reach[o], (p - obj.centre).norm());
      if (!op.any_baked()) continue;
      std::vector<Vec3> d(obj.rest.size(), Vec3::Zero());
      const auto& model = player.deformed(o);
      for (std::size_t v = 0; v < obj.rest.size(); ++v)
        if (op.owner[v] >= 0 && op.baked[std::size_t(op.owner[v])]) d[v] = model[v] - obj.rest[v];
      played.baked[o].push_back(std::move(d));
    }
  }
  plan.report.scene_size = (hi - lo).norm();
  return played;
}

}  // namespace csrbf::gltf::export_detail
