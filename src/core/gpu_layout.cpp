// The GPU layout of csrbf.h (csrbf_gpu_size, csrbf_gpu_fill, csrbf_gpu_update): the textures that
// web/csrbf_deformation.glsl reads, computed as csrbf_deformation.js computes them from an exported
// CSRBF_deformation file, number for number, so that a texture filled here equals the module's
// texel for texel: sources and coefficients rounded to float as the exporter stores them, then
// times the weight and rounded again; the neighbour grid in double over those float sources. This
// file is compiled without floating-point contraction (src/core/CMakeLists.txt): JavaScript rounds
// every product.
#include "c_api_detail.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

namespace {

using namespace csrbf;
using csrbf::capi::guarded;
using csrbf::capi::num;

static_assert(sizeof(int) == 4, "the layout's integer textures are 32-bit ints");

constexpr std::size_t kWidth = CSRBF_GPU_WIDTH;
constexpr double kMaxCells = double(1 << 18);
constexpr std::size_t kMaxIndex = std::size_t(1) << 24;  // the shader's indices are floats

std::size_t rows(std::size_t count) { return std::max<std::size_t>(1, (count + kWidth - 1) / kWidth); }

/// One deformation's neighbour grid: cells of side h >= R over its float sources' box grown by R,
/// each listing the sources within R of it (csrbf_deformation.js's neighbourGrid).
struct Grid {
  double origin[3] = {0, 0, 0}, h = 0;
  std::size_t dims[3] = {1, 1, 1};
  std::vector<int> first, count, list;
  std::size_t cells() const { return dims[0] * dims[1] * dims[2]; }
};

std::vector<double> float_sources(const SpaceMap& map) {
  std::vector<double> s(3 * map.size());
  for (std::size_t i = 0; i < map.size(); ++i)
    for (int k = 0; k < 3; ++k) s[3 * i + std::size_t(k)] = double(float(map.sources()[i][k]));
  return s;
}

Grid grid_of(const std::vector<double>& s, double radius) {
  const std::size_t n = s.size() / 3;
  double lo[3], hi[3], extent[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::numeric_limits<double>::infinity();
    hi[k] = -lo[k];
  }
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], s[3 * i + std::size_t(k)]);
      hi[k] = std::max(hi[k], s[3 * i + std::size_t(k)]);
    }
  Grid g;
  for (int k = 0; k < 3; ++k) {
    g.origin[k] = lo[k] - radius;
    extent[k] = hi[k] + radius - g.origin[k];
  }
  g.h = radius;
  const auto size_dims = [&] {
    double product = 1;
    for (int k = 0; k < 3; ++k) {
      const double d = std::max(1.0, std::ceil(extent[k] / g.h));
      product *= d;
      g.dims[k] = product > kMaxCells ? 0 : std::size_t(d);
    }
    return product;
  };
  while (size_dims() > kMaxCells) g.h *= 1.25;
  const std::size_t cells = g.cells();
  g.count.assign(cells, 0);
  const double reach = radius * radius * (1 + 1e-6);
  const auto visit = [&](std::size_t i, auto&& add) {
    const double* p = &s[3 * i];
    std::size_t a[3], b[3];
    for (int k = 0; k < 3; ++k) {
      a[k] = std::size_t(std::max(0.0, std::floor((p[k] - radius - g.origin[k]) / g.h)));
      b[k] = std::size_t(std::min(double(g.dims[k] - 1), std::floor((p[k] + radius - g.origin[k]) / g.h)));
    }
    for (std::size_t z = a[2]; z <= b[2]; ++z)
      for (std::size_t y = a[1]; y <= b[1]; ++y)
        for (std::size_t x = a[0]; x <= b[0]; ++x) {
          // The distance from the source to the cell's box, against R (a little wider: rounding).
          const std::size_t c[3] = {x, y, z};
          double d2 = 0;
          for (int k = 0; k < 3; ++k) {
            const double l = g.origin[k] + double(c[k]) * g.h, u = l + g.h;
            const double e = p[k] < l ? l - p[k] : p[k] > u ? p[k] - u : 0;
            d2 += e * e;
          }
          if (d2 <= reach) add(x + g.dims[0] * (y + g.dims[1] * z));
        }
  };
  for (std::size_t i = 0; i < n; ++i) visit(i, [&](std::size_t c) { ++g.count[c]; });
  g.first.assign(cells + 1, 0);
  for (std::size_t c = 0; c < cells; ++c) g.first[c + 1] = g.first[c] + g.count[c];
  g.list.assign(std::size_t(g.first[cells]), 0);
  std::vector<int> at(g.first.begin(), g.first.end() - 1);
  for (std::size_t i = 0; i < n; ++i) visit(i, [&](std::size_t c) { g.list[std::size_t(at[c]++)] = int(i); });
  return g;
}

