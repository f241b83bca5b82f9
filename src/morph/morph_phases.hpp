// morph() in phases (morph_run.cpp, morph_fit.cpp): what the phases share, and the mappings they
// build. Private to csrbf_morph.
#pragma once

#include "csrbf/morph/backend.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/space_map.hpp"
#include "patch_kinds.hpp"
#include "radius.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace csrbf::morph::detail {

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

struct Flat {
  int axis;
  double lo, hi;
  std::string patch;
};

/// A 2-D OpenFOAM case (a patch of type empty, every point on one of two planes normal to an
/// axis): the axis and the planes.
std::optional<Flat> flat_axis(const VolumeMesh& mesh);

/// The diagonal of the points' box (0 without points).
double mesh_size(const VolumeMesh& mesh);

/// One morph, phase by phase (see morph() in morph.hpp): check the options; resolve each patch's
/// kind and prescribe its points; gather the controls (a 2-D case's flattened onto its mid-plane);
/// choose R; cull the staying controls no moving one reaches; predict; greedy or every control, in
/// one level or two; the slip correction; evaluate and place.
class Morpher {
 public:
  Morpher(const VolumeMesh& mesh, const MorphOptions& options, MorphBackend& backend);
  MorphResult run(const Motion& motion_in);

 private:
  using Included = std::function<bool(std::uint32_t)>;

  // morph_run.cpp
  void check_options() const;
  void resolve(const Motion& motion_in);
  /// The report's counts; false where nothing moves (the result is the mesh as it is).
  bool start_report();
  void check_flat_parts() const;
  void slip_surfaces();
  /// The slip correction's mapping, or none where no point leaves its surface; first_d: the first
  /// mapping's displacements at every point where one is made (map is released then).
  std::unique_ptr<FittedMapping> slip_correction(std::unique_ptr<FittedMapping>& map, std::vector<Vec3>& first_d);
  /// Where the mapping is evaluated: the points, or in a 2-D case their projections on the mid-plane.
  std::span<const Vec3> evaluated_at();
  void evaluate_and_place(FittedMapping& map, FittedMapping* correction, const std::vector<Vec3>& first_d);
  std::uint64_t number(std::uint32_t p) const {
    return mesh_.point_ids.empty() ? std::uint64_t(p) : mesh_.point_ids[p];
  }
  void note(const std::string& line) const;

  // morph_fit.cpp
  /// The fit of the prescribed points that included selects, displaced by displacements (largest:
  /// the largest of them, every process's).
  std::unique_ptr<FittedMapping> fit_controls(const Included& included, const std::vector<Vec3>& displacements,
                                              double largest);
  void gather_controls(const Included& included, const std::vector<Vec3>& displacements);
  void gather_flat_controls(const Included& included, const std::vector<Vec3>& displacements);
  void choose_radius(double largest);
  void cull_far_controls();
  void predict_fit();
  /// Greedy's rounds; false where it stopped on its budget (every control is fitted then).
  bool greedy(double largest, std::unique_ptr<FittedMapping>& map);
  /// Two levels where asked for or worth it; why: the report's words for the choice.
  std::optional<TwoLevelPlan> plan_levels(std::string& why);
  std::unique_ptr<FittedMapping> fit_two_levels(const TwoLevelPlan& plan, const std::string& why);
  /// The largest distance of a control's image from its target, every process's; err per control.
  double worst(FittedMapping& map);

  const VolumeMesh& mesh_;
  const MorphOptions& options_;
  MorphBackend& b;
  // What this process may hold in all while the fits run: their share and what it holds now. Two
  // levels give each level what is left of it when that level starts (the morph's own arrays and a
  // quality measure running beside it grow meanwhile).
  double process_bytes_ = 0;

  std::optional<Flat> flat_;
  std::vector<PatchPlane> planes_;
  double size_ = 0;
  Motion motion_;
  Prescribed pres_;
  MorphResult r_;
  MorphReport& rep;
  FitOptions fit_;  // its radius chosen here with radius_auto
  bool two_levels_possible_ = false;
  std::size_t n_ = 0;  // prescribed points
  double tol_ = 0;
  bool any_slip_ = false;

  // The controls of the fit being made, and its errors.
  std::vector<Vec3> sources_, targets_;
  std::vector<std::uint64_t> ids_;
  std::vector<double> err_;
  bool first_fit_ = true;
  bool correcting_ = false;  // the second fit, a slip correction's

  // Each slip entry's plane, or (curved) the surface of its faces that its points are projected on.
  std::vector<const PatchPlane*> plane_of_;
  std::vector<std::optional<SurfaceProjector>> surfaces_;
  std::vector<Vec3> projected_points_;
};

}  // namespace csrbf::morph::detail
