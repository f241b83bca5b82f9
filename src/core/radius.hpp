// Radii from the points' own spacing, one module for the core's choosers: suggest_radius
// (estimate.cpp) and the interpolator's radius="auto" and multiscale levels (interpolator.cpp).
// (csrbf morph's radius, src/morph/radius.cpp, is chosen from the displacement and the boundary's
// spacing instead, and builds its own.)
#pragma once

#include "csrbf/types.hpp"

#include <numbers>
#include <span>

namespace csrbf::detail {

/// The volume of the unit ball in dim = 1, 2 or 3 dimensions.
inline double unit_ball(int dim) { return dim == 1 ? 2.0 : dim == 2 ? std::numbers::pi : 4.0 / 3.0 * std::numbers::pi; }

/// The radius within which a point of pts has `neighbors` others on average (strictly within: the
/// radius is just past the distance that counts), measured in the first dim coordinates.
double neighbour_radius(std::span<const Vec3> pts, int dim, double neighbors);

}  // namespace csrbf::detail
