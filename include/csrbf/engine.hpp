// csrbf for game engines and other code built without exceptions (-fno-exceptions): a deformer that
// is fitted once and then deforms vertex buffers as engines keep them, positions and normals
// interleaved in one buffer at any stride, float or double. Nothing here throws: every call returns a
// Result (a status and a message), and this header includes csrbf.h and the standard library only.
//
//   csrbf::engine::Deformer d;
//   csrbf::engine::Settings s;
//   s.radius = 0.3;
//   if (auto r = csrbf::engine::Deformer::fit(sources, destinations, n, s, d); !r) log(r.message);
//   csrbf::engine::VertexBuffer vb{vertices, count, sizeof(Vertex), offsetof(Vertex, pos),
//                                  offsetof(Vertex, normal), csrbf::engine::Scalar::Float32};
//   d.deform(rest, vb, phase);   // rest and vb may be the same buffer
//
// Normals are taken through the map exactly, n' = J^-T n with J = dT/dx at the vertex (scaled to
// the length n had), not blended. Float buffers are deformed in float where the map's float check
// passes (normals within 1e-5 rad of double's for the smooth kernels C2-C6), else in double.
//
// Header-only over the C API (csrbf/csrbf.h), whose functions csrbf::core exports: the types below
// have the C structs' layouts, and a Deformer owns a csrbf_deformer handle (copies share it).
#pragma once

#include "csrbf/csrbf.h"

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <utility>

namespace csrbf::engine {

/// What a call did: Ok, or what kind of failure (the message says which argument or control, and
/// the value).
enum class Status : int {
  Ok = 0,
  InvalidInput = 1,          ///< an argument, a layout or a control is not valid
  DuplicateSource = 2,       ///< two controls share a source
  DegeneratePolynomial = 3,  ///< the sources do not determine the polynomial asked for
  IllConditioned = 4,        ///< the controls are too close together for the radius
  NotPositiveDefinite = 5,   ///< the solver failed
  ResourceLimit = 6,         ///< the fit would pass its memory limit (said before allocating)
  OutOfMemory = 7,           ///< an allocation failed
  Internal = 8,              ///< anything else (the message says what)
};

struct Result {
  Status status = Status::Ok;
  char message[CSRBF_MESSAGE_SIZE] = {};  ///< empty on success; otherwise NUL-terminated, in English
  explicit operator bool() const noexcept { return status == Status::Ok; }
};

enum class Kernel : int { C0 = 0, C2 = 2, C4 = 4, C6 = 6 };
enum class Polynomial : int { None = 0, Constant = 1, Linear = 2 };
enum class Scalar : int { Float32 = 0, Float64 = 1 };

struct Settings {
  double radius = 0.0;  ///< radius of support R, in the sources' units (> 0)
  Kernel kernel = Kernel::C2;
  Polynomial polynomial = Polynomial::None;  ///< None: strictly local (far vertices keep their bits)
  double memory_limit_gib = 4.0;             ///< the fit refuses (ResourceLimit) beyond it
};

/// `count` vertices at `base`, each `stride` bytes after the one before; a vertex's position (3
/// scalars) at `position_offset` bytes from its start, its normal at `normal_offset` (kNoNormal: the
/// buffer has none). Scalars in native byte order.
inline constexpr std::size_t kNoNormal = CSRBF_NO_NORMAL;
struct VertexBuffer {
  void* base = nullptr;
  std::size_t count = 0;
  std::size_t stride = 0;
  std::size_t position_offset = 0;
  std::size_t normal_offset = kNoNormal;
  Scalar scalar = Scalar::Float32;
};

/// A fitted deformation T(x) = x + phase d(x). Cheap to copy (copies share the fit); every const
/// member may be called from several threads at once.
class Deformer {
 public:
  Deformer() noexcept = default;
  Deformer(const Deformer& other) noexcept : handle_(csrbf_share(other.handle_)) {}
  Deformer(Deformer&& other) noexcept : handle_(std::exchange(other.handle_, nullptr)) {}
  Deformer& operator=(Deformer other) noexcept {
    std::swap(handle_, other.handle_);
    return *this;
  }
  ~Deformer() { csrbf_destroy(handle_); }