/// The deformations checked, in the layout's order (by stage, stably).
std::vector<std::size_t> order_of(const csrbf_gpu_deformation* d, std::size_t count) {
  if (count > 0 && !d) throw InvalidInput("deformations is null for " + std::to_string(count) + " deformations");
  if (count > kMaxIndex / 8)
    throw InvalidInput(std::to_string(count) + " deformations: the layout holds at most 2^21 (8 texels each)");
  for (std::size_t j = 0; j < count; ++j) {
    const std::string at = "deformations[" + std::to_string(j) + "]";
    if (!d[j].deformer) throw InvalidInput(at + ".deformer is null");
    if (d[j].deformer->map->size() == 0) throw InvalidInput(at + ".deformer has no controls");
    if (d[j].stage < 0) throw InvalidInput(at + ".stage is " + std::to_string(d[j].stage) + ", not >= 0");
    if (!std::isfinite(d[j].weight) || std::abs(d[j].weight) > 1e6)
      throw InvalidInput(at + ".weight must be a finite number within [-1e6, 1e6], got " + num(d[j].weight));
  }
  std::vector<std::size_t> order(count);
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return d[a].stage < d[b].stage; });
  return order;
}

/// The deformations' grids in the layout's order and where each one's sources, cells and list
/// start (csrbf_deformation.js's firstSource, firstCell, firstListed), built once a call.
struct Plan {
  struct Slot {
    std::size_t deformation = 0, first_source = 0, first_cell = 0, first_listed = 0;
    Grid grid;
  };
  std::vector<Slot> slots;
  std::size_t sources = 0, cells = 0, listed = 0;  // in all
};

Plan plan_of(const csrbf_gpu_deformation* d, const std::vector<std::size_t>& order) {
  Plan p;
  for (const std::size_t j : order) {
    const SpaceMap& map = *d[j].deformer->map;
    p.slots.push_back({j, p.sources, p.cells, p.listed, grid_of(float_sources(map), map.radius())});
    const Grid& g = p.slots.back().grid;
    p.sources += map.size();
    p.cells += g.cells();
    p.listed += g.list.size();
    if (p.cells > kMaxIndex || p.sources > kMaxIndex)
      throw InvalidInput(std::to_string(p.sources) + " sources and " + std::to_string(p.cells) +
                         " cells so far: the layout's float indices hold at most 2^24 of each");
  }
  return p;
}

/// The rows of every texture for `count` deformations of `sources` sources; cells and list rows
/// from plan where given (csrbf_gpu_update needs only the weighted textures').
csrbf_gpu_layout rows_of(std::size_t count, std::size_t sources, const Plan* plan) {
  csrbf_gpu_layout l{};
  l.sources_rows = l.coefficients_rows = rows(sources);
  l.deformations_rows = rows(8 * count);
  l.cells_rows = rows(plan ? plan->cells : 0);
  l.list_rows = rows(plan ? plan->listed : 0);
  l.groups_rows = rows(0);
  return l;
}

void check_rows(const csrbf_gpu_layout& l, const csrbf_gpu_layout& want, bool all) {
  const auto check = [](const void* p, std::size_t got, std::size_t need, const char* name) {
    if (!p) throw InvalidInput(std::string("layout.") + name + " is null");
    if (got != need)
      throw InvalidInput(std::string("layout.") + name + "_rows is " + std::to_string(got) +
                         " where csrbf_gpu_size gives " + std::to_string(need) + " for these deformations");
  };
  check(l.coefficients, l.coefficients_rows, want.coefficients_rows, "coefficients");
  check(l.deformations, l.deformations_rows, want.deformations_rows, "deformations");
  if (!all) return;
  check(l.sources, l.sources_rows, want.sources_rows, "sources");
  check(l.cells, l.cells_rows, want.cells_rows, "cells");
  check(l.list, l.list_rows, want.list_rows, "list");
  check(l.groups, l.groups_rows, want.groups_rows, "groups");
}

