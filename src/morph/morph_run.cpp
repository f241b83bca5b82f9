// morph()'s phases around the fit (see morph_phases.hpp): the options checked, each patch's kind
// and its points prescribed, the report begun, the slip correction, the evaluation and placement.
#include "morph_phases.hpp"
#include "csrbf/units.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/morph/progress.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace csrbf::morph::detail {
namespace {

using io::FileError;
}  // namespace

double mesh_size(const VolumeMesh& mesh) {
  if (mesh.points.empty()) return 0;
  Vec3 lo = mesh.points[0], hi = lo;
  for (const Vec3& p : mesh.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).norm();
}

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

Morpher::Morpher(const VolumeMesh& mesh, const MorphOptions& options, MorphBackend& backend)
    : mesh_(mesh),
      options_(options),
      b(backend),
      process_bytes_(options.fit.memory_limit_bytes + io::resident_bytes()),
      rep(r_.report) {}

MorphResult Morpher::run(const Motion& motion_in) {
  check_options();
  resolve(motion_in);
  if (!start_report()) return r_;  // nothing moves
  check_flat_parts();
  tol_ = 1e-12 * std::max(size_, 1e-300);
  any_slip_ = b.max(double(rep.slip)) > 0;  // (every process, in this order)
  const auto t_fit = Clock::now();
  b.balance(mesh_.points);
  slip_surfaces();
  std::unique_ptr<FittedMapping> map =
      fit_controls([&](std::uint32_t i) { return pres_.slip[i] < 0; }, pres_.displacements, rep.max_displacement);
  std::vector<Vec3> first_d;  // the first mapping's displacements, where a correction follows
  std::unique_ptr<FittedMapping> correction;
  if (any_slip_) correction = slip_correction(map, first_d);
  if (!correction) rep.fit = map->stats();
  rep.seconds_fit = seconds_since(t_fit);
  const auto t_eval = Clock::now();
  evaluate_and_place(correction ? *correction : *map, correction.get(), first_d);
  rep.seconds_evaluate = seconds_since(t_eval);
  return std::move(r_);
}

void Morpher::check_options() const {
  const MorphOptions& options = options_;
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
}

// Every patch's kind: the motion's entries matched by name, group or expression, and defaults
// for the boundaries it leaves unlisted (slip where planar, fixed otherwise).
void Morpher::resolve(const Motion& motion_in) {
  const VolumeMesh& mesh = mesh_;
  flat_ = flat_axis(mesh);
  planes_ = patch_planes(mesh, b);
  size_ = b.max(mesh_size(mesh));
  std::vector<PatchReport> patch_reports;
  b.agree(
      caught([&] { motion_ = resolve_patches(mesh, motion_in, planes_, size_, flat_.has_value(), patch_reports); }));
  b.agree(caught([&] { pres_ = prescribe(mesh, motion_, b.part()); }));
  if (b.part()) {
    for (std::size_t m = 0; m < motion_.patches.size(); ++m) {
      const PatchMotion& pm = motion_.patches[m];
      if (b.max(double(mesh.patch(pm.patch)->points.size())) == 0 && !pm.by_default)
        throw FileError(pm.where + ": patch '" + pm.patch + "' has no points");
      if (pm.kind != PatchMotion::Kind::Displacements) continue;
      // Each line of a displacements file must move a point of the patch in some part.
      std::vector<double> used(pres_.used[m].begin(), pres_.used[m].end());
      b.max(std::span<double>(used));
      for (std::size_t gi = 0; gi < used.size(); ++gi)
        if (used[gi] == 0)
          throw FileError(pm.at(pm.given[gi]) + "point " + std::to_string(pm.given[gi].point) +
                          " is not a point of patch '" + pm.patch +
                          "' in any part of the mesh (out of range, or on another patch)");
    }
  }
  rep.patches = patch_reports;
}

bool Morpher::start_report() {
  const MorphOptions& options = options_;
  rep.prescribed = pres_.points.size();
  rep.moving = pres_.moving();
  rep.fixed = std::size_t(std::count(pres_.fixed.begin(), pres_.fixed.end(), char(1)));
  rep.slip = std::size_t(std::count_if(pres_.slip.begin(), pres_.slip.end(), [](std::int32_t s) { return s >= 0; }));
  r_.points = mesh_.points;
  fit_ = options.fit;
  // Two levels may be taken (MorphOptions::levels): not with a polynomial (it moves the whole space),
  // greedy (it chooses its own controls), or a backend that holds one mapping (mpirun).
  two_levels_possible_ =
      options.levels != 1 && fit_.polynomial == Polynomial::None && options.greedy == 0 && b.keeps_mappings();
  rep.radius = options.radius_auto ? 0.0 : fit_.radius;
  rep.radius_why = options.radius_auto ? "nothing moves" : "given";
  n_ = pres_.points.size();
  for (const Vec3& dv : pres_.displacements) rep.max_displacement = std::max(rep.max_displacement, dv.norm());
  rep.max_displacement = b.max(rep.max_displacement);
  return !(b.max(double(rep.moving)) == 0 || rep.max_displacement == 0 || options.phase == 0);
}

