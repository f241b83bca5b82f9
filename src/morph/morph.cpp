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
#include "radius.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <exception>
#include <memory>
#include <numeric>
#include <optional>
#include <iomanip>
#include <sstream>
#include <unordered_map>

namespace csrbf::morph {

namespace {

using io::FileError;
using Clock = std::chrono::steady_clock;

class LocalMapping final : public FittedMapping {
 public:
  explicit LocalMapping(SpaceMap map) : map_(std::move(map)) {}
  void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) override { map_.apply(in, out, phase); }
  void displacements(std::span<const Vec3> in, std::span<Vec3> out) override {
    map_.displacements(in.empty() ? nullptr : in.front().data(), out.empty() ? nullptr : out.front().data(), in.size());
  }
  FitStats stats() const override { return map_.stats(); }

 private:
  SpaceMap map_;
};

/// A two-level fit's mapping: the coarse level's displacement plus the fine one's. A point that
/// neither reaches keeps its coordinates bit for bit.
class TwoLevelMapping final : public FittedMapping {
 public:
  TwoLevelMapping(std::unique_ptr<FittedMapping> coarse, std::unique_ptr<FittedMapping> fine)
      : coarse_(std::move(coarse)), fine_(std::move(fine)) {}
  void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) override {
    std::vector<Vec3> d(in.size());
    displacements(in, d);
    for (std::size_t i = 0; i < in.size(); ++i) out[i] = d[i] == Vec3::Zero() ? in[i] : Vec3(in[i] + phase * d[i]);
  }
  void displacements(std::span<const Vec3> in, std::span<Vec3> out) override {
    std::vector<Vec3> fine(in.size());
    coarse_->displacements(in, out);
    fine_->displacements(in, fine);
    for (std::size_t i = 0; i < in.size(); ++i) out[i] += fine[i];
  }
  /// The fine level's: it fits every control.
  FitStats stats() const override { return fine_->stats(); }

 private:
  std::unique_ptr<FittedMapping> coarse_, fine_;
};

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::string show(const Vec3& v) {
  std::ostringstream s;
  s.precision(9);
  s << '[' << v.x() << ", " << v.y() << ", " << v.z() << ']';
  return s.str();
}

double mesh_size(const VolumeMesh& mesh) {
  if (mesh.points.empty()) return 0;
  Vec3 lo = mesh.points[0], hi = lo;
  for (const Vec3& p : mesh.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).norm();
}

std::string patch_list(const VolumeMesh& mesh) {
  std::string s;
  for (const auto& p : mesh.patches) s += (s.empty() ? "" : ", ") + p.name;
  return s.empty() ? "(none)" : s;
}

/// Points added in one greedy round are at least R apart: each one's correction then reaches no
/// other one's neighbourhood, and a round can add many.
class SpacedSet {
 public:
  explicit SpacedSet(double r) : r_(r) {}
  bool try_add(const Vec3& p) {
    const auto cell = key(p);
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(pack(cell[0] + dx, cell[1] + dy, cell[2] + dz));
          if (it == cells_.end()) continue;
          for (const Vec3& q : it->second)
            if ((q - p).squaredNorm() < r_ * r_) return false;
        }
    cells_[pack(cell[0], cell[1], cell[2])].push_back(p);
    return true;
  }

 private:
  std::array<std::int64_t, 3> key(const Vec3& p) const {
    return {std::int64_t(std::floor(p.x() / r_)), std::int64_t(std::floor(p.y() / r_)),
            std::int64_t(std::floor(p.z() / r_))};
  }
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    return (std::uint64_t(x) * 73856093ull) ^ (std::uint64_t(y) * 19349663ull) ^ (std::uint64_t(z) * 83492791ull);
  }
  double r_;
  std::unordered_map<std::uint64_t, std::vector<Vec3>> cells_;
};

struct Flat {
  int axis;
  double lo, hi;
  std::string patch;
};

