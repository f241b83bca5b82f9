#include "csrbf/anim/scene.hpp"

#include "csrbf/displacement_field.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace csrbf::anim {

void Object::finalize() {
  Vec3 sum = Vec3::Zero();
  double area = 0.0;
  for (const auto& f : faces) {
    // Fan triangulation; each triangle's centroid weighted by its area.
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      const Vec3& a = rest[f[0]];
      const Vec3& b = rest[f[k]];
      const Vec3& c = rest[f[k + 1]];
      const double w = (b - a).cross(c - a).norm() / 2;
      sum += w * (a + b + c) / 3;
      area += w;
    }
  }
  if (area > 0 && std::isfinite(area)) {
    centre = sum / area;
    return;
  }
  centre = Vec3::Zero();
  for (const auto& p : rest) centre += p;
  if (!rest.empty()) centre /= double(rest.size());
}

std::size_t Scene::frame_count(double from, double to) const {
  if (!(to >= from)) return 0;
  // Frames at from + k / fps for k = 0, 1, ... while within [from, to] (a tolerance for rounding).
  return std::size_t(std::floor((to - from) * fps + 1e-9)) + 1;
}

Pose pose_at(const Object& object, double t) {
  Pose p;
  p.rotation = object.orientation.rotation(t);
  p.position = object.trajectory ? object.trajectory->position(t) : object.centre;
  return p;
}

void contact_controls(const Vec3& lo, const Vec3& hi, const Vec3& centre, double sphere_radius, double spread,
                      std::vector<Vec3>& s, std::vector<Vec3>& d) {
  s.clear();
  d.clear();
  for (int c = 0; c < 8; ++c) {
    const Vec3 p((c & 1) ? hi.x() : lo.x(), (c & 2) ? hi.y() : lo.y(), (c & 4) ? hi.z() : lo.z());
    s.push_back(p);
    d.push_back(p);
  }
  const double step = spread * sphere_radius;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const double wall = side ? hi[axis] : lo[axis];
      const double pen = sphere_radius - std::abs(centre[axis] - wall);
      if (pen <= 0) continue;
      Vec3 n = Vec3::Zero();
      n[axis] = side ? 1.0 : -1.0;
      Vec3 contact = centre;
      contact[axis] = wall;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const Vec3 offsets[5] = {Vec3::Zero(), Vec3::Unit(u) * step, -Vec3::Unit(u) * step, Vec3::Unit(v) * step,
                               -Vec3::Unit(v) * step};
      for (int k = 0; k < 5; ++k) {
        Vec3 p = contact + offsets[k];
        p[u] = std::clamp(p[u], lo[u], hi[u]);
        p[v] = std::clamp(p[v], lo[v], hi[v]);
        // A corner is already pinned; a patch control on it would duplicate that source.
        const bool at_corner = (p[u] == lo[u] || p[u] == hi[u]) && (p[v] == lo[v] || p[v] == hi[v]);
        if (at_corner || std::find(s.begin(), s.end(), p) != s.end()) continue;
        s.push_back(p);
        d.push_back(p + n * (k == 0 ? pen : 0.6 * pen));
      }
    }
}

// ---------------------------------------------------------------------------------------------------

namespace {

struct PartState {
  std::vector<double> rest;                                      // the part's rest vertices, interleaved
  std::vector<std::optional<DisplacementField<double>>> fields;  // per deformation, where kept
  std::vector<std::vector<char>> inside;      // per deformation with an active area: 1 for a part vertex in it
  std::vector<double> a, b;                   // work buffers
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();  // bounding box of the rest vertices
};

struct ObjectState {
  std::vector<PartState> parts;
  std::vector<Vec3> model, world;
};

}  // namespace

struct Player::Impl {
  std::vector<ObjectState> objects;
  std::vector<Vec3> s, d;  // contact controls
};

