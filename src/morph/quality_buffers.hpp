// The buffers of the polyhedral quality measure, kept by QualityMeter between calls (private to
// csrbf::morph): a 1e7-point mesh's pass allocates about a gigabyte, and the first touch of fresh
// pages cost as much as the measure.
#pragma once

#include "csrbf/morph/quality.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace csrbf::morph::detail {

struct PolyBuffers {
  std::vector<Vec3> fc, fa, cc;
  std::vector<double> vol;
  std::vector<double> reference_volumes;  ///< QualityMeter's first measure's, for volume ratios
  std::vector<char> inverted;
  std::vector<std::uint64_t> first;  ///< the cell-to-face index: the topology's, built once
  std::vector<std::uint32_t> faces_of;
  /// The cell determinant's faces besides internal ones: coupled patches' [begin, end) (cyclic,
  /// processor), and the axis a 2-D mesh's empty patches face (-1: 3-D).
  std::vector<std::pair<std::uint64_t, std::uint64_t>> coupled;
  int empty_axis = -1;
};

PolyQuality poly_quality(const PolyTopology& t, std::span<const Vec3> points, PolyBuffers& b);

}  // namespace csrbf::morph::detail