/// A 2-D OpenFOAM case (a patch of type empty, every point on one of two planes normal to an
/// axis): the axis and the planes.
std::optional<Flat> flat_axis(const VolumeMesh& mesh) {
  const Patch* empty = nullptr;
  for (const Patch& p : mesh.patches)
    if (p.type == "empty") empty = &p;
  if (!empty || mesh.points.empty()) return std::nullopt;
  for (int a = 0; a < 3; ++a) {
    const double first = mesh.points[0][a];
    double second = first;
    bool two = true;
    for (const Vec3& p : mesh.points) {
      const double v = p[a];
      if (v == first || v == second) continue;
      if (second == first) {
        second = v;
        continue;
      }
      two = false;
      break;
    }
    if (two && second != first) return Flat{a, std::min(first, second), std::max(first, second), empty->name};
  }
  return std::nullopt;
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
  const double tol = 1e-12 * std::max(mesh_size(mesh), 1e-300);
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
  MorphBackend& b = backend ? *backend : local_backend();
  // What this process may hold in all while the fits run: their share and what it holds now. Two
  // levels give each level what is left of it when that level starts (the morph's own arrays and a
  // quality measure running beside it grow meanwhile).
  const double process_bytes = options.fit.memory_limit_bytes + io::resident_bytes();
  if (!options.radius_auto && (!(options.fit.radius > 0) || !std::isfinite(options.fit.radius)))
    throw InvalidInput("the radius must be a finite number > 0, got " + io::format_number(options.fit.radius));
  if (!std::isfinite(options.phase)) throw InvalidInput("the phase must be finite");
  if (!(options.greedy >= 0) || !std::isfinite(options.greedy))
    throw InvalidInput("the greedy tolerance must be a finite number >= 0, got " + io::format_number(options.greedy));
  if (options.levels < 0 || options.levels > 2)
    throw InvalidInput("levels must be 0 (auto), 1 or 2, got " + std::to_string(options.levels));
  if (options.levels == 2 && options.fit.polynomial != Polynomial::None)
    throw InvalidInput("two levels need polynomial none (a polynomial moves the whole space; its fit is one level)");
  if (options.levels == 2 && options.greedy > 0)
    throw InvalidInput("two levels and greedy exclude each other (greedy chooses its own controls): give one");
  if (options.levels == 2 && !b.keeps_mappings())
    throw InvalidInput(
        "two levels need one process (under mpirun a later fit replaces the ranks' mapping): "
        "run without mpirun, or with levels 1");
  // Every patch's kind: the motion's entries matched by name, group or expression, and defaults
  // for the boundaries it leaves unlisted (slip where planar, fixed otherwise).
  const auto flat = flat_axis(mesh);
  const std::vector<detail::PatchPlane> planes = detail::patch_planes(mesh, b);
  const double size = b.max(mesh_size(mesh));
  Motion motion;
  std::vector<PatchReport> patch_reports;
  b.agree(caught(
      [&] { motion = detail::resolve_patches(mesh, motion_in, planes, size, flat.has_value(), patch_reports); }));
  Prescribed pres;
  b.agree(caught([&] { pres = prescribe(mesh, motion, b.part()); }));
  if (b.part()) {
    for (std::size_t m = 0; m < motion.patches.size(); ++m) {
      const PatchMotion& pm = motion.patches[m];
      if (b.max(double(mesh.patch(pm.patch)->points.size())) == 0 && !pm.by_default)
        throw FileError(pm.where + ": patch '" + pm.patch + "' has no points");
      if (pm.kind != PatchMotion::Kind::Displacements) continue;
      // Each line of a displacements file must move a point of the patch in some part.
      std::vector<double> used(pres.used[m].begin(), pres.used[m].end());
      b.max(std::span<double>(used));
      for (std::size_t gi = 0; gi < used.size(); ++gi)
        if (used[gi] == 0)
          throw FileError(pm.at(pm.given[gi]) + "point " + std::to_string(pm.given[gi].point) +
                          " is not a point of patch '" + pm.patch +
                          "' in any part of the mesh (out of range, or on another patch)");
    }
  }
  MorphResult r;
  MorphReport& rep = r.report;
  rep.patches = patch_reports;
  rep.prescribed = pres.points.size();
  rep.moving = pres.moving();
  rep.fixed = std::size_t(std::count(pres.fixed.begin(), pres.fixed.end(), char(1)));
  rep.slip = std::size_t(std::count_if(pres.slip.begin(), pres.slip.end(), [](std::int32_t s) { return s >= 0; }));
  r.points = mesh.points;
  FitOptions fit = options.fit;  // its radius chosen here with radius_auto
  // Two levels may be taken (MorphOptions::levels): not with a polynomial (it moves the whole space),
  // greedy (it chooses its own controls), or a backend that holds one mapping (mpirun).
  const bool two_levels_possible =
      options.levels != 1 && fit.polynomial == Polynomial::None && options.greedy == 0 && b.keeps_mappings();
  rep.radius = options.radius_auto ? 0.0 : fit.radius;
  rep.radius_why = options.radius_auto ? "nothing moves" : "given";
  const auto note = [&](const std::string& line) {
    if (options.progress) options.progress->note(line);
  };
  const std::size_t n = pres.points.size();
  for (const Vec3& dv : pres.displacements) rep.max_displacement = std::max(rep.max_displacement, dv.norm());
  rep.max_displacement = b.max(rep.max_displacement);
  if (b.max(double(rep.moving)) == 0 || rep.max_displacement == 0 || options.phase == 0) return r;  // nothing moves

  if (b.part()) {  // every part with points must see the same 2-D axis, or none
    const double mine = mesh.points.empty() ? -1.0 : flat ? double(flat->axis + 1) : 0.0;
    const double hi = b.max(mine), lo = -b.max(mine < 0 ? -1e9 : -mine);
    if (hi != lo)
      throw FileError(motion.file +
                      ": the parts of the mesh disagree about being 2-D (an 'empty' patch with "
                      "faces in some parts, not in others): decompose the case again");
  }
  const double tol = 1e-12 * std::max(size, 1e-300);
  const auto number = [&](std::uint32_t p) { return mesh.point_ids.empty() ? std::uint64_t(p) : mesh.point_ids[p]; };
  // The controls: the prescribed points (those included), or in a 2-D case their projections on
  // the mid-plane, each pair of the two planes' points one control; then the fit.
  std::vector<Vec3> sources, targets;
  std::vector<std::uint64_t> ids;
  std::vector<double> err;
  bool first_fit = true;
  bool correcting = false;                            // the second fit, a slip correction's
  const bool any_slip = b.max(double(rep.slip)) > 0;  // (every process, in this order)
  const auto fit_controls = [&](const auto& included, const std::vector<Vec3>& displacements,
                                double largest) -> std::unique_ptr<FittedMapping> {
    sources.clear();
    targets.clear();
    ids.clear();
    std::unique_ptr<FittedMapping> map;
    b.agree(caught([&] {
      if (flat) {
        const int a = flat->axis;
        const double mid = 0.5 * (flat->lo + flat->hi);
        std::vector<std::uint32_t> order;
        for (std::uint32_t i = 0; i < n; ++i)
          if (included(i)) order.push_back(i);
        const auto projected = [&](std::uint32_t i) {
          Vec3 p = mesh.points[pres.points[i]];
          p[a] = mid;
          return p;
        };
        const auto less = [&](std::uint32_t i, std::uint32_t j) {
          const Vec3 p = projected(i), q = projected(j);
          return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
        };
        std::sort(order.begin(), order.end(), less);
        for (std::size_t k = 0; k < order.size(); ++k) {
          const std::uint32_t i = order[k];
          const Vec3& d = displacements[i];
          if (std::abs(d[a]) > tol)
            throw io::FileError(motion.file + ": the mesh is 2-D (patch '" + flat->patch + "' is empty), but point " +
                                std::to_string(mesh.point_ids.empty() ? std::uint64_t(pres.points[i])
                                                                      : mesh.point_ids[pres.points[i]]) +
                                " moves out of its plane by " + std::to_string(d[a]));
          const Vec3 p = projected(i);
          if (!sources.empty() && sources.back() == p) {
            if ((targets.back() - sources.back() - d).norm() > tol)
              throw io::FileError(motion.file + ": the mesh is 2-D (patch '" + flat->patch +
                                  "' is empty), but points " + std::to_string(pres.points[order[k - 1]]) + " and " +
                                  std::to_string(pres.points[i]) + " of its two planes move differently");
            continue;
          }
          sources.push_back(p);
          targets.push_back(p + d);
          ids.push_back(number(pres.points[i]));
        }
      } else {
        for (std::size_t i = 0; i < n; ++i) {
          if (!included(std::uint32_t(i))) continue;
          sources.push_back(mesh.points[pres.points[i]]);
          targets.push_back(sources.back() + displacements[i]);
          ids.push_back(number(pres.points[i]));
        }
      }
    }));
    if (first_fit && options.radius_auto) {
      // Every process's controls, in one order whatever the decomposition: the same R everywhere.
      std::vector<Vec3> moving_c, staying_c;
      for (std::size_t i = 0; i < sources.size(); ++i)
        (targets[i] != sources[i] ? moving_c : staying_c).push_back(sources[i]);
      moving_c = detail::sorted_unique(b.gather(moving_c));
      staying_c = detail::sorted_unique(b.gather(staying_c));
      const detail::RadiusChoice c = detail::choose_radius(
          moving_c, staying_c,
          std::abs(options.phase) * (options.auto_displacement > 0 ? options.auto_displacement : largest), size,
          detail::kAutoMemoryShare * fit.memory_limit_bytes, fit.polynomial == Polynomial::None, two_levels_possible);
      fit.radius = rep.radius = c.radius;
      rep.radius_why = c.why;
      std::ostringstream os;
      os << "radius auto: R = " << std::setprecision(6) << c.radius << ": " << c.why;
      note(os.str());
    }
    // Exact locality (polynomial none): a control that stays is fitted only where a moving one lies
    // within R of it. Every source of the fit is then within R of a moving control, and its kernel
    // reaches R further: a point 2R or farther from every moving control sums no term and keeps its
    // coordinates bit for bit (the report's reach). Staying controls farther away carried
    // coefficients of 1e-16 and moved the whole connected mesh by up to 4e-7 (a flow solver's
    // residuals jumped 63x on such a mesh); they are placed exactly afterwards, as every prescribed
    // point is. With a polynomial, the mapping moves the whole space: every control is kept.
    if (fit.polynomial == Polynomial::None) {
      rep.reach = 2.0 * fit.radius;
      std::vector<Vec3> moving;
      for (std::size_t i = 0; i < sources.size(); ++i)
        if (targets[i] != sources[i]) moving.push_back(sources[i]);
      const std::vector<Vec3> all_moving = b.gather(moving);
      std::size_t kept = sources.size();
      std::vector<Vec3> dropped;
      if (!all_moving.empty()) {
        kept = 0;
        const NeighborIndex near(all_moving, fit.radius);
        for (std::size_t i = 0; i < sources.size(); ++i) {
          bool keep = targets[i] != sources[i];
          if (!keep) near.for_each_within(sources[i], [&](std::size_t, double) { keep = true; });
          if (!keep) {
            if (b.part()) dropped.push_back(sources[i]);
            continue;
          }
          sources[kept] = sources[i];
          targets[kept] = targets[i];
          ids[kept] = ids[i];
          ++kept;
        }
      }
      if (b.part()) {
        // A point on a processor boundary is a control of each part that holds it: counted once.
        std::vector<Vec3> all = b.gather(dropped);
        const auto less = [](const Vec3& a, const Vec3& c) {
          return std::lexicographical_compare(a.data(), a.data() + 3, c.data(), c.data() + 3);
        };
        std::sort(all.begin(), all.end(), less);
        rep.far_fixed = std::size_t(std::unique(all.begin(), all.end()) - all.begin());
      } else {
        rep.far_fixed = sources.size() - kept;
      }
      sources.resize(kept);
      targets.resize(kept);
      ids.resize(kept);
    }
    const std::size_t nc = sources.size();
    if (first_fit) {
      // The prediction, before anything large is built (the fit checks its memory again).
      const std::vector<Vec3> all_sources = b.part() ? b.gather(sources) : sources;
      rep.predicted =
          detail::predict(all_sources, mesh.points, flat ? flat->axis : -1, flat ? 0.5 * (flat->lo + flat->hi) : 0.0,
                          fit.radius, b.sum(double(mesh.points.size())), b);
      const MorphPrediction& p = rep.predicted;
      std::ostringstream os;
      os.precision(3);
      os << "predicted: " << all_sources.size() << " controls with " << p.neighbours_per_control
         << " neighbours each and " << p.neighbours_per_point << " per point; the fit about " << p.bytes / kGiB
         << " GiB (of " << fit.memory_limit_bytes / kGiB << " GiB left to it) and " << p.seconds_fit
         << " s, the evaluation " << p.seconds_evaluate << " s";
      note(os.str());
      first_fit = false;
    }
    std::vector<Vec3> at(nc);
    const auto worst = [&](FittedMapping& map, std::vector<double>& err) {
      map.apply(sources, at, 1.0);
      err.resize(nc);
      double e = 0;
      for (std::size_t i = 0; i < nc; ++i) e = std::max(e, err[i] = (at[i] - targets[i]).norm());
      return b.max(e);
    };
    // Once greedy stopped in the motion's fit, a slip correction's fit takes every control too: the
    // result is then the plain morph's, and the report's one stop describes it.
    bool fit_all = !(options.greedy > 0 && b.max(double(nc)) > 1) || !rep.greedy_stopped.empty();
    if (!fit_all) {
      ProgressPhase rounds(options.progress, "greedy", 0, 0);  // rounds counted; their number is not known
      const double limit = options.greedy * largest;
      // The budget: a share of the plain morph's predicted fit and evaluation. The fit's share is
      // refined by each round's own cost per matrix entry, once a round fits 1000 controls or more
      // (a small fit is mostly fixed costs).
      const double entries_all = b.sum(double(nc)) * (1 + rep.predicted.neighbours_per_control);
      double fit_all_seconds = rep.predicted.seconds_fit;
      double spent = 0;
      std::size_t rounds_here = 0;  // this fit's (a slip correction's greedy counts its own)
      std::vector<char> chosen(nc, 0);
      std::vector<std::uint32_t> subset;
      std::size_t first = 0;
      for (std::size_t i = 1; i < nc; ++i)
        if ((targets[i] - sources[i]).squaredNorm() > (targets[first] - sources[first]).squaredNorm()) first = i;
      if (nc > 0) {
        subset.push_back(std::uint32_t(first));
        chosen[first] = 1;
      }
      std::vector<std::uint32_t> by_error(nc);
      for (;;) {
        ++rep.greedy_rounds;
        ++rounds_here;
        rounds.advance(double(rep.greedy_rounds));
        const auto t_round = Clock::now();
        std::sort(subset.begin(), subset.end());
        std::vector<Vec3> s(subset.size()), t(subset.size());
        std::vector<std::uint64_t> u(subset.size());
        for (std::size_t k = 0; k < subset.size(); ++k) {
          s[k] = sources[subset[k]];
          t[k] = targets[subset[k]];
          u[k] = ids[subset[k]];
        }
        map.reset();
        const auto t_fit_round = Clock::now();
        map = b.fit(s, t, fit, u);
        const double fit_seconds = b.max(seconds_since(t_fit_round));
        rep.max_boundary_error = worst(*map, err);
        if (rep.max_boundary_error <= limit || b.max(double(subset.size() < nc)) == 0) break;
        const FitStats st = map->stats();
        const double entries = double(st.controls) + 2.0 * double(st.neighbor_pairs);
        if (st.controls >= 1000 && entries > 0) fit_all_seconds = fit_seconds / entries * entries_all;
        const double round_seconds = b.max(seconds_since(t_round));
        spent += round_seconds;
        const double budget = std::max(options.greedy_budget * (fit_all_seconds + rep.predicted.seconds_evaluate),
                                       options.greedy_budget_floor);
        // The next round fits more controls: it costs at least this one.
        if (spent + round_seconds > budget) {
          std::ostringstream os;
          os.precision(3);
          os << (correcting ? "in the slip correction's fit, after " : "after ") << rounds_here
             << (rounds_here == 1 ? " round (" : " rounds (") << subset.size() << " controls, error "
             << rep.max_boundary_error / largest << " of the largest displacement against " << options.greedy
             << "), greedy had spent " << spent << " s of its budget of " << budget << " s (" << options.greedy_budget
             << " x the plain fit and evaluation, predicted " << fit_all_seconds << " + "
             << rep.predicted.seconds_evaluate << " s): every control is fitted instead"
             << (correcting ? "" : (any_slip ? " (and in a slip correction's fit, if one follows)" : ""));
          rep.greedy_stopped = os.str();
          fit_all = true;
          break;
        }
        std::iota(by_error.begin(), by_error.end(), 0u);
        std::sort(by_error.begin(), by_error.end(), [&](std::uint32_t a, std::uint32_t b) { return err[a] > err[b]; });
        SpacedSet spaced(fit.radius);
        const std::size_t before = subset.size();
        for (const std::uint32_t i : by_error) {
          if (err[i] <= limit) break;
          if (chosen[i] || !spaced.try_add(sources[i])) continue;
          chosen[i] = 1;
          subset.push_back(i);
        }
        // Only controls themselves miss the tolerance (it is below what the solve reaches): stop.
        if (b.max(double(subset.size() > before)) == 0) break;
      }
      rep.controls = subset.size();
      if (fit_all && options.progress) options.progress->note("greedy stopped " + rep.greedy_stopped);
    }
    if (fit_all) {
      map.reset();
      // Two levels: asked for, or where auto finds them worth it (radius.hpp). Greedy chose its own
      // controls, and a polynomial moves the whole space: one level for those.
      std::optional<detail::TwoLevelPlan> plan;
      std::string why;
      if (two_levels_possible && nc > 0) {
        // The motion's fit was predicted for these very controls; a correction's are others.
        plan = detail::plan_two_levels(sources, targets, fit.radius, detail::kAutoMemoryShare * fit.memory_limit_bytes,
                                       correcting ? -1.0 : rep.predicted.neighbours_per_control,
                                       correcting ? 0.0 : rep.predicted.bytes);
        if (!correcting) {
          rep.seconds_plain_predicted = plan->seconds_plain;
          rep.seconds_two_levels_predicted = plan->seconds_two;
        }
        std::ostringstream os;
        os.precision(3);
        // R / 4 against the boundary's spacing (which the plan finds only below R / 4).
        const auto under_spacing = [&] {
          os << "R / 4 = " << plan->spacing;
          if (plan->boundary_spacing < plan->spacing)
            os << " is under twice the boundary's spacing " << plan->boundary_spacing;
          else
            os << " is under the boundary's spacing";
        };
        if (options.levels == 2) {
          os << "asked for";
          if (plan->spacing < 2 * plan->boundary_spacing || plan->coarse.size() < 3) {
            os << "; ";
            under_spacing();
            os << " and the coarse level has " << plan->coarse.size() << " of the " << nc
               << " controls: the fine level carries the motion, and one level (--levels 1) gives better cells";
          }
        } else if (plan->worth_it && plan->plain_too_large) {
          os << "auto: one level would pass its memory budget (half of what --memory-limit leaves the fit)";
        } else if (plan->worth_it) {
          os << "auto: predicted " << plan->seconds_two << " s against " << plan->seconds_plain << " s in one level";
        } else {
          os << "auto: one level, predicted " << plan->seconds_plain
             << " s (two where one would pass its memory budget, or take " << detail::kTwoLevelSeconds
             << " s or more and " << detail::kTwoLevelGain << " x as long as two";
          if (plan->spacing < 2 * plan->boundary_spacing) {
            os << "; and ";
            under_spacing();
          }
          os << ")";
          plan.reset();
        }
        why = os.str();
      } else {
        why = options.levels == 1                  ? "asked for"
              : fit.polynomial != Polynomial::None ? "one level: a polynomial moves the whole space"
              : options.greedy > 0                 ? "one level: greedy chooses its own controls"
              : !b.keeps_mappings()                ? "one level: under mpirun"
                                                   : "one level";
      }
      if (!correcting) rep.levels_why = why;
      ProgressPhase fitting(options.progress, "fit", 0, plan ? plan->seconds_two : rep.predicted.seconds_fit);
      if (plan) {
        std::vector<Vec3> cs(plan->coarse.size()), ct(cs.size());
        std::vector<std::uint64_t> ci(cs.size());
        for (std::size_t k = 0; k < cs.size(); ++k) {
          cs[k] = sources[plan->coarse[k]];
          ct[k] = targets[plan->coarse[k]];
          ci[k] = ids[plan->coarse[k]];
        }
        // The coarse level is held while the fine one is fitted: the fine fit gets what the coarse
        // one (its matrix, factor and evaluation lists, as resident memory shows them) leaves.
        const double held_before = io::resident_bytes();
        FitOptions coarse_options = fit;
        coarse_options.memory_limit_bytes = std::clamp(process_bytes - held_before, 1.0, fit.memory_limit_bytes);
        std::unique_ptr<FittedMapping> coarse = b.fit(cs, ct, coarse_options, ci);
        // What the coarse level leaves at every control: the fine level's targets.
        std::vector<Vec3> d(nc), fine_targets(nc);
        coarse->displacements(sources, d);
        for (std::size_t i = 0; i < nc; ++i) fine_targets[i] = targets[i] - d[i];
        FitOptions fine = fit;
        fine.radius = plan->fine_radius;
        const double held = io::resident_bytes();
        fine.memory_limit_bytes =
            std::max(std::min(fit.memory_limit_bytes - std::max(held - held_before, 0.0), process_bytes - held), 1.0);
        std::unique_ptr<FittedMapping> f;
        try {
          f = b.fit(sources, fine_targets, fine, ids);
        } catch (const InvalidInput& e) {
          // Its messages name its own R, which the user never gave.
          std::ostringstream os;
          os.precision(6);
          os << "two levels: the fine level's fit at R = " << plan->fine_radius << " (1.75 x the boundary's spacing, "
             << "at most R / 4): " << e.what() << " (--levels 1 fits one level at R = " << fit.radius << ")";
          throw InvalidInput(os.str());
        }
        map = std::make_unique<TwoLevelMapping>(std::move(coarse), std::move(f));
        if (!correcting) {
          rep.levels = 2;
          rep.coarse_controls = cs.size();
          rep.coarse_spacing = plan->spacing;
          rep.fine_radius = plan->fine_radius;
        }
        std::ostringstream os;
        os.precision(3);
        os << (correcting ? "the slip correction's fit" : "the fit") << " in two levels: " << cs.size() << " of " << nc
           << (nc == 1 ? " control" : " controls") << ", no two closer than " << plan->spacing
           << ", at R = " << fit.radius << ", then what they leave at every control at R = " << plan->fine_radius
           << " (1.75 x the boundary's spacing " << plan->boundary_spacing << ")";
        os << " (" << why << ")";
        note(os.str());
      } else {
        map = b.fit(sources, targets, fit, ids);
      }
      rep.max_boundary_error = worst(*map, err);
      rep.controls = nc;
    }
    return map;
  };
  const auto t_fit = Clock::now();
  b.balance(mesh.points);
  // Slip: the fit of the moving and fixed points gives each slip point its displacement, whose part
  // off its patch's surface (the normal part on a plane; to the surface's closest point on a
  // curved one) is then taken back by a second fit of those corrections (the other prescribed
  // points held at 0), added to the first: the patch's points stay on its surface and the cells
  // beside it follow. A plane containing the motion (the sides of an extruded 2-D mesh) needs no
  // correction and no second fit.
  // Each slip entry's plane, or (curved) the surface of its faces that its points are projected on.
  std::vector<const detail::PatchPlane*> plane_of(motion.patches.size(), nullptr);
  std::vector<std::optional<detail::SurfaceProjector>> surfaces(motion.patches.size());
  if (any_slip)
    b.agree(caught([&] {
      for (std::size_t e = 0; e < motion.patches.size(); ++e) {
        if (motion.patches[e].kind != PatchMotion::Kind::Slip) continue;
        const Patch* patch = mesh.patch(motion.patches[e].patch);
        const detail::PatchPlane& plane = planes[std::size_t(patch - mesh.patches.data())];
        if (plane.deviation <= detail::kPlanarTolerance * size)
          plane_of[e] = &plane;
        else if (!patch->points.empty())
          surfaces[e].emplace(mesh, *patch, motion.patches[e].where);
      }
    }));
  std::unique_ptr<FittedMapping> map =
      fit_controls([&](std::uint32_t i) { return pres.slip[i] < 0; }, pres.displacements, rep.max_displacement);
  std::unique_ptr<FittedMapping> correction;
  std::vector<Vec3> first_d;  // the first mapping's displacements, where a correction follows
  std::vector<Vec3> projected_points;
  // Where the mapping is evaluated: the points, or in a 2-D case their projections on the mid-plane.
  const auto evaluated_at = [&]() -> std::span<const Vec3> {
    if (!flat) return mesh.points;
    if (projected_points.empty()) {
      projected_points = mesh.points;
      for (Vec3& p : projected_points) p[flat->axis] = 0.5 * (flat->lo + flat->hi);
    }
    return projected_points;
  };
  if (any_slip) {
    std::vector<Vec3> at_slip, d_slip;
    std::vector<std::uint32_t> which;
    for (std::uint32_t i = 0; i < n; ++i) {
      if (pres.slip[i] < 0) continue;
      Vec3 p = mesh.points[pres.points[i]];
      if (flat) p[flat->axis] = 0.5 * (flat->lo + flat->hi);
      at_slip.push_back(p);
      which.push_back(i);
    }
    d_slip.resize(at_slip.size());
    map->displacements(at_slip, d_slip);
    // A point on two or more slip patches (an edge, a corner) stays on each: the planes' normals.
    std::vector<std::vector<Vec3>> normals(n);
    for (std::size_t e = 0; e < motion.patches.size(); ++e) {
      const detail::PatchPlane* plane = plane_of[e];
      if (!plane) continue;
      for (const auto p : mesh.patch(motion.patches[e].patch)->points) {
        const auto it = std::lower_bound(pres.points.begin(), pres.points.end(), p);
        if (it != pres.points.end() && *it == p && pres.slip[std::size_t(it - pres.points.begin())] >= 0)
          normals[std::size_t(it - pres.points.begin())].push_back(plane->normal);
      }
    }
    // The displacement kept within every plane of the point: the plane's, the line two planes share,
    // or none where three meet (parallel planes count once).
    const auto within_planes = [](Vec3 d, const std::vector<Vec3>& ns) -> Vec3 {
      std::vector<Vec3> basis;  // orthonormal, spanning the normals
      for (Vec3 v : ns) {
        for (const Vec3& u : basis) v -= v.dot(u) * u;
        if (v.norm() > 1e-6) basis.push_back(v.normalized());
      }
      for (const Vec3& u : basis) d -= d.dot(u) * u;
      return basis.size() >= 3 ? Vec3::Zero() : d;
    };
    std::vector<Vec3> corrections(n, Vec3::Zero());
    double largest = 0;
    for (std::size_t k = 0; k < which.size(); ++k) {
      const std::uint32_t i = which[k];
      const std::size_t e = std::size_t(pres.slip[i]);
      Vec3 d = d_slip[k];
      if (d != Vec3::Zero()) {  // beyond the reach: exactly still
        d = within_planes(d, normals[i]);
        if (surfaces[e]) {
          const Vec3& x = mesh.points[pres.points[i]];
          d = surfaces[e]->project(x + d) - x;
        }
      }
      if (flat) d[flat->axis] = 0;
      pres.displacements[i] = d;
      corrections[i] = d - d_slip[k];
      if (flat) corrections[i][flat->axis] = 0;
      largest = std::max(largest, corrections[i].norm());
    }
    // Corrections below 1e-9 of the mesh's size move no cell: they are left to the exact placement.
    const double small = 1e-9 * size;
    for (Vec3& c : corrections)
      if (c.norm() <= small) c = Vec3::Zero();
    if (b.max(largest) > small) {
      // The first mapping is evaluated before the second fit (a backend may hold one mapping).
      first_d.resize(mesh.points.size());
      map->displacements(evaluated_at(), first_d);
      rep.fit = map->stats();  // the first fit's figures (the motion's own); the correction's are smaller
      map.reset();
      const std::size_t first_controls = rep.controls;
      const double first_error = rep.max_boundary_error;
      correcting = true;
      correction = fit_controls([](std::uint32_t) { return true; }, corrections, b.max(largest));
      rep.controls += first_controls;
      rep.max_boundary_error = std::max(rep.max_boundary_error, first_error);
    }
  }
  if (!correction) rep.fit = map->stats();
  rep.seconds_fit = seconds_since(t_fit);

  const auto t_eval = Clock::now();
  // In this process the points are evaluated in slices, which the progress counts; a backend that
  // spreads them over processes takes them whole (its calls are collective).
  ProgressPhase evaluating(options.progress, "evaluate", double(mesh.points.size()), rep.predicted.seconds_evaluate);
  const auto here = [](FittedMapping* m) {
    return dynamic_cast<LocalMapping*>(m) != nullptr || dynamic_cast<TwoLevelMapping*>(m) != nullptr;
  };
  const auto displacements_of = [&](FittedMapping& m, std::span<const Vec3> in, std::span<Vec3> out) {
    const std::size_t step = here(&m) ? std::max<std::size_t>(std::size_t(1) << 16, in.size() / 50) : in.size();
    for (std::size_t s = 0; s < in.size(); s += step) {
      const std::size_t k = std::min(step, in.size() - s);
      m.displacements(in.subspan(s, k), out.subspan(s, k));
      evaluating.advance(double(s + k));
    }
  };
  if (correction) {
    // x + phase (d1 + d2): the first mapping's displacements (kept) and the correction's.
    std::vector<Vec3> c(mesh.points.size());
    displacements_of(*correction, evaluated_at(), c);
    for (std::size_t i = 0; i < c.size(); ++i) {
      const Vec3 d = first_d[i] + c[i];
      if (d == Vec3::Zero()) continue;  // r.points is the mesh's: kept bit for bit (-0 stays -0)
      r.points[i] = mesh.points[i] + options.phase * d;
      if (flat) r.points[i][flat->axis] = mesh.points[i][flat->axis];
    }
  } else if (flat) {
    // The displacement at each point's projection: the two planes' points move alike, and never
    // out of their planes (every control's displacement is 0 along the axis).
    std::vector<Vec3> d(mesh.points.size());
    displacements_of(*map, evaluated_at(), d);
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (d[i] == Vec3::Zero()) continue;  // kept bit for bit (-0 stays -0)
      r.points[i] = mesh.points[i] + options.phase * d[i];
      r.points[i][flat->axis] = mesh.points[i][flat->axis];
    }
  } else if (here(map.get())) {
    const std::span<const Vec3> in = mesh.points;
    const std::span<Vec3> out = r.points;
    const std::size_t step = std::max<std::size_t>(std::size_t(1) << 16, in.size() / 50);
    for (std::size_t s = 0; s < in.size(); s += step) {
      const std::size_t k = std::min(step, in.size() - s);
      map->apply(in.subspan(s, k), out.subspan(s, k), options.phase);
      evaluating.advance(double(s + k));
    }
  } else {
    map->apply(mesh.points, r.points, options.phase);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t p = pres.points[i];
    r.points[p] = pres.fixed[i] || pres.displacements[i] == Vec3::Zero()
                      ? mesh.points[p]
                      : Vec3(mesh.points[p] + options.phase * pres.displacements[i]);
    if (pres.slip[i] >= 0 && pres.displacements[i] != Vec3::Zero()) {
      const auto& surface = surfaces[std::size_t(pres.slip[i])];
      if (surface) r.points[p] = surface->project(r.points[p]);
    }
  }
  rep.seconds_evaluate = seconds_since(t_eval);
  return r;
}

double largest_displacement(const VolumeMesh& mesh, const Motion& motion_in) {
  MorphBackend& b = local_backend();
  const auto flat = flat_axis(mesh);
  const std::vector<detail::PatchPlane> planes = detail::patch_planes(mesh, b);
  std::vector<PatchReport> reports;
  const Motion motion = detail::resolve_patches(mesh, motion_in, planes, mesh_size(mesh), flat.has_value(), reports);
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
