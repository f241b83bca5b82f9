#include "patch_kinds.hpp"

#include "csrbf/geometry.hpp"
#include "csrbf/io/error.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <regex>

namespace csrbf::morph::detail {

using io::FileError;

std::vector<PatchPlane> patch_planes(const VolumeMesh& mesh, MorphBackend& b) {
  std::vector<PatchPlane> planes(mesh.patches.size());
  for (std::size_t k = 0; k < mesh.patches.size(); ++k) {
    const Patch& patch = mesh.patches[k];
    PatchPlane& plane = planes[k];
    // Only boundaries get defaults: the others (processor patches, which differ between the parts
    // of a decomposed mesh, so that the parts' collective sums would not pair up) are skipped.
    if (!patch.boundary) continue;
    Vec3 sum = Vec3::Zero();
    for (const auto p : patch.points) sum += mesh.points[p];
    const double count = b.sum(double(patch.points.size()));
    if (count == 0) continue;
    for (int c = 0; c < 3; ++c) plane.centre[c] = b.sum(sum[c]) / count;
    Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
    for (const auto p : patch.points) {
      const Vec3 x = mesh.points[p] - plane.centre;
      spread += x * x.transpose();
    }
    for (int r = 0; r < 3; ++r)
      for (int c = r; c < 3; ++c) spread(c, r) = spread(r, c) = b.sum(spread(r, c));
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(spread);
    plane.normal = eigen.eigenvectors().col(0).normalized();  // the least spread
    double deviation = 0;
    for (const auto p : patch.points)
      deviation = std::max(deviation, std::abs((mesh.points[p] - plane.centre).dot(plane.normal)));
    plane.deviation = b.max(deviation);
    plane.every_point = b.max(double(patch.points.size() != mesh.points.size())) == 0;
  }
  return planes;
}

namespace {

const char* kind_name(PatchMotion::Kind k) {
  switch (k) {
    case PatchMotion::Kind::Fixed:
      return "fixed";
    case PatchMotion::Kind::Slip:
      return "slip";
    case PatchMotion::Kind::Free:
      return "free";
    default:
      return "moving";
  }
}

/// The regular expression a motion entry's name is, or none (a name that is no valid expression
/// matches by name and group only).
std::optional<std::regex> expression(const std::string& pattern) {
  try {
    return std::regex(pattern, std::regex::ECMAScript);
  } catch (const std::regex_error&) {
    return std::nullopt;
  }
}

}  // namespace

Motion resolve_patches(const VolumeMesh& mesh, const Motion& motion, std::span<const PatchPlane> planes,
                       double mesh_size, bool two_d, std::vector<PatchReport>& reports) {
  const std::size_t np = mesh.patches.size();
  std::vector<int> entry(np, -1);
  std::vector<std::string> how(np);
  std::vector<std::size_t> hits(motion.patches.size(), 0);
  // Exact names first, then groups, then expressions: a patch named in full is never taken by a
  // pattern that also matches it.
  for (int pass = 0; pass < 3; ++pass)
    for (std::size_t e = 0; e < motion.patches.size(); ++e) {
      const std::string& key = motion.patches[e].patch;
      const std::optional<std::regex> re = pass == 2 ? expression(key) : std::nullopt;
      for (std::size_t k = 0; k < np; ++k) {
        if (entry[k] >= 0) continue;
        const Patch& p = mesh.patches[k];
        bool hit = false;
        if (pass == 0) hit = p.name == key;
        if (pass == 1) hit = std::find(p.groups.begin(), p.groups.end(), key) != p.groups.end();
        if (pass == 2) hit = re && std::regex_match(p.name, *re);
        if (!hit) continue;
        entry[k] = int(e);
        how[k] = pass == 0 ? "listed" : pass == 1 ? "group '" + key + "'" : "listed as '" + key + "'";
        ++hits[e];
      }
    }
  std::string names;
  for (const auto& p : mesh.patches) names += (names.empty() ? "" : ", ") + p.name;
  for (std::size_t e = 0; e < motion.patches.size(); ++e) {
    const PatchMotion& pm = motion.patches[e];
    if (!hits[e])
      throw FileError(pm.where + ": the mesh has no patch '" + pm.patch +
                      "'; its patches: " + (names.empty() ? "(none)" : names) +
                      " (an entry may also name a group, or be a regular expression matching whole names)");
    if (pm.kind == PatchMotion::Kind::Displacements && hits[e] > 1)
      throw FileError(pm.where + ": a displacements file moves one patch, but '" + pm.patch + "' names " +
                      std::to_string(hits[e]) + " of them: name the patch itself");
  }
  Motion out = motion;
  out.patches.clear();
  reports.clear();
  for (std::size_t k = 0; k < np; ++k) {
    const Patch& p = mesh.patches[k];
    PatchReport rep{p.name, "free", ""};
    if (entry[k] >= 0) {
      PatchMotion pm = motion.patches[std::size_t(entry[k])];
      pm.patch = p.name;
      rep.kind = kind_name(pm.kind);
      rep.why = how[k];
      if (pm.kind != PatchMotion::Kind::Free) out.patches.push_back(std::move(pm));
      reports.push_back(rep);
      continue;
    }
    PatchMotion pm;
    pm.patch = p.name;
    pm.where = motion.file + ": patch '" + p.name + "' (not listed)";
    pm.by_default = true;
    const std::string& t = p.type;
    bool given = true;
    if (!p.boundary) {
      rep.why = t == "processor" || t == "processorCyclic" ? "processor boundary" : "not a boundary";
      given = false;
    } else if (t == "empty" && two_d) {
      rep.why = "empty: the 2-D morph keeps its planes";
      given = false;
    } else if (k < planes.size() && planes[k].every_point) {
      rep.why = "holds every point of the mesh (the sides of an extruded 2-D mesh)";
      given = false;
    } else if (t == "symmetryPlane" || t == "symmetry" || t == "wedge" || t == "empty") {
      pm.kind = PatchMotion::Kind::Slip;
      rep.why = "type " + t;
    } else if (t.rfind("cyclic", 0) == 0) {
      pm.kind = PatchMotion::Kind::Fixed;
      rep.why = "type " + t + " (its points must move with their partners)";
    } else if (k < planes.size() && planes[k].deviation <= kPlanarTolerance * mesh_size) {
      pm.kind = PatchMotion::Kind::Slip;
      rep.why = "planar";
    } else {
      pm.kind = PatchMotion::Kind::Fixed;
      rep.why = "curved";
    }
    if (given) {
      rep.kind = kind_name(pm.kind);
      out.patches.push_back(std::move(pm));
    }
    reports.push_back(rep);
  }
  return out;
}

SurfaceProjector::SurfaceProjector(const VolumeMesh& mesh, const Patch& patch, const std::string& where) {
  if (patch.face_end <= patch.face_begin || mesh.poly.face_start.size() < patch.face_end + 1)
    throw FileError(where + ": patch '" + patch.name +
                    "' is curved (not within 1e-9 of the mesh's size of a plane), and slip on a curved patch "
                    "projects onto its faces, which csrbf knows in OpenFOAM meshes only: make it fixed, or give "
                    "its motion");
  const auto& t = mesh.poly;
  for (std::uint64_t f = patch.face_begin; f < patch.face_end; ++f) {
    const std::uint64_t a = t.face_start[f], e = t.face_start[f + 1];
    for (std::uint64_t k = a + 1; k + 1 < e; ++k)
      triangles_.push_back(
          {mesh.points[t.face_points[a]], mesh.points[t.face_points[k]], mesh.points[t.face_points[k + 1]]});
  }
  centres_.reserve(triangles_.size());
  for (const auto& tr : triangles_) {
    const Vec3 c = (tr[0] + tr[1] + tr[2]) / 3;
    centres_.push_back(c);
    for (const Vec3& v : tr) reach_ = std::max(reach_, (v - c).norm());
  }
  reach_ = std::max(reach_, 1e-300);
  index_ = NeighborIndex(centres_, 2 * reach_);
}

Vec3 SurfaceProjector::project(const Vec3& y) const {
  Vec3 best = y;
  double best_d2 = std::numeric_limits<double>::infinity();
  const auto consider = [&](std::size_t k) {
    const auto& tr = triangles_[k];
    const Vec3 q = closest_point_on_triangle(y, tr[0], tr[1], tr[2]);
    const double d2 = (q - y).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = q;
    }
  };
  // A triangle whose centre is within 2 reach of y holds the closest point whenever y is within
  // reach of the surface; farther off, every triangle is tried.
  index_.for_each_within(y, [&](std::size_t k, double) { consider(k); });
  if (!(best_d2 <= reach_ * reach_))
    for (std::size_t k = 0; k < triangles_.size(); ++k) consider(k);
  return best;
}

}  // namespace csrbf::morph::detail