  /// Fits n controls: sources and destinations as n x 3 doubles (x y z, one control after another).
  static Result fit(const double* sources, const double* destinations, std::size_t n, const Settings& settings,
                    Deformer& out) noexcept {
    const csrbf_settings s{settings.radius, int(settings.kernel), int(settings.polynomial), settings.memory_limit_gib};
    csrbf_deformer* h = nullptr;
    csrbf_result r;
    if (csrbf_fit(sources, destinations, n, &s, &h, &r) == CSRBF_OK) out = Deformer(h);
    return result_of(r);
  }
  /// The same sources and settings with new destinations (n x 3, n as fitted): only the solve is
  /// redone (an animation's frame).
  Result refit(const double* destinations, Deformer& out) const noexcept {
    csrbf_deformer* h = nullptr;
    csrbf_result r;
    if (csrbf_refit(handle_, destinations, &h, &r) == CSRBF_OK) out = Deformer(h);
    return result_of(r);
  }

  /// Deforms the vertices of `in` into `out` at `phase` (normally in [0, 1]): positions T(x), normals
  /// J^-T n. in and out have the same count and scalar; they may be the same buffer with one base
  /// and stride (in place; the offsets may differ), or separate buffers of any layout. Buffers that
  /// overlap otherwise are refused (InvalidInput), as is a layout past the end of the address space. Where in has
  /// normals, out must have them too. An unfitted Deformer is the identity.
  Result deform(const VertexBuffer& in, const VertexBuffer& out, double phase = 1.0) const noexcept {
    const csrbf_vertex_buffer i = buffer_of(in), o = buffer_of(out);
    csrbf_result r;
    csrbf_deform(handle_, &i, &o, phase, &r);
    return result_of(r);
  }

  std::size_t size() const noexcept { return csrbf_size(handle_); }  ///< the number of controls (0 before a fit)
  bool fitted() const noexcept { return handle_ != nullptr; }
  /// The C handle (for code that mixes the two APIs); owned by this Deformer.
  const csrbf_deformer* handle() const noexcept { return handle_; }

 private:
  explicit Deformer(csrbf_deformer* handle) noexcept : handle_(handle) {}
  static Result result_of(const csrbf_result& r) noexcept {
    Result out;
    out.status = Status(r.status);
    static_assert(sizeof out.message == sizeof r.message);
    std::memcpy(out.message, r.message, sizeof out.message);
    return out;
  }
  static csrbf_vertex_buffer buffer_of(const VertexBuffer& b) noexcept {
    return {b.base, b.count, b.stride, b.position_offset, b.normal_offset, int(b.scalar)};
  }
  csrbf_deformer* handle_ = nullptr;
  friend Result gpu_size(const csrbf_gpu_deformation*, std::size_t, csrbf_gpu_layout&) noexcept;
  friend Result gpu_fill(const csrbf_gpu_deformation*, std::size_t, csrbf_gpu_layout&) noexcept;
  friend Result gpu_update(const csrbf_gpu_deformation*, std::size_t, csrbf_gpu_layout&) noexcept;
};

/// The GPU layout (csrbf.h): the textures web/csrbf_deformation.glsl reads, for deformations given
/// as {deformer.handle(), weight, stage}, filled as csrbf_deformation.js fills them. gpu_size sets the
/// layout's rows; the caller allocates them (CSRBF_GPU_WIDTH texels a row); gpu_fill writes every
/// texture, gpu_update a new frame's coefficients and polynomials.
using GpuDeformation = csrbf_gpu_deformation;
using GpuLayout = csrbf_gpu_layout;
inline Result gpu_size(const GpuDeformation* deformations, std::size_t count, GpuLayout& layout) noexcept {
  csrbf_result r;
  csrbf_gpu_size(deformations, count, &layout, &r);
  return Deformer::result_of(r);
}
inline Result gpu_fill(const GpuDeformation* deformations, std::size_t count, GpuLayout& layout) noexcept {
  csrbf_result r;
  csrbf_gpu_fill(deformations, count, &layout, &r);
  return Deformer::result_of(r);
}
inline Result gpu_update(const GpuDeformation* deformations, std::size_t count, GpuLayout& layout) noexcept {
  csrbf_result r;
  csrbf_gpu_update(deformations, count, &layout, &r);
  return Deformer::result_of(r);
}

}  // namespace csrbf::engine
