// The glTF exporter's writing of one object (see export_detail.hpp): its rest attributes, its
// morph targets (exact, then baked frames), CSRBF_deformation, primitives, nodes and channels.
#include "export_detail.hpp"

#include "csrbf/kernels.hpp"

#include <cctype>
#include <cstdio>
#include <numbers>
#include <utility>

namespace csrbf::gltf::export_detail {
namespace {

/// One object's export: what its phases share, written in the order the glb holds it.
class ObjectWriter {
 public:
  ObjectWriter(const ExportPlan& ep, Document& doc, anim::Player& player, const PlayedFrames& played, std::size_t o)
      : ep_(ep),
        doc_(doc),
        b(doc.b),
        player_(player),
        played_(played),
        o_(o),
        obj(ep.scene.objects[o]),
        plan(ep.plans[o]),
        nv(obj.rest.size()),
        moved(nv),
        dn(nv) {}

  void write() {
    begin();
    rest_attributes();
    choose_compact_exact();
    list_baked_frames();
    if (ep_.options.compact != Compact::Off && !baked_frame.empty()) {
      collect_baked_deformations();
      choose_compact_baked();
    }
    compact = std::find(in_extension.begin(), in_extension.end(), 1) != in_extension.end() || baked_in_extension;
    if (compact && ep_.options.compact == Compact::Only)
      zero_target = b.accessor({{"componentType", kFloat},
                                {"count", nv},
                                {"type", "VEC3"},
                                {"min", {0.0, 0.0, 0.0}},
                                {"max", {0.0, 0.0, 0.0}}});
    write_exact_targets();
    if (compact) write_compact();
    write_baked_targets();
    ntargets = targets.size();
    orep.targets = ntargets;
    write_mesh();
    write_nodes();
    translation_channel();
    rotation_channel();
    if (ntargets) weights_channel();
    report_parts();
  }

 private:
  const ExportPlan& ep_;
  Document& doc_;
  Builder& b;
  anim::Player& player_;
  const PlayedFrames& played_;
  const std::size_t o_;
  const anim::Object& obj;
  const ObjectPlan& plan;
  const std::size_t nv;
  GltfObjectReport orep;

  // The rest attributes; --quantize's frame (centre qc, half side qk) and the error it makes.
  std::vector<Vec3> rest_normals;
  Vec3 qc = Vec3::Zero();
  double qk = 1.0;
  double quantization_error = 0;
  std::size_t pos_acc = 0, nor_acc = 0;

  // The morph targets as written, and target_data's last target (see there).
  json targets = json::array();
  std::vector<std::uint32_t> index, nindex;
  std::vector<float> value, nvalue;
  int pcomp = kFloat, ncomp = kFloat;  // the last target_data's components (--quantize)
  std::vector<Vec3> moved, dn;
  // Targets whose displacements are identical (a baked part at rest over several frames) share
  // their accessors: stored once.
  // Keyed by a hash of the float values; a hit is compared whole with the earlier target's
  // displacements (held by the plan or the baked frames: nothing is copied).
  std::multimap<std::uint64_t, std::pair<const std::vector<Vec3>*, json>> written;
  std::vector<std::string> target_names;

  // --compact: which exact deformations the extension holds, and their float forms' errors.
  std::vector<char> in_extension;
  std::vector<double> float_error;
  std::vector<std::size_t> baked_frame;  // the frame of each baked target
  std::vector<BakedDeformation> baked_defs;
  std::vector<std::pair<std::size_t, std::size_t>> baked_slots;  // (part, deformation) for vertex groups
  bool baked_in_extension = false;
  double baked_error = 0;
  bool compact = false;
  std::size_t zero_target = 0;  // --compact=only: the accessor of the targets the extension replaces
  json compact_json;
  std::size_t group_accessor = 0;
  bool grouped = false;
  std::vector<json> groups_of;  // per slot: the vertex groups its deformation moves
  json defs = json::array();

  std::size_t ntargets = 0;
  std::size_t pivot = 0, mesh_node = 0;