void Morpher::check_flat_parts() const {
  if (!b.part()) return;
  // Every part with points must see the same 2-D axis, or none.
  const double mine = mesh_.points.empty() ? -1.0 : flat_ ? double(flat_->axis + 1) : 0.0;
  const double hi = b.max(mine), lo = -b.max(mine < 0 ? -1e9 : -mine);
  if (hi != lo)
    throw FileError(motion_.file +
                    ": the parts of the mesh disagree about being 2-D (an 'empty' patch with "
                    "faces in some parts, not in others): decompose the case again");
}

void Morpher::note(const std::string& line) const {
  if (options_.progress) options_.progress->note(line);
}

// Slip: the fit of the moving and fixed points gives each slip point its displacement, whose part
// off its patch's surface (the normal part on a plane; to the surface's closest point on a
// curved one) is then taken back by a second fit of those corrections (the other prescribed
// points held at 0), added to the first: the patch's points stay on its surface and the cells
// beside it follow. A plane containing the motion (the sides of an extruded 2-D mesh) needs no
// correction and no second fit.
void Morpher::slip_surfaces() {
  plane_of_.assign(motion_.patches.size(), nullptr);
  surfaces_.resize(motion_.patches.size());
  if (!any_slip_) return;
  b.agree(caught([&] {
    for (std::size_t e = 0; e < motion_.patches.size(); ++e) {
      if (motion_.patches[e].kind != PatchMotion::Kind::Slip) continue;
      const Patch* patch = mesh_.patch(motion_.patches[e].patch);
      const PatchPlane& plane = planes_[std::size_t(patch - mesh_.patches.data())];
      if (plane.deviation <= kPlanarTolerance * size_)
        plane_of_[e] = &plane;
      else if (!patch->points.empty())
        surfaces_[e].emplace(mesh_, *patch, motion_.patches[e].where);
    }
  }));
}

std::span<const Vec3> Morpher::evaluated_at() {
  if (!flat_) return mesh_.points;
  if (projected_points_.empty()) {
    projected_points_ = mesh_.points;
    for (Vec3& p : projected_points_) p[flat_->axis] = 0.5 * (flat_->lo + flat_->hi);
  }
  return projected_points_;
}

namespace {

/// The displacement kept within every plane of the point: the plane's, the line two planes share,
/// or none where three meet (parallel planes count once).
Vec3 within_planes(Vec3 d, const std::vector<Vec3>& ns) {
  std::vector<Vec3> basis;  // orthonormal, spanning the normals
  for (Vec3 v : ns) {
    for (const Vec3& u : basis) v -= v.dot(u) * u;
    if (v.norm() > 1e-6) basis.push_back(v.normalized());
  }
  for (const Vec3& u : basis) d -= d.dot(u) * u;
  return basis.size() >= 3 ? Vec3::Zero() : d;
}

}  // namespace

