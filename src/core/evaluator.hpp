// The fast evaluation path of SpaceMap (private to csrbf::core).
//
// Space around the sources is cut into a dense grid of cubic cells of side h = R / K (K = 2, or 1
// when the lists below would take too much memory). For every cell the sources closer than R to the
// cell's box are listed once, at fit time, as one run of source indices padded to a multiple of 8
// with an inert source (far away, zero coefficient). On the first evaluation in float or in double,
// the runs are copied out as contiguous structure-of-arrays coordinates and coefficients (EvalData),
// so that evaluating a vertex costs one cell lookup and one branch-free loop over its cell's run:
// portable code the compiler vectorises (with an x86-64-v3 clone, AVX2 + FMA, picked at load time),
// or hand-written AVX-512 (evaluator_avx512.cpp) on CPUs that have it. With K = 2 about 40% of the
// candidates lie within R (the ball's share of the cell grown by R), against 16% for the 27 cells of
// side R that NeighborIndex visits.
//
// SpaceMap::displacement() keeps the simple path through NeighborIndex; tests hold the two together.
#pragma once

#include "csrbf/kernels.hpp"
#include "csrbf/neighbor_index.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

namespace csrbf::detail {

/// The cell lists: depend on the sources and R only.
struct EvalGrid {
  bool usable = false;         // false: lists too large; SpaceMap uses NeighborIndex instead
  int subdivision = 0;         // K: h = R / K
  Vec3 origin = Vec3::Zero();  // lower corner of the grid (sources' box grown by R)
  /// Subtracted from every coordinate before distances are taken: 0 for sources near the origin
  /// (the bits of before), else, per axis, the multiple of the power of two 2^k >= the box's extent
  /// nearest the box's centre, so that x - shift is exact for every x within reach (Sterbenz).
  Vec3 shift = Vec3::Zero();
  double h = 0, inv_h = 0, radius = 0;
  std::int64_t nx = 0, ny = 0, nz = 0;
  std::vector<std::uint32_t> begin;  // begin[cell] .. begin[cell+1]: the cell's entries
  FillVector<std::uint32_t> source;  // source[entry] = input index; N (the inert source) pads
  static constexpr std::size_t kLanes = 8;
  // K = 2, or 1 when memory is short. K = 3 lists 17% fewer candidates a vertex but takes 2.6x the
  // memory, and measured no faster (M = 1e6, N = 1e4).
  static constexpr int kMaxSubdivision = 2;

  /// max_bytes: the most memory the lists and the EvalData copies of both precisions may take;
  /// max_subdivision: the finest K tried (1 for a map evaluated once over few points a source:
  /// SpaceMap::from_solution's points).
  /// dims < 3: the axes from dims on are padding, 0 for every source and every point evaluated
  /// (csrbf::Interpolator's 1-D and 2-D points): each gets one layer of cells around 0, not the
  /// 2K + 1 of a volume (a quarter of the lists for 2-D points); points off it are outside the grid.
  static EvalGrid build(std::span<const Vec3> sources, double radius, std::size_t max_bytes,
                        int max_subdivision = kMaxSubdivision, int dims = 3);
  /// The neighbour graph of the sources (every pair closer than R), from the cell lists: the
  /// candidates of a source are its own cell's run. Requires usable.
  void neighbor_graph(std::span<const Vec3> sources, std::vector<std::size_t>& offsets,
                      FillVector<std::uint32_t>& neighbors, FillVector<double>& dist2,
                      double max_entries = std::numeric_limits<double>::infinity()) const;
  std::size_t bytes() const noexcept { return source.size() * 4 + begin.size() * 4; }
};

/// ResourceLimit where a neighbour graph, counted, has more entries than max_entries (checked before
/// its rows are allocated: the fit's memory check predicts from a sample, which a dense cluster can
/// escape).
void check_graph_entries(double entries, double max_entries, std::size_t n);

/// The leading coefficient of the polynomial factor of phi (4 for C2's 4r + 1), which the evaluation
/// loops fold into the coefficients.
constexpr double phi_lead(Kernel k) noexcept {
  return k == Kernel::C2 ? 4.0 : k == Kernel::C4 ? 35.0 : k == Kernel::C6 ? 32.0 : 1.0;
}

/// An array that is not zeroed when allocated: EvalData writes each entry once, the large ones in
/// parallel, so the pages are first touched by the threads that fill them; large ones on huge pages
/// (FillVector: the six arrays of 1e5 scattered 2-D points took 9000 page faults, 30% of a fit and
/// first evaluation's, at about 18 us each on a virtual machine).
template <class T>
class Buffer {
 public:
  void allocate(std::size_t n) {
    FillVector<T>().swap(data_);
    data_.resize(n);
  }
  T* data() noexcept { return data_.data(); }
  const T* data() const noexcept { return data_.data(); }
  T& operator[](std::size_t i) noexcept { return data_[i]; }
  const T& operator[](std::size_t i) const noexcept { return data_[i]; }
  std::size_t size() const noexcept { return data_.size(); }