  void begin() {
    orep.name = obj.name;
    orep.vertices = obj.rest.size();
    b.where = "objects[" + std::to_string(o_) + "] '" + obj.name + "'";
    bool triangles = false;
    for (const auto f : obj.faces) triangles |= f.size() >= 3;
    if (!triangles)
      throw InvalidInput("export: " + b.where +
                         " has no faces (polygons of 3 or more vertices): glTF draws meshes as triangles");
    ep_.report.frame_bytes += ep_.frames * nv * 12;
  }

  /// The rest shape's box: its lower and upper corners.
  std::pair<Vec3, Vec3> rest_box() const {
    Vec3 lo = obj.rest.front(), hi = lo;
    for (const Vec3& p : obj.rest) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    return {lo, hi};
  }
  /// The rest shape's size: its box's diagonal.
  double rest_size() const {
    const auto [lo, hi] = rest_box();
    return (hi - lo).norm();
  }

  // The shared attributes: rest positions and normals.
  // --quantize (KHR_mesh_quantization): positions as normalized SHORT in the box's frame (centre
  // qc, half side qk: the mesh node scales them back), normals as normalized BYTE; the targets'
  // displacements as SHORT in the same frame, their normals' changes as BYTE, each where it fits
  // in [-1, 1] (else float). The largest vertex error this makes is reported.
  void rest_attributes() {
    std::vector<float> pos(3 * nv), nor(3 * nv);
    rest_normals = vertex_normals(obj.rest, obj.faces);
    for (std::size_t v = 0; v < nv; ++v)
      for (int c = 0; c < 3; ++c) {
        pos[3 * v + std::size_t(c)] = float(obj.rest[v][c]);
        nor[3 * v + std::size_t(c)] = float(rest_normals[v][c]);
      }
    if (ep_.options.quantize) {
      const auto [lo, hi] = rest_box();
      qc = 0.5 * (lo + hi);
      qk = 0.5 * (hi - lo).maxCoeff();
      if (!(qk > 0)) qk = 1.0;
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
  }

  std::size_t quantized_attribute(const std::vector<float>& v, int component, const char* what) {
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
  }

  // A target's displacements and its normals' change, as (index, value) lists, and their bytes as
  // sparse accessors (an index and a float xyz an entry; one explicit zero where none).
  // A target's normals: a client blends n0 + w dn (then normalises) at weight w. For an exact
  // target (w is its phase, anywhere in [0, 1]), dn is fitted by least squares to the deformed
  // mesh's normals at w = 1/4, 1/2, 3/4 and 1, which lowers the largest angle against them
  // (dn = n(1) - n0 is right at w = 1 only); a baked frame's target (w is 1 at its frame) keeps
  // n(1) - n0. The largest angle at those weights is reported, with the endpoint's for comparison.
  std::size_t target_data(const std::vector<Vec3>& d, bool fit_phases = false) {
    nonzero(d, 0.0, index, value);
    for (std::size_t v = 0; v < nv; ++v) moved[v] = obj.rest[v] + d[v];
    const std::vector<Vec3> n1 = vertex_normals(moved, obj.faces);
    for (std::size_t v = 0; v < nv; ++v) dn[v] = n1[v] - rest_normals[v];
    if (fit_phases) fit_normal_changes(d, n1);
    nonzero(dn, 1e-6, nindex, nvalue);
    pcomp = ncomp = kFloat;
    if (ep_.options.quantize) {
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
  }

  /// dn fitted to the normals of the mesh moved by w d at the weights ws (n1 at w = 1).
  void fit_normal_changes(const std::vector<Vec3>& d, const std::vector<Vec3>& n1) {
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

  /// Writes the target (or shares an identical one's accessors); returns its bytes as target_data gives them.
  std::size_t add_target(const std::vector<Vec3>& d, bool fit_phases = false) {
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
        ++ep_.report.shared_targets;
        return bytes;
      }
    const std::size_t pa = b.sparse_vec3(nv, index, value, "a morph target's displacements", pcomp);
    const std::size_t na = b.sparse_vec3(nv, nindex, nvalue, "a morph target's normals", ncomp);
    const json t = {{"POSITION", pa}, {"NORMAL", na}};
    targets.push_back(t);
    written.emplace(h, std::make_pair(&d, t));
    return bytes;
  }

  // --compact: which exact deformations the extension holds. Each is evaluated the way a client
  // evaluates it, from float sources and coefficients at the float rest positions, against the
  // exact displacement; one whose float form errs by more than 1e-5 of the object's rest size
  // (coefficients far above the displacements: controls nearly on top of each other) stays an
  // ordinary morph target, and the report says so.
  void choose_compact_exact() {
    in_extension.assign(plan.exact.size(), 0);
    float_error.assign(plan.exact.size(), 0.0);
    if (ep_.options.compact == Compact::Off || plan.exact.empty()) return;
    const double tolerance = 1e-5 * rest_size();
    for (std::size_t j = 0; j < plan.exact.size(); ++j) {
      const auto& e = plan.exact[j];
      const SpaceMap form = float_form(*obj.parts[e.part].deformations[e.deformation].map);
      std::vector<Vec3> x;
      std::vector<std::size_t> which;
      for (std::size_t v = 0; v < nv; ++v)
        if (e.d[v] != Vec3::Zero() || moves_vertex(obj, plan, e, v)) {
          which.push_back(v);
          x.push_back(obj.rest[v].cast<float>().cast<double>());
        }
      std::vector<Vec3> dw(x.size());
      if (!x.empty()) form.displacements(x.data()->data(), dw.data()->data(), x.size());
      double err = 0;
      for (std::size_t i = 0; i < x.size(); ++i) {
        const double d = (dw[i] - e.d[which[i]]).norm();
        err = std::isnan(d) ? std::numeric_limits<double>::infinity() : std::max(err, d);
      }
      float_error[j] = err;
      in_extension[j] = err <= tolerance && float_radius(form.radius());
      if (!in_extension[j]) {
        const auto& def = obj.parts[e.part].deformations[e.deformation];
        ep_.report.compact_left_out.push_back(obj.name + "/" + obj.parts[e.part].name + "/" + def.name);
      }
    }
  }

  // The baked frames (frames where nothing moves have no target); their targets follow the exact ones.
  void list_baked_frames() {
    if (!plan.any_baked()) return;
    for (std::size_t k = 0; k < ep_.frames; ++k) {
      bool moves = false;
      for (const auto& d : played_.baked[o_][k]) moves |= d != Vec3::Zero();
      if (moves) baked_frame.push_back(k);
    }
  }

  // --compact: the baked parts as CSRBF_deformation too. Each baked target's frame becomes terms
  // of its weight: a fixed deformation keeps its sources, with one term a frame, its coefficients
  // times the frame's phase; a contact, refitted every frame, is a deformation a frame (its
  // sources move) with one term. A Compose part's deformations are stages, in order. The baked
  // targets are replaced only where every frame's float form, evaluated as a client evaluates
  // it, is within the tolerance of the baked displacement.
  void collect_baked_deformations() {
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
          const double t = ep_.frame_t[baked_frame[j]];
          const double phase = def.schedule.phase(t);
          if (phase == 0.0) continue;
          if (def.map) {
            baked_defs.back().terms.emplace_back(j, phase);
          } else if (auto fit = player_.contact_map(o_, p, i, t)) {
            baked_defs.push_back({p, i, slot, stage, std::make_shared<SpaceMap>(std::move(*fit)), {{j, phase}}});
          }
        }
      }
    }
  }

