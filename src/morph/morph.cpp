#include "csrbf/morph/morph.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/morph/volume_file.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/units.hpp"
#include "patch_kinds.hpp"
#include "morph_phases.hpp"
#include "radius.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

namespace csrbf::morph {

namespace {

using detail::LocalMapping;
using io::FileError;

std::string show(const Vec3& v) {
  std::ostringstream s;
  s.precision(9);
  s << '[' << v.x() << ", " << v.y() << ", " << v.z() << ']';
  return s.str();
}

std::string patch_list(const VolumeMesh& mesh) {
  std::string s;
  for (const auto& p : mesh.patches) s += (s.empty() ? "" : ", ") + p.name;
  return s.empty() ? "(none)" : s;
}

}  // namespace

std::unique_ptr<FittedMapping> MorphBackend::fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                                 const FitOptions& options, std::span<const std::uint64_t>) {
  return std::make_unique<LocalMapping>(SpaceMap::fit(sources, targets, options));
}

struct SeriesBackend::Entry {
  std::vector<Vec3> sources;
  FitOptions options;
  SpaceMap map;
};

std::unique_ptr<FittedMapping> SeriesBackend::fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                                  const FitOptions& options, std::span<const std::uint64_t>) {
  const auto same = [&](const Entry& e) {
    return e.options.radius == options.radius && e.options.kernel == options.kernel &&
           e.options.polynomial == options.polynomial && e.options.solver == options.solver &&
           e.options.ordering == options.ordering && e.sources.size() == sources.size() &&
           std::equal(sources.begin(), sources.end(), e.sources.begin());
  };
  for (std::size_t k = 0; k < last_.size(); ++k) {
    if (!same(*last_[k])) continue;
    ++reused_;
    auto e = last_[k];
    e->map = e->map.with_destinations(targets);
    last_.erase(last_.begin() + std::ptrdiff_t(k));
    last_.insert(last_.begin(), e);
    return std::make_unique<LocalMapping>(e->map);
  }
  auto e = std::make_shared<Entry>(
      Entry{{sources.begin(), sources.end()}, options, SpaceMap::fit(sources, targets, options)});
  ++factorisations_;
  last_.insert(last_.begin(), e);
  if (last_.size() > 4) last_.pop_back();
  return std::make_unique<LocalMapping>(e->map);
}

void MorphBackend::write_copy(const VolumeFile& file, std::span<const Vec3> points, const std::filesystem::path& out) {
  file.write_copy(points, out);
}

void MorphBackend::write_in_place(const VolumeFile& file, std::span<const Vec3> points) { file.write_in_place(points); }

MorphBackend& local_backend() {
  static MorphBackend b;
  return b;
}

std::size_t Prescribed::moving() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
    n += !fixed[i] && (slip.empty() || slip[i] < 0) && displacements[i] != Vec3::Zero();
  return n;
}