Player::Player(const Scene& scene) : scene_(&scene), impl_(std::make_unique<Impl>()) {
  impl_->objects.resize(scene.objects.size());
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const Object& obj = scene.objects[o];
    ObjectState& st = impl_->objects[o];
    st.model = obj.rest;
    st.world = obj.rest;
    st.parts.resize(obj.parts.size());
    for (std::size_t p = 0; p < obj.parts.size(); ++p) {
      const Part& part = obj.parts[p];
      PartState& ps = st.parts[p];
      ps.rest.reserve(3 * part.vertices.size());
      ps.lo = Vec3::Constant(std::numeric_limits<double>::infinity());
      ps.hi = -ps.lo;
      for (const auto v : part.vertices) {
        const Vec3& x = obj.rest[v];
        ps.rest.insert(ps.rest.end(), {x.x(), x.y(), x.z()});
        ps.lo = ps.lo.cwiseMin(x);
        ps.hi = ps.hi.cwiseMax(x);
      }
      ps.a.resize(ps.rest.size());
      ps.b.resize(ps.rest.size());
      ps.fields.resize(part.deformations.size());
      ps.inside.resize(part.deformations.size());
      for (std::size_t k = 0; k < part.deformations.size(); ++k) {
        const Deformation& def = part.deformations[k];
        if (!def.area.empty()) {
          ps.inside[k].resize(part.vertices.size());
          for (std::size_t i = 0; i < part.vertices.size(); ++i)
            ps.inside[k][i] = std::binary_search(def.area.begin(), def.area.end(), part.vertices[i]);
        }
        // Sum: every fixed deformation acts on the rest shape; Compose: only the first does.
        if (def.map && (part.combine == Combine::Sum || k == 0))
          ps.fields[k].emplace(*def.map, ps.rest.data(), part.vertices.size());
      }
    }
  }
}

double Player::bytes(const Scene& scene) {
  double total = 0;
  for (const Object& obj : scene.objects) {
    total += 2.0 * 24.0 * double(obj.rest.size());  // model, world
    for (const Part& part : obj.parts) {
      const double n = double(part.vertices.size());
      total += 3.0 * 24.0 * n;  // rest, a, b
      for (std::size_t k = 0; k < part.deformations.size(); ++k) {
        const Deformation& def = part.deformations[k];
        if (!def.area.empty()) total += n;                                                 // inside
        if (def.map && (part.combine == Combine::Sum || k == 0)) total += 2.0 * 24.0 * n;  // a field's rest, d
      }
    }
  }
  return total;
}

Player::~Player() = default;
Player::Player(Player&&) noexcept = default;

std::optional<SpaceMap> Player::contact_map(std::size_t object, std::size_t part, std::size_t deformation,
                                            double t) const {
  std::vector<Vec3> s, d;
  return contact_fit(object, part, deformation, t, s, d);
}

std::optional<SpaceMap> Player::contact_fit(std::size_t o, std::size_t p, std::size_t k, double t, std::vector<Vec3>& s,
                                            std::vector<Vec3>& d) const {
  const Object& obj = scene_->objects.at(o);
  const Deformation& def = obj.parts.at(p).deformations.at(k);
  if (!def.contact) throw InvalidInput("Player::contact_map: the deformation is not a contact");
  const PartState& ps = impl_->objects[o].parts[p];
  const Pose pose = pose_at(obj, t);
  const Pose cp = pose_at(scene_->objects[def.contact->collider], t);
  // The collider's centre in this object's model coordinates.
  const Vec3 centre = pose.rotation.conjugate() * (cp.position - pose.position) + obj.centre;
  contact_controls(ps.lo, ps.hi, centre, def.contact->collider_radius, def.contact->spread, s, d);
  if (s.size() == 8) return std::nullopt;
  // A contact is refitted at every frame: a fit that fails says where and when.
  try {
    return SpaceMap::fit(s, d, def.options);
  } catch (const std::exception& e) {
    std::ostringstream m;
    m << "objects[" << o << "].parts[" << p << "].deformations[" << k << "] (contact) at t = " << t
      << " s: " << e.what();
    throw InvalidInput(m.str());
  }
}