  /// Part p at baked target j as a client evaluates the float forms, stage after stage, at the
  /// float rest positions: its largest distance from the baked frame (infinite where not a number).
  void measure_baked_part(std::size_t j, std::size_t p) {
    const auto& want = played_.baked[o_][baked_frame[j]];
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
        const auto term = std::find_if(bd.terms.begin(), bd.terms.end(), [&](const auto& t) { return t.first == j; });
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

  void choose_compact_baked() {
    const double tolerance = 1e-5 * rest_size();
    for (std::size_t j = 0; j < baked_frame.size() && baked_error <= tolerance; ++j)
      for (std::size_t p = 0; p < obj.parts.size(); ++p)
        if (plan.baked[p]) measure_baked_part(j, p);
    bool radii = true;
    for (const auto& bd : baked_defs) radii = radii && float_radius(bd.map->radius());
    baked_in_extension = baked_error <= tolerance && radii;
    if (!baked_in_extension) {
      baked_defs.clear();
      baked_slots.clear();
      for (std::size_t p = 0; p < obj.parts.size(); ++p)
        if (plan.baked[p]) ep_.report.compact_left_out.push_back(obj.name + "/" + obj.parts[p].name + " (baked)");
    }
  }

  void write_exact_targets() {
    for (std::size_t j = 0; j < plan.exact.size(); ++j) {
      const auto& e = plan.exact[j];
      // The target's displacements and normals are computed once: written as fallback, or only
      // measured where --compact=only leaves the target empty.
      std::size_t bytes = 0;
      if (in_extension[j] && ep_.options.compact == Compact::Only) {
        bytes = target_data(e.d, true);
        targets.push_back({{"POSITION", zero_target}, {"NORMAL", zero_target}});
      } else {
        bytes = add_target(e.d, true);
      }
      if (in_extension[j]) ep_.report.replaced_target_bytes += bytes;
      target_names.push_back(obj.parts[e.part].deformations[e.deformation].name);
    }
  }

  // CSRBF_deformation (--compact): each exact target's deformation as its sources, coefficients,
  // radius and polynomial, its term's weight the target's, which it replaces. Where deformations
  // move only some vertices (their part's, their area's), a vertex group a vertex: the set of
  // deformations that move it, numbered.
  void write_compact() {
    write_groups();
    for (std::size_t j = 0; j < plan.exact.size(); ++j) {
      if (!in_extension[j]) continue;
      const auto& e = plan.exact[j];
      const anim::Deformation& def = obj.parts[e.part].deformations[e.deformation];
      orep.compact_error = std::max(orep.compact_error, float_error[j]);
      write_deformation(*def.map, {{j, 1.0}}, 0, j, def.name, obj.parts[e.part].name);
    }
    for (const auto& bd : baked_defs) {
      if (bd.terms.empty()) continue;  // a fixed deformation whose phase is 0 at every baked frame
      std::vector<std::pair<std::size_t, double>> terms;
      for (const auto& [j, phase] : bd.terms) terms.emplace_back(plan.exact.size() + j, phase);
      write_deformation(*bd.map, terms, bd.stage, plan.exact.size() + bd.slot,
                        obj.parts[bd.part].deformations[bd.deformation].name, obj.parts[bd.part].name);
    }
    if (baked_in_extension) orep.compact_error = std::max(orep.compact_error, baked_error);
    compact_json = {{"deformations", defs}};
    if (!std::isfinite(orep.compact_error))
      throw InvalidInput("export: " + b.where +
                         " --compact: a deformation evaluated from its float sources and "
                         "coefficients is not finite (coefficients beyond single precision?)");
  }

  // Slots: the exact targets j, then each baked part's deformations (plan.exact.size() + slot).
  void write_groups() {
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
    groups_of.assign(plan.exact.size() + baked_slots.size(), json::array());
    for (const auto& [set, id] : ids)
      for (const std::uint32_t j : set) groups_of[j].push_back(id);
    if (!grouped) return;
    // UNSIGNED_SHORT, one a vertex at a stride of 4 bytes: glTF aligns every vertex attribute's
    // elements to 4 bytes.
    std::vector<std::uint16_t> packed(2 * nv, 0);
    for (std::size_t v = 0; v < nv; ++v) packed[2 * v] = std::uint16_t(group[v]);
    const std::size_t view = b.view(packed.data(), packed.size() * 2, kArrayBuffer, {MeshoptView::Mode::Attributes, 4});
    b.doc["bufferViews"][view]["byteStride"] = 4;
    group_accessor =
        b.accessor({{"bufferView", view}, {"componentType", kUnsignedShort}, {"count", nv}, {"type", "SCALAR"}});
    ep_.report.compact_bytes += packed.size() * 2;
    orep.groups = ids.size();
  }

  // A deformation: its sources, kernel and radius, and one term a (weight, phase) of terms:
  // the coefficients and polynomial times the phase, in float.
  void write_deformation(const SpaceMap& map, const std::vector<std::pair<std::size_t, double>>& terms,
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
      ep_.report.compact_bytes += 12 * n;
      term_list.push_back(std::move(term));
    }
    const std::size_t sa = b.floats(src, 3, "a deformation's sources");
    ep_.report.compact_bytes += 12 * n;
    std::string kernel(kernel_name(map.kernel()));
    for (char& ch : kernel) ch = char(std::toupper(static_cast<unsigned char>(ch)));
    json d = {{"kernel", kernel}, {"radius", map.radius()}, {"sources", sa}, {"terms", std::move(term_list)}};
    if (stage > 0) d["stage"] = stage;
    d["extras"] = {{"name", name}, {"part", part}};
    if (grouped) d["groups"] = groups_of[slot];
    defs.push_back(std::move(d));
    ++orep.compact_deformations;
  }

