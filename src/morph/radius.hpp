// `csrbf morph --radius auto` and the prediction of a fit's size and time (private to csrbf::morph).
#pragma once

#include "csrbf/morph/morph.hpp"

#include <span>
#include <string>
#include <vector>

namespace csrbf::morph::detail {

/// Points sorted (lexicographically) and unique: every process's controls, gathered, in an order
/// that does not depend on how the mesh was decomposed (a processor boundary's point once).
std::vector<Vec3> sorted_unique(std::vector<Vec3> v);

/// The median distance from a moving control to its nearest other control, over a seeded sample
/// of at most 512 moving controls: the boundary's spacing. 0 where there are not two controls.
double boundary_spacing(std::span<const Vec3> controls, std::span<const Vec3> moving);

/// The controls a fit of radius R takes (polynomial none): the moving ones and the staying ones
/// within R of a moving one; with a polynomial, all.
std::vector<Vec3> fitted_controls(std::span<const Vec3> moving, std::span<const Vec3> staying, double radius,
                                  bool local);

struct RadiusChoice {
  double radius = 0;
  std::string why;
};

/// R for a motion whose largest displacement (as applied) is `displacement`: kDisplacementFactor
/// times it, at least kSpacingFactor times the boundary's spacing, at most the mesh's size, and
/// smaller where the fit's predicted memory would pass `budget` bytes or each control would have
/// more than kMostNeighbours neighbours (bisection on the prediction). moving, staying: sorted_unique.
inline constexpr double kDisplacementFactor = 20.0;
inline constexpr double kSpacingFactor = 4.0;
inline constexpr double kMostNeighbours = 400.0;
/// The share of the memory left to the fit that auto's R may predict (the evaluation's grid and
/// the solver's work space take the rest).
inline constexpr double kAutoMemoryShare = 0.5;
/// two_levels: the fit may take two levels (MorphOptions::levels, radius.hpp's plan): R is then
/// reduced only where the two levels' memory or neighbours pass those limits too.
RadiusChoice choose_radius(std::span<const Vec3> moving, std::span<const Vec3> staying, double displacement,
                           double size, double budget, bool local, bool two_levels = false);

/// The controls no two of which are closer than `spacing`, each taken where it is farther than that
/// from those taken before it, in order: indices, ascending.
std::vector<std::uint32_t> spaced_subset(std::span<const Vec3> sources, double spacing);

/// What a fit of `controls` (sorted_unique, every process's) at radius R and the evaluation of
/// `points` (this process's) will need: neighbours per control (a sample) and per point (a seeded
/// sample of at most 512 points), the fit's memory (estimate_fit_memory) and the times of
/// kSecondsPerEntry, kSecondsPerTerm and kSecondsPerPoint (measured on 2 cores: docs/morphing.md).
/// total_points: every process's.
inline constexpr double kSecondsPerEntry =
    2.2e-7;  ///< a fit, per non-zero of A (its factorisation or CG, three right-hand sides)
inline constexpr double kSecondsPerTerm = 5e-10;    ///< an evaluation, per kernel term of a point
inline constexpr double kSecondsPerPoint = 1.5e-7;  ///< an evaluation, per point (its grid cell, its copy)
/// The two-level fit (MorphOptions::levels): the coarse level fits the controls no two of which are
/// closer than kCoarseSpacing x R, at R; the fine level fits what the coarse one leaves at every
/// control, at kFineRadius x the boundary's spacing (at most the coarse spacing). Levels auto takes
/// two where the coarse spacing is at least twice the boundary's spacing and the plain fit would
/// pass its memory budget, or is predicted to take kTwoLevelSeconds or more and kTwoLevelGain times
/// the two levels' predicted time. At one R one level gives the better cells (windAroundBuildings
/// at R = 15: 47.91 degrees against 49.03), so auto keeps it wherever it is affordable.
inline constexpr double kCoarseSpacing = 0.25;
inline constexpr double kFineRadius = 1.75;
inline constexpr double kTwoLevelSeconds = 10.0;
inline constexpr double kTwoLevelGain = 4.0;
struct TwoLevelPlan {
  std::vector<std::uint32_t> coarse;  ///< the coarse level's controls (indices, ascending)
  double spacing = 0, fine_radius = 0, boundary_spacing = 0;
  double seconds_plain = 0, seconds_two = 0;  ///< predicted fits (kSecondsPerEntry)
  bool plain_too_large = false;               ///< one level's predicted memory passes the budget
  bool worth_it = false;                      ///< what levels auto takes
};
/// The plan for controls `sources` (moving: target != source) at radius R, within `budget` bytes;
/// neighbours, bytes: the plain fit's mean neighbours per control and memory where already
/// predicted (neighbours < 0: estimated here). The fine level's neighbours are counted around the
/// moving controls of the boundary's spacing's sample.
TwoLevelPlan plan_two_levels(std::span<const Vec3> sources, std::span<const Vec3> targets, double radius, double budget,
                             double neighbours = -1, double bytes = 0);
/// flat_axis >= 0: a 2-D mesh, whose points are evaluated at `mid` along that axis.
MorphPrediction predict(std::span<const Vec3> controls, std::span<const Vec3> points, int flat_axis, double mid,
                        double radius, double total_points, MorphBackend& b);

}  // namespace csrbf::morph::detail