void Player::evaluate(double t) {
  const Scene& scene = *scene_;
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const Object& obj = scene.objects[o];
    ObjectState& st = impl_->objects[o];
    const Pose pose = pose_at(obj, t);
    std::copy(obj.rest.begin(), obj.rest.end(), st.model.begin());
    for (std::size_t p = 0; p < obj.parts.size(); ++p) {
      const Part& part = obj.parts[p];
      PartState& ps = st.parts[p];
      const std::size_t n = part.vertices.size();
      if (part.deformations.empty() || n == 0) continue;
      std::copy(ps.rest.begin(), ps.rest.end(), ps.a.begin());
      for (std::size_t k = 0; k < part.deformations.size(); ++k) {
        const Deformation& def = part.deformations[k];
        const double phase = def.schedule.phase(t);
        if (phase == 0.0) continue;
        if (def.contact) {
          const std::optional<SpaceMap> fitted = contact_fit(o, p, k, t, impl_->s, impl_->d);
          if (!fitted) continue;  // no wall touched: corners only, the identity
          const SpaceMap& map = *fitted;
          const double* in = part.combine == Combine::Sum ? ps.rest.data() : ps.a.data();
          if (part.combine == Combine::Sum) {
            map.displacements(in, ps.b.data(), n);
            for (std::size_t i = 0; i < 3 * n; ++i) ps.a[i] += phase * ps.b[i];
          } else {
            map.apply(in, ps.a.data(), n, phase);
          }
        } else if (part.combine == Combine::Sum) {
          const auto disp = ps.fields[k]->displacements();
          const auto& inside = ps.inside[k];
          for (std::size_t i = 0; i < 3 * n; ++i)
            if (inside.empty() || inside[i / 3]) ps.a[i] += phase * disp[i];
        } else {
          // Vertices outside the active area keep where they were before this deformation.
          const auto& inside = ps.inside[k];
          if (!inside.empty()) std::copy(ps.a.begin(), ps.a.end(), ps.b.begin());
          if (ps.fields[k])
            ps.fields[k]->apply(phase, ps.a.data());  // the first: rest + phase d(rest)
          else
            def.map->apply(ps.a.data(), ps.a.data(), n, phase);
          for (std::size_t i = 0; i < inside.size(); ++i)
            if (!inside[i]) std::copy_n(ps.b.begin() + std::ptrdiff_t(3 * i), 3, ps.a.begin() + std::ptrdiff_t(3 * i));
        }
      }
      for (std::size_t i = 0; i < n; ++i)
        st.model[part.vertices[i]] = Vec3(ps.a[3 * i], ps.a[3 * i + 1], ps.a[3 * i + 2]);
    }
    const Eigen::Matrix3d r = pose.rotation.toRotationMatrix();
    bool finite = pose.position.allFinite() && r.allFinite();
    for (std::size_t i = 0; i < st.model.size(); ++i) {
      st.world[i] = r * (st.model[i] - obj.centre) + pose.position;
      finite = finite && st.world[i].allFinite();
    }
    if (!finite) {
      // A trajectory far out (keys at 1e308) or a deformation that overflows: never a NaN frame.
      std::ostringstream m;
      m << "objects[" << o << "]" << (obj.name.empty() ? "" : " ('" + obj.name + "')") << " at t = " << t
        << " s: the pose or a vertex is not finite (trajectory keys or displacements too large)";
      throw InvalidInput(m.str());
    }
  }
}

const std::vector<Vec3>& Player::positions(std::size_t object) const { return impl_->objects.at(object).world; }
const std::vector<Vec3>& Player::deformed(std::size_t object) const { return impl_->objects.at(object).model; }

}  // namespace csrbf::anim