  void write_baked_targets() {
    for (const std::size_t k : baked_frame) {
      std::size_t bytes = 0;
      if (baked_in_extension && ep_.options.compact == Compact::Only) {
        bytes = target_data(played_.baked[o_][k]);
        targets.push_back({{"POSITION", zero_target}, {"NORMAL", zero_target}});
      } else {
        bytes = add_target(played_.baked[o_][k]);
      }
      if (baked_in_extension) ep_.report.replaced_target_bytes += bytes;
      char name[64];
      std::snprintf(name, sizeof name, "baked frame %zu (t = %.4g s)", k, ep_.frame_t[k]);
      target_names.push_back(name);
    }
  }

  // Weights at time t: the phases of the exact targets, and the baked frames' cross-fade.
  void weights_at(double t, std::vector<double>& w) const {
    const std::vector<double>& frame_t = ep_.frame_t;
    w.assign(ntargets, 0.0);
    for (std::size_t j = 0; j < plan.exact.size(); ++j) {
      const auto& e = plan.exact[j];
      w[j] = obj.parts[e.part].deformations[e.deformation].schedule.phase(t);
    }
    if (baked_frame.empty()) return;
    // The sample interval [f0, f0 + 1] holding t, and how far into it.
    std::size_t f0 = ep_.frames - 1;
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
  }