std::unique_ptr<FittedMapping> Morpher::slip_correction(std::unique_ptr<FittedMapping>& map,
                                                        std::vector<Vec3>& first_d) {
  const VolumeMesh& mesh = mesh_;
  Prescribed& pres = pres_;
  const auto& flat = flat_;
  std::vector<Vec3> at_slip, d_slip;
  std::vector<std::uint32_t> which;
  for (std::uint32_t i = 0; i < n_; ++i) {
    if (pres.slip[i] < 0) continue;
    Vec3 p = mesh.points[pres.points[i]];
    if (flat) p[flat->axis] = 0.5 * (flat->lo + flat->hi);
    at_slip.push_back(p);
    which.push_back(i);
  }
  d_slip.resize(at_slip.size());
  map->displacements(at_slip, d_slip);
  // A point on two or more slip patches (an edge, a corner) stays on each: the planes' normals.
  std::vector<std::vector<Vec3>> normals(n_);
  for (std::size_t e = 0; e < motion_.patches.size(); ++e) {
    const PatchPlane* plane = plane_of_[e];
    if (!plane) continue;
    for (const auto p : mesh.patch(motion_.patches[e].patch)->points) {
      const auto it = std::lower_bound(pres.points.begin(), pres.points.end(), p);
      if (it != pres.points.end() && *it == p && pres.slip[std::size_t(it - pres.points.begin())] >= 0)
        normals[std::size_t(it - pres.points.begin())].push_back(plane->normal);
    }
  }
  std::vector<Vec3> corrections(n_, Vec3::Zero());
  double largest = 0;
  for (std::size_t k = 0; k < which.size(); ++k) {
    const std::uint32_t i = which[k];
    const std::size_t e = std::size_t(pres.slip[i]);
    Vec3 d = d_slip[k];
    if (d != Vec3::Zero()) {  // beyond the reach: exactly still
      d = within_planes(d, normals[i]);
      if (surfaces_[e]) {
        const Vec3& x = mesh.points[pres.points[i]];
        d = surfaces_[e]->project(x + d) - x;
      }
    }
    if (flat) d[flat->axis] = 0;
    pres.displacements[i] = d;
    corrections[i] = d - d_slip[k];
    if (flat) corrections[i][flat->axis] = 0;
    largest = std::max(largest, corrections[i].norm());
  }
  // Corrections below 1e-9 of the mesh's size move no cell: they are left to the exact placement.
  const double small = 1e-9 * size_;
  for (Vec3& c : corrections)
    if (c.norm() <= small) c = Vec3::Zero();
  if (!(b.max(largest) > small)) return nullptr;
  // The first mapping is evaluated before the second fit (a backend may hold one mapping).
  first_d.resize(mesh.points.size());
  map->displacements(evaluated_at(), first_d);
  rep.fit = map->stats();  // the first fit's figures (the motion's own); the correction's are smaller
  map.reset();
  const std::size_t first_controls = rep.controls;
  const double first_error = rep.max_boundary_error;
  correcting_ = true;
  std::unique_ptr<FittedMapping> correction =
      fit_controls([](std::uint32_t) { return true; }, corrections, b.max(largest));
  rep.controls += first_controls;
  rep.max_boundary_error = std::max(rep.max_boundary_error, first_error);
  return correction;
}

// In this process the points are evaluated in slices, which the progress counts; a backend that
// spreads them over processes takes them whole (its calls are collective).
void Morpher::evaluate_and_place(FittedMapping& map, FittedMapping* correction, const std::vector<Vec3>& first_d) {
  const VolumeMesh& mesh = mesh_;
  const Prescribed& pres = pres_;
  const auto& flat = flat_;
  const double phase = options_.phase;
  std::vector<Vec3>& points = r_.points;
  ProgressPhase evaluating(options_.progress, "evaluate", double(mesh.points.size()), rep.predicted.seconds_evaluate);
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
      points[i] = mesh.points[i] + phase * d;
      if (flat) points[i][flat->axis] = mesh.points[i][flat->axis];
    }
  } else if (flat) {
    // The displacement at each point's projection: the two planes' points move alike, and never
    // out of their planes (every control's displacement is 0 along the axis).
    std::vector<Vec3> d(mesh.points.size());
    displacements_of(map, evaluated_at(), d);
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (d[i] == Vec3::Zero()) continue;  // kept bit for bit (-0 stays -0)
      points[i] = mesh.points[i] + phase * d[i];
      points[i][flat->axis] = mesh.points[i][flat->axis];
    }
  } else if (here(&map)) {
    const std::span<const Vec3> in = mesh.points;
    const std::span<Vec3> out = points;
    const std::size_t step = std::max<std::size_t>(std::size_t(1) << 16, in.size() / 50);
    for (std::size_t s = 0; s < in.size(); s += step) {
      const std::size_t k = std::min(step, in.size() - s);
      map.apply(in.subspan(s, k), out.subspan(s, k), phase);
      evaluating.advance(double(s + k));
    }
  } else {
    map.apply(mesh.points, points, phase);
  }
  for (std::size_t i = 0; i < n_; ++i) {
    const std::uint32_t p = pres.points[i];
    points[p] = pres.fixed[i] || pres.displacements[i] == Vec3::Zero()
                    ? mesh.points[p]
                    : Vec3(mesh.points[p] + phase * pres.displacements[i]);
    if (pres.slip[i] >= 0 && pres.displacements[i] != Vec3::Zero()) {
      const auto& surface = surfaces_[std::size_t(pres.slip[i])];
      if (surface) points[p] = surface->project(points[p]);
    }
  }
}

}  // namespace csrbf::morph::detail
