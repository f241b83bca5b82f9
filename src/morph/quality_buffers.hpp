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
  /// Each face's non-orthogonality cosine (internal faces) and skewness; each cell's determinant
  /// and bad face pyramids: the last measure's, which a later one updates where points moved.
  std::vector<double> cosine, skew, det;
  std::vector<std::uint32_t> bad;
  /// QualityMeter: the points that differed from the mesh's at the last measure, whose faces and
  /// cells hold figures of those points (recomputed at the next measure whether or not they move).
  /// Empty until a whole measure of the mesh's number of points has filled the arrays above.
  std::vector<char> touched;
  std::vector<std::uint64_t> first;  ///< the cell-to-face index: the topology's, built once
  std::vector<std::uint32_t> faces_of;
  /// The cell determinant's faces besides internal ones: coupled patches' [begin, end) (cyclic,
  /// processor), and the axis a 2-D mesh's empty patches face (-1: 3-D).
  std::vector<std::pair<std::uint64_t, std::uint64_t>> coupled;
  int empty_axis = -1;
};

/// What a measure recomputes: the faces with a moved point, and their cells (whose faces' non-
/// orthogonality and skewness are then recomputed too). Everything else keeps the figures in the
/// buffers, which must then be those of the same points there.
struct Dirty {
  std::vector<char> face, cell;
};

/// dirty: nullptr measures everything.
PolyQuality poly_quality(const PolyTopology& t, std::span<const Vec3> points, PolyBuffers& b,
                         const Dirty* dirty = nullptr);

}  // namespace csrbf::morph::detail