/// A frame's part: coefficients and texels 3..6, float(weight x float(value)) as the module sums
/// its one term (a weight of 0: zeros, and texel 3's w 0).
void fill_weighted(const csrbf_gpu_deformation* d, const std::vector<std::size_t>& order, csrbf_gpu_layout& l) {
  std::fill_n(l.coefficients, 4 * kWidth * l.coefficients_rows, 0.0f);
  std::size_t first = 0;
  for (std::size_t slot = 0; slot < order.size(); ++slot) {
    const csrbf_gpu_deformation& g = d[order[slot]];
    const SpaceMap& map = *g.deformer->map;
    float* poly = l.deformations + 32 * slot + 12;
    std::fill_n(poly, 16, 0.0f);
    if (g.weight != 0) {
      const double w = g.weight;
      for (std::size_t i = 0; i < map.size(); ++i)
        for (int k = 0; k < 3; ++k)
          l.coefficients[4 * (first + i) + std::size_t(k)] =
              float(w * double(float(map.coefficients()(Eigen::Index(i), k))));
      if (map.polynomial() != Polynomial::None) {
        const Eigen::Matrix<double, 4, 3> pc = map.polynomial_coefficients();
        for (int r = 0; r < 4; ++r)
          for (int k = 0; k < 3; ++k) poly[4 * r + k] = float(w * double(float(pc(r, k))));
      }
      poly[3] = 1.0f;
    }
    first += map.size();
  }
}

}  // namespace

extern "C" {

csrbf_status csrbf_gpu_size(const csrbf_gpu_deformation* deformations, size_t count, csrbf_gpu_layout* layout,
                            csrbf_result* result) {
  return guarded(result, [&] {
    if (!layout) throw InvalidInput("layout is null");
    const auto order = order_of(deformations, count);
    const Plan plan = plan_of(deformations, order);
    const csrbf_gpu_layout r = rows_of(count, plan.sources, &plan);
    layout->sources_rows = r.sources_rows;
    layout->coefficients_rows = r.coefficients_rows;
    layout->deformations_rows = r.deformations_rows;
    layout->cells_rows = r.cells_rows;
    layout->list_rows = r.list_rows;
    layout->groups_rows = r.groups_rows;
  });
}

csrbf_status csrbf_gpu_fill(const csrbf_gpu_deformation* deformations, size_t count, csrbf_gpu_layout* layout,
                            csrbf_result* result) {
  return guarded(result, [&] {
    if (!layout) throw InvalidInput("layout is null");
    csrbf_gpu_layout& l = *layout;
    const auto order = order_of(deformations, count);
    const Plan plan = plan_of(deformations, order);
    check_rows(l, rows_of(count, plan.sources, &plan), true);
    std::fill_n(l.sources, 4 * kWidth * l.sources_rows, 0.0f);
    std::fill_n(l.deformations, 4 * kWidth * l.deformations_rows, 0.0f);
    std::fill_n(l.cells, 2 * kWidth * l.cells_rows, 0);
    std::fill_n(l.list, kWidth * l.list_rows, 0);
    std::fill_n(l.groups, kWidth * l.groups_rows, 0);
    for (std::size_t slot = 0; slot < plan.slots.size(); ++slot) {
      const Plan::Slot& at = plan.slots[slot];
      const SpaceMap& map = *deformations[at.deformation].deformer->map;
      const Grid& g = at.grid;
      for (std::size_t i = 0; i < map.size(); ++i)
        for (int k = 0; k < 3; ++k) l.sources[4 * (at.first_source + i) + std::size_t(k)] = float(map.sources()[i][k]);
      for (std::size_t c = 0; c < g.cells(); ++c) {
        l.cells[2 * (at.first_cell + c)] = int(at.first_listed) + g.first[c];
        l.cells[2 * (at.first_cell + c) + 1] = g.count[c];
      }
      for (std::size_t k = 0; k < g.list.size(); ++k) l.list[at.first_listed + k] = int(at.first_source) + g.list[k];
      const float head[12] = {float(map.radius()),
                              float(kernel_smoothness(map.kernel())),
                              float(deformations[at.deformation].stage),
                              -1.0f,
                              float(g.origin[0]),
                              float(g.origin[1]),
                              float(g.origin[2]),
                              float(1 / g.h),
                              float(g.dims[0]),
                              float(g.dims[1]),
                              float(g.dims[2]),
                              float(at.first_cell)};
      std::copy_n(head, 12, l.deformations + 32 * slot);
    }
    fill_weighted(deformations, order, l);
  });
}

csrbf_status csrbf_gpu_update(const csrbf_gpu_deformation* deformations, size_t count, csrbf_gpu_layout* layout,
                              csrbf_result* result) {
  return guarded(result, [&] {
    if (!layout) throw InvalidInput("layout is null");
    const auto order = order_of(deformations, count);
    std::size_t sources = 0;
    for (const std::size_t j : order) sources += deformations[j].deformer->map->size();
    check_rows(*layout, rows_of(count, sources, nullptr), false);
    fill_weighted(deformations, order, *layout);
  });
}

}  // extern "C"