  // The primitives: faces in no part with the object's look, then each part's own faces.
  json primitives() {
    json out = json::array();
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
          if (!ep_.options.textures.coordinates)
            throw InvalidInput(
                "has a texture, and the exporter was given no texture coordinates "
                "(GltfOptions::textures; csrbf::render::export_gltf gives VTK's)");
          uv = ep_.options.textures.coordinates(obj, face_list, m.mapping);
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
      json prim = {{"attributes", attrs}, {"indices", ia}, {"material", doc_.material(m, mname)}, {"mode", 4}};
      if (ntargets) prim["targets"] = targets;
      out.push_back(prim);
    }
    return out;
  }

  void write_mesh() {
    json mesh = {{"name", obj.name}, {"primitives", primitives()}};
    std::vector<double> w0;
    if (ntargets) {
      weights_at(0.0, w0);
      mesh["weights"] = w0;
      mesh["extras"] = {{"targetNames", target_names}};
    }
    if (compact) {
      mesh["extensions"] = {{"CSRBF_deformation", compact_json}};
      doc_.any_compact = true;
    }
    b.doc["meshes"].push_back(mesh);
  }

  // The pivot (the centre of gravity, moved and turned) and, under it, the mesh (model coordinates).
  void write_nodes() {
    const std::size_t mesh_index = b.doc["meshes"].size() - 1;
    pivot = b.doc["nodes"].size();
    b.doc["nodes"].push_back({{"name", obj.name + " pivot"}, {"children", {pivot + 1}}});
    json mesh_json = {{"name", obj.name}, {"mesh", mesh_index}, {"translation", vec_json(qc - obj.centre)}};
    if (ep_.options.quantize) mesh_json["scale"] = {qk, qk, qk};  // KHR_mesh_quantization's positions back
    b.doc["nodes"].push_back(std::move(mesh_json));
    b.doc["scenes"][0]["nodes"].push_back(pivot);
    mesh_node = pivot + 1;
  }

