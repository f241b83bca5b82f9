// The morph of a volume mesh by its boundaries: the points of the patches the motion names are
// the controls (each moves as its patch prescribes, or stays), a CSRBF space mapping fitted to
// them carries every other point along, and the prescribed points land exactly where prescribed.
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/fit_stats.hpp"
#include "csrbf/morph/backend.hpp"
#include "csrbf/morph/motion.hpp"
#include "csrbf/morph/progress.hpp"
#include "csrbf/morph/quality.hpp"
#include "csrbf/morph/volume_mesh.hpp"

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace csrbf::morph {

/// Every point a motion prescribes: its id and displacement, and whether it stays (fixed).
struct Prescribed {
  std::vector<std::uint32_t> points;  ///< ascending
  std::vector<Vec3> displacements;
  std::vector<char> fixed;
  /// The motion entry of a slip point (its displacement is the mapping's, projected onto the
  /// patch's surface, set by morph), or -1.
  std::vector<std::int32_t> slip;
  /// A part of a decomposed mesh: for each motion patch with a displacements file, which of its
  /// lines this part used (the others are other parts' points, or wrong).
  std::vector<std::vector<char>> used;
  /// Points that move: not fixed, not slip, with a non-zero displacement.
  std::size_t moving() const;
};

/// Resolves the motion's patches against the mesh. A point on a moving patch and a fixed one
/// moves; two moving patches that disagree at a shared point (by more than 1e-12 of the mesh's
/// size) are an error naming both and the point. Unknown and empty patches, point ids outside the
/// patch, and patch points missing from a displacements file are errors. Throws io::FileError.
/// part: the mesh is one part of a decomposed mesh (MorphBackend::part): a patch may be empty here,
/// and a displacements file's points that are not on this part's patch are another part's.
Prescribed prescribe(const VolumeMesh& mesh, const Motion& motion, bool part = false);

struct MorphOptions {
  FitOptions fit;      ///< radius > 0 required; kernel, polynomial, solver, memory limit
  double phase = 1.0;  ///< the fraction of the motion applied, in [0, 1] normally
  /// > 0: greedy reduction (Rendall & Allen 2009): controls are added, worst first, until every
  /// prescribed point is interpolated within greedy x the largest displacement.
  double greedy = 0.0;
  /// Greedy never loses: its rounds may take this fraction of the time the fit of every control and
  /// its evaluation are predicted to take (the prediction refined by each round's measured cost per
  /// matrix entry); past it, greedy stops and every control is fitted, so the whole morph takes at
  /// most about 1 + greedy_budget times the plain one. Infinity: greedy runs until it meets its
  /// tolerance.
  double greedy_budget = 0.2;
  /// ... and at least this many seconds (a morph of a few milliseconds is not worth stopping).
  double greedy_budget_floor = 0.1;
  /// The fit's levels: 1, the plain fit of every control at R; 2, two levels (multilevel
  /// interpolation after Floater & Iske 1996): a coarse fit at R of the controls no two of which are
  /// closer than R / 4, then a fine fit at about 1.75 x the boundary's spacing of what the coarse one
  /// leaves at every control. Both are exact at the controls and sum no term farther than R from a
  /// control (the reach stays 2R); two levels cost a fraction of a plain fit at a large R, and the
  /// cells beside the boundary take the fine level's shorter wavelength. 0 (auto): two levels where
  /// one level would pass its memory budget, or is predicted to take 10 s or more and 4 times the
  /// two levels' time (radius.hpp; MorphReport::levels_why says which). Two levels
  /// need polynomial none, no greedy, and a backend that keeps two mappings (one process).
  int levels = 0;
  /// `--radius auto`: fit.radius is ignored, and R is chosen from the motion's largest displacement
  /// (as applied), the boundary's spacing and fit.memory_limit_bytes (MorphReport::radius_why).
  bool radius_auto = false;
  /// radius_auto: the displacement its rule takes in place of this motion's largest (a series of
  /// motions: the series' largest, so that every time has one R and one matrix). 0: the motion's.
  double auto_displacement = 0;
  /// Told of the radius chosen, the prediction, and each phase's progress (null: nothing).
  Progress* progress = nullptr;
};

/// What a fit and its evaluation will need, predicted before either starts: neighbours (other
/// controls within R) per control and controls within R per mesh point, from seeded samples; the
/// fit's memory (its neighbour graph, matrix and factor) and times (a model of this machine's
/// cost per matrix entry and per kernel term; docs/morphing.md gives its measured accuracy).
struct MorphPrediction {
  double neighbours_per_control = 0, neighbours_per_point = 0;
  double bytes = 0, seconds_fit = 0, seconds_evaluate = 0;
};

/// What one patch of the mesh did: its kind ("moving", "fixed", "slip" or "free") and why
/// ("listed", "listed as 'wall.*'", "group 'wall'", "type symmetryPlane", "planar", "curved", ...).
struct PatchReport {
  std::string name, kind, why;
};

struct MorphReport {
  /// moving: prescribed points with a non-zero displacement (a fixed one, or one that a motion
  /// moves by 0, does not count); slip: points kept on their patch's surface (moved or not).
  std::size_t prescribed = 0, moving = 0, fixed = 0, slip = 0;
  std::vector<PatchReport> patches;  ///< every patch of the mesh
  std::size_t controls = 0;          ///< sources of the fit (all prescribed points, or greedy's subset)
  std::size_t greedy_rounds = 0;
  /// Where greedy stopped before its tolerance and every control was fitted instead: why (its
  /// budget and what it had spent); empty otherwise.
  std::string greedy_stopped;
  double max_displacement = 0;  ///< largest prescribed, at phase 1
  /// Largest distance between a prescribed point's interpolated and prescribed position, before
  /// the prescribed points are placed exactly (greedy's measure; ~1e-12 without greedy).
  double max_boundary_error = 0;
  /// Polynomial none: a point this far or farther from every moving control keeps its coordinates
  /// bit for bit (2R: only the staying controls within R of a moving one are fitted); infinity
  /// with a polynomial (the mapping moves the whole space).
  double reach = std::numeric_limits<double>::infinity();
  /// Staying controls left out of the fit: farther than R from every moving control (placed
  /// exactly all the same).
  std::size_t far_fixed = 0;
  FitStats fit;
  double seconds_fit = 0, seconds_evaluate = 0;
  double radius = 0;  ///< the R fitted (chosen, with radius_auto)
  /// The motion's fit: 1 level, or 2 (MorphOptions::levels) with its coarse controls, their spacing
  /// and the fine level's radius; and the two predictions that auto weighed (0 where none was made).
  int levels = 1;
  std::string levels_why;  ///< asked for, or what auto weighed
  std::size_t coarse_controls = 0;
  double coarse_spacing = 0, fine_radius = 0, seconds_plain_predicted = 0, seconds_two_levels_predicted = 0;
  std::string radius_why;  ///< radius_auto: how R was chosen; else "given"
  MorphPrediction predicted;
};

struct MorphResult {
  std::vector<Vec3> points;
  MorphReport report;
};

/// Morphs mesh.points. Prescribed points are placed at x + phase d exactly, fixed ones are copied
/// bit for bit, every other point is x + phase d(x) of the fitted mapping. The backend fits and
/// evaluates (default: SpaceMap in this process; csrbf::mpi's over MPI ranks).
MorphResult morph(const VolumeMesh& mesh, const Motion& motion, const MorphOptions& options,
                  MorphBackend* backend = nullptr);

/// The largest displacement a motion prescribes on mesh (at phase 1), its patches resolved as
/// morph() resolves them. This process alone. Throws io::FileError as morph() does.
double largest_displacement(const VolumeMesh& mesh, const Motion& motion);

/// A backend for a series of morphs of one mesh in this process (a motion a time step): a fit
/// whose sources, radius, kernel, polynomial and solver equal one of the last four fits' (a morph
/// with slip fits twice, and each fit may have two levels) takes that fit's matrix and factorisation and solves for the
/// new displacements alone (SpaceMap::with_destinations): one factorisation, many right-hand sides.
class SeriesBackend final : public MorphBackend {
 public:
  std::unique_ptr<FittedMapping> fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                     const FitOptions& options, std::span<const std::uint64_t> ids) override;
  std::size_t factorisations() const noexcept { return factorisations_; }  ///< fits done whole
  std::size_t reused() const noexcept { return reused_; }                  ///< fits that took a factorisation

 private:
  struct Entry;
  std::vector<std::shared_ptr<Entry>> last_;  // the last four, newest first
  std::size_t factorisations_ = 0, reused_ = 0;
};

/// The largest phase s in [0, phase] at which the morph (positions linear in s between points
/// and moved) inverts no cell that was not inverted before, found by bisection to 1e-4 of phase.
double largest_safe_phase(const VolumeMesh& mesh, std::span<const Vec3> moved, double phase,
                          std::size_t inverted_before);

}  // namespace csrbf::morph