 private:
  FillVector<T> data_;
};

/// The runs of EvalGrid copied out: coordinates in units of R relative to the grid's shift (double:
/// exact differences far from 0) or its origin (float: to keep digits) and coefficients alpha, by
/// entry.
/// Padding entries lie far away (r clips to 1, phi(1) = 0) with zero coefficients.
///
/// Large grids (kSortEntries entries or more) also sort each run by the sources' distance from the
/// cell's centre c and keep, for each block of kLanes entries, the least such distance (`reach`, in
/// units of R, rounded down). A point p of the cell needs only the sources closer than
/// R + |p - c| to c (triangle inequality), so the evaluation stops at the first block whose reach
/// is beyond that: about 15% fewer blocks on a surface with cells of side R/2. Small grids skip
/// the sort (it costs more than it saves on one evaluation of a small mesh); they have no reach,
/// and trim() leaves their runs whole.
template <class T>
struct EvalData {
  Buffer<T> x, y, z, ax, ay, az;
  std::vector<float> reach;  // sorted only: per block of kLanes entries, and 8 of padding
  bool sorted = false;
  static constexpr std::size_t kSortEntries = std::size_t(1) << 16;
  /// alpha: N x 3 row-major, the input order of the sources. The coefficients are stored times
  /// phi_lead(kernel), the factor the evaluation loops leave out of phi.
  void assign(const EvalGrid& g, std::span<const Vec3> sources, const double* alpha, Kernel kernel);
  std::size_t bytes() const noexcept { return x.size() * 6 * sizeof(T) + reach.size() * sizeof(float); }
  /// The end of the part of run [b, e) that a point with the given limit (1 + |p - c| / R, rounded
  /// up) needs. Counted without branches on the data, 8 blocks at a time (reach has 8 entries of
  /// padding): a loop that stops at the first block beyond reach mispredicts its exit at nearly
  /// every run.
  std::uint32_t trim(std::uint32_t b, std::uint32_t e, float limit) const noexcept {
    if (!sorted) return e;
    constexpr std::uint32_t L = EvalGrid::kLanes;
    const std::uint32_t blocks = (e - b) / L;
    const float* r = reach.data() + b / L;
    std::uint32_t keep = 0;
    for (std::uint32_t k = 0; k < blocks; k += 8) {
      const std::uint32_t m = blocks - k;
      for (std::uint32_t j = 0; j < 8; ++j) keep += std::uint32_t(j < m) & std::uint32_t(r[k + j] < limit);
    }
    return b + keep * L;
  }
};
extern template struct EvalData<float>;
extern template struct EvalData<double>;

/// out[3i..3i+2] = (add_point ? in + phase * d : d) for the points [begin, end) of in/out (n x 3,
/// interleaved). The polynomial part is added by the caller through poly (may be null).
struct PolynomialPart {
  Vec3 center = Vec3::Zero();
  double inv_scale = 1.0;
  double b[4][3] = {};  // row 0 constant, rows 1..3 linear in u = (x - center) * inv_scale
};

void evaluate(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly, const double* in,
              double* out, std::size_t begin, std::size_t end, double phase, bool add_point);
void evaluate(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly, const float* in,
              float* out, std::size_t begin, std::size_t end, double phase, bool add_point);

/// What evaluate_normals() reads and writes for its points (n x 3 interleaved, n x 9 for jac).
template <class T>
struct NormalsJob {
  const T* in;
  T* out;                         ///< in + phase d(in); may be in
  const T* normals_in = nullptr;  ///< may be null
  T* normals_out = nullptr;       ///< J^-T n, of det J's sign, scaled to |n| (to 1 where unit)
  T* jac = nullptr;               ///< J = dT/dx = I + phase dd/dx, row-major; may be null
  double phase = 1.0;
  bool unit = false;
};
/// The points [begin, end) of job through the cell lists with their Jacobians: the engine API's
/// and VTK's normals (the one-point-a-lane loop of eval_kernel.hpp, in AVX-512 where the CPU has
/// it, else the portable loop with its AVX2 clone).
void evaluate_normals(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly,
                      const NormalsJob<double>& job, std::size_t begin, std::size_t end);
void evaluate_normals(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly,
                      const NormalsJob<float>& job, std::size_t begin, std::size_t end);

/// Points that arrive in an order unrelated to space (a point cloud, a mesh renumbered by another
/// tool) make every point a new cell: the group path never runs and each run is fetched from memory
/// anew. Such batches are gathered by cell first (a counting sort, linear), evaluated, and written
/// back in the caller's order.
/// True when consecutive points mostly lie in different cells, judged from 64 windows of 64 pairs
/// spread over the batch (o(1): a coherent batch pays nothing measurable).
template <class T>
bool incoherent(const EvalGrid& g, const T* in, std::size_t n);
/// The buffers of a batch gathered by cell. The caller keeps them between batches (thread_local):
/// fresh pages for every batch cost more than the sort itself where page faults are slow (virtual
/// machines: 3x the evaluation at M = 1e6 in double).
template <class T>
struct CellOrder {
  FillVector<std::uint32_t> order;  ///< order[k]: the index of the k-th point in cell order
  FillVector<std::uint32_t> cell;
  std::vector<std::uint32_t> start;
  FillVector<T> points;  ///< the points gathered in that order (n x 3), evaluated in place
};
/// Fills o.order for the n points (n x 3) sorted by cell (stable; points outside the grid last).
template <class T>
void order_by_cell(const EvalGrid& g, const T* in, std::size_t n, CellOrder<T>& o);

/// Which loop evaluate() runs: the portable one (with an AVX2 clone) or the AVX-512 one.
enum class EvalIsa { Portable, Avx512 };
/// True when this build has the AVX-512 loop and the CPU runs it.
bool avx512_available() noexcept;
/// Default: Avx512 where available. For tests and benchmarks; Avx512 falls back to Portable where
/// not available.
void set_eval_isa(EvalIsa isa) noexcept;
EvalIsa eval_isa() noexcept;

#ifdef CSRBF_HAVE_AVX512_EVAL
void evaluate_avx512(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly,
                     const double* in, double* out, std::size_t begin, std::size_t end, double phase, bool add_point);
void evaluate_avx512(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly,
                     const float* in, float* out, std::size_t begin, std::size_t end, double phase, bool add_point);
void evaluate_normals_avx512(const EvalGrid& g, const EvalData<double>& a, Kernel kernel, const PolynomialPart* poly,
                             const NormalsJob<double>& job, std::size_t begin, std::size_t end);
void evaluate_normals_avx512(const EvalGrid& g, const EvalData<float>& a, Kernel kernel, const PolynomialPart* poly,
                             const NormalsJob<float>& job, std::size_t begin, std::size_t end);
#endif

}  // namespace csrbf::detail