Prescribed prescribe(const VolumeMesh& mesh, const Motion& motion, bool part) {
  const std::size_t np = mesh.points.size();
  const double tol = 1e-12 * std::max(detail::mesh_size(mesh), 1e-300);
  std::vector<std::int32_t> who(np, -1);  // the motion that set a point
  std::vector<Vec3> d(np, Vec3::Zero());
  std::unordered_map<std::uint64_t, std::uint32_t> ids;
  std::uint64_t min_id = 0, max_id = 0;
  if (!mesh.point_ids.empty()) {
    ids.reserve(np);
    min_id = max_id = mesh.point_ids[0];
    for (std::size_t i = 0; i < np; ++i) {
      ids.emplace(mesh.point_ids[i], std::uint32_t(i));
      min_id = std::min(min_id, mesh.point_ids[i]);
      max_id = std::max(max_id, mesh.point_ids[i]);
    }
  }
  const auto number = [&](std::uint32_t p) { return mesh.point_ids.empty() ? std::uint64_t(p) : mesh.point_ids[p]; };
  Prescribed out;
  if (part) out.used.resize(motion.patches.size());
  for (std::size_t m = 0; m < motion.patches.size(); ++m) {
    const PatchMotion& pm = motion.patches[m];
    if (part && pm.kind == PatchMotion::Kind::Displacements) out.used[m].assign(pm.given.size(), 0);
    if (pm.kind == PatchMotion::Kind::Free) continue;  // no controls
    const Patch* patch = mesh.patch(pm.patch);
    if (!patch)
      throw FileError(pm.where + ": the mesh has no patch '" + pm.patch + "'; its patches: " + patch_list(mesh));
    if (patch->points.empty()) {
      if (part || pm.by_default) continue;  // the patch lies in other parts of the mesh, or is unlisted
      throw FileError(pm.where + ": patch '" + pm.patch + "' has no points");
    }
    std::vector<Vec3> given;
    if (pm.kind == PatchMotion::Kind::Displacements) {
      given.assign(patch->points.size(), Vec3::Constant(std::nan("")));
      std::vector<std::size_t> line(patch->points.size(), 0);
      for (std::size_t gi = 0; gi < pm.given.size(); ++gi) {
        const auto& g = pm.given[gi];
        const std::string at = pm.at(g);
        std::uint64_t index = g.point;
        if (!mesh.point_ids.empty()) {  // the file's own numbers (Gmsh node tags)
          const auto id = ids.find(g.point);
          if (id == ids.end() && part) continue;  // a point of another part
          if (id == ids.end())
            throw FileError(at + "point " + std::to_string(g.point) +
                            " is not a node of the mesh (its nodes are numbered " + std::to_string(min_id) + " to " +
                            std::to_string(max_id) + ")");
          index = id->second;
        } else if (g.point >= np) {
          throw FileError(at + "point " + std::to_string(g.point) + " is out of range: the mesh has " +
                          std::to_string(np) + " points (0 to " + std::to_string(np ? np - 1 : 0) + ")");
        }
        const auto it = std::lower_bound(patch->points.begin(), patch->points.end(), std::uint32_t(index));
        if ((it == patch->points.end() || *it != index) && part) continue;  // on this patch in another part
        if (part) out.used[m][gi] = 1;
        if (it == patch->points.end() || *it != index)
          throw FileError(at + "point " + std::to_string(g.point) + " is not on patch '" + pm.patch + "'");
        const auto k = std::size_t(it - patch->points.begin());
        if (line[k])
          throw FileError(
              at + "point " + std::to_string(g.point) + " is given twice (also " +
              (pm.file.empty() ? "as row " + std::to_string(line[k] - 1) : "on line " + std::to_string(line[k])) + ")");
        line[k] = g.line;
        if (!(g.d.cwiseAbs().maxCoeff() <= 1e150))  // what a fit takes (its coordinates within 1e150)
          throw FileError(at + "point " + std::to_string(g.point) + ": displacement (" + io::format_number(g.d.x()) +
                          ", " + io::format_number(g.d.y()) + ", " + io::format_number(g.d.z()) + ") is beyond 1e150");
        given[k] = g.d;
      }
      for (std::size_t k = 0; k < line.size(); ++k)
        if (!line[k]) {
          const std::size_t missing = std::size_t(std::count(line.begin(), line.end(), std::size_t(0)));
          throw FileError(pm.source() + ": " + std::to_string(missing) + " of the " + std::to_string(line.size()) +
                          " points of patch '" + pm.patch + "' have no displacement; the first is point " +
                          std::to_string(number(patch->points[k])));
        }
    }
    const bool fixed = pm.kind == PatchMotion::Kind::Fixed, slip = pm.kind == PatchMotion::Kind::Slip;
    for (std::size_t k = 0; k < patch->points.size(); ++k) {
      const std::uint32_t p = patch->points[k];
      const Vec3 dp = fixed || slip ? Vec3::Zero() : (given.empty() ? pm.displacement(mesh.points[p]) : given[k]);
      if (!dp.allFinite())
        throw FileError(pm.where + ": the displacement of point " + std::to_string(number(p)) + " is not finite");
      if (who[p] < 0) {
        who[p] = std::int32_t(m);
        d[p] = dp;
        continue;
      }
      const PatchMotion& other = motion.patches[std::size_t(who[p])];
      const bool other_fixed = other.kind == PatchMotion::Kind::Fixed;
      // Slip yields to every other kind: a point on a slip patch's edge with a fixed or moving
      // patch is that patch's.
      if (slip) continue;
      if (other.kind == PatchMotion::Kind::Slip) {
        who[p] = std::int32_t(m);
        d[p] = dp;
        continue;
      }
      if (fixed) continue;  // a moving patch's point moves
      if (other_fixed) {
        who[p] = std::int32_t(m);
        d[p] = dp;
        continue;
      }
      if ((d[p] - dp).norm() > tol)
        throw FileError(motion.file + ": point " + std::to_string(number(p)) + " " + show(mesh.points[p]) +
                        " is on patch '" + other.patch + "', which moves it by " + show(d[p]) + ", and on patch '" +
                        pm.patch + "', which moves it by " + show(dp) +
                        ": give the two patches the same motion at their shared points");
    }
  }
  for (std::size_t p = 0; p < np; ++p) {
    if (who[p] < 0) continue;
    out.points.push_back(std::uint32_t(p));
    out.displacements.push_back(d[p]);
    out.fixed.push_back(motion.patches[std::size_t(who[p])].kind == PatchMotion::Kind::Fixed);
    out.slip.push_back(motion.patches[std::size_t(who[p])].kind == PatchMotion::Kind::Slip ? who[p] : -1);
  }
  return out;
}
MorphResult morph(const VolumeMesh& mesh, const Motion& motion_in, const MorphOptions& options, MorphBackend* backend) {
  return detail::Morpher(mesh, options, backend ? *backend : local_backend()).run(motion_in);
}

double largest_displacement(const VolumeMesh& mesh, const Motion& motion_in) {
  MorphBackend& b = local_backend();
  const auto flat = detail::flat_axis(mesh);
  const std::vector<detail::PatchPlane> planes = detail::patch_planes(mesh, b);
  std::vector<PatchReport> reports;
  const Motion motion =
      detail::resolve_patches(mesh, motion_in, planes, detail::mesh_size(mesh), flat.has_value(), reports);
  const Prescribed pres = prescribe(mesh, motion);
  double largest = 0;
  for (const Vec3& d : pres.displacements) largest = std::max(largest, d.norm());
  return largest;
}

double largest_safe_phase(const VolumeMesh& mesh, std::span<const Vec3> moved, double phase,
                          std::size_t inverted_before) {
  std::vector<Vec3> at(mesh.points.size());
  QualityMeter meter(mesh);
  const auto ok = [&](double s) {
    const double w = s / phase;
    for (std::size_t i = 0; i < at.size(); ++i) at[i] = mesh.points[i] + w * (moved[i] - mesh.points[i]);
    return meter.measure(at).inverted_cells() <= inverted_before;
  };
  double lo = 0, hi = phase;
  while (hi - lo > 1e-4 * std::abs(phase)) {
    const double mid = 0.5 * (lo + hi);
    (ok(mid) ? lo : hi) = mid;
  }
  return lo;
}

}  // namespace csrbf::morph