  // Translation: the trajectory, key for key (cut at 0 and at the duration), as CUBICSPLINE.
  void translation_channel() {
    const double duration = ep_.duration;
    if (!(obj.trajectory && obj.trajectory->keys().size() > 1)) {
      b.doc["nodes"][pivot]["translation"] = vec_json(anim::pose_at(obj, 0.0).position);
      return;
    }
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
    const auto written_at = [&](std::size_t i, int part) {
      return Vec3(out[9 * i + 3 * part], out[9 * i + 3 * part + 1], out[9 * i + 3 * part + 2]);
    };
    double spline_error = 0;
    for (std::size_t i = 0; i + 1 < times.size(); ++i)
      for (int s = 1; s < 8; ++s) {
        const double h = s / 8.0, dt = times[i + 1] - times[i], h2 = h * h, h3 = h2 * h;
        const Vec3 p = (2 * h3 - 3 * h2 + 1) * written_at(i, 1) + (h3 - 2 * h2 + h) * dt * written_at(i, 2) +
                       (-2 * h3 + 3 * h2) * written_at(i + 1, 1) + (h3 - h2) * dt * written_at(i + 1, 0);
        spline_error = std::max(spline_error, (p - tr.position(times[i] + h * dt)).norm());
      }
    orep.max_deviation += spline_error;
    doc_.add_channel(pivot, "translation", doc_.time_accessor(times), b.floats(out, 3, "the trajectory"),
                     "CUBICSPLINE");
    b.doc["nodes"][pivot]["translation"] = vec_json(tr.position(0.0));
  }

  // Rotation: slerp tracks key for key; squad sampled at the frame rate (and at its keys).
  void rotation_channel() {
    const double duration = ep_.duration;
    const anim::OrientationTrack& ot = obj.orientation;
    if (ot.keys().size() <= 1) {
      b.doc["nodes"][pivot]["rotation"] = quat_json(ot.rotation(0.0));
      return;
    }
    std::vector<double> times = {0.0, duration};
    for (const auto& k : ot.keys()) times.push_back(k.time);
    if (ot.interpolation() == anim::Rotation::Squad) times.insert(times.end(), ep_.frame_t.begin(), ep_.frame_t.end());
    double worst =
        merged_gap(times, duration, [&](double a, double c) { return angle_between(ot.rotation(a), ot.rotation(c)); });
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
    orep.max_deviation += worst * played_.reach[o_];
    std::vector<float> out;
    for (const auto& r : q)
      for (const double c : {r.x(), r.y(), r.z(), r.w()}) out.push_back(float(c));
    doc_.add_channel(pivot, "rotation", doc_.time_accessor(times), b.floats(out, 4, "the orientation"), "LINEAR");
    b.doc["nodes"][pivot]["rotation"] = quat_json(q.front());
  }

  // Weights: at the frames, the phase keys and the duration, LINEAR.
  void weights_channel() {
    const double duration = ep_.duration;
    std::vector<double> times = ep_.frame_t;
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
    doc_.add_channel(mesh_node, "weights", doc_.time_accessor(times), b.floats(out, 1, "the morph weights"), "LINEAR");
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

  void report_parts() {
    GltfReport& report = ep_.report;
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
};

}  // namespace

void write_object(const ExportPlan& plan, Document& doc, anim::Player& player, const PlayedFrames& played,
                  std::size_t o) {
  ObjectWriter(plan, doc, player, played, o).write();
}

}  // namespace csrbf::gltf::export_detail
