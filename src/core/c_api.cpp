// The C API (csrbf/csrbf.h): csrbf's exceptions turned into status codes at this boundary, strided
// vertex buffers gathered into packed scalars of their type, deformed with their Jacobians, and
// scattered. csrbf/engine.hpp wraps it for C++.
#include "csrbf/csrbf.h"

#include "c_api_detail.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/units.hpp"
#include "csrbf/version.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <utility>
#include <vector>

namespace {

using namespace csrbf;
using csrbf::capi::guarded;
using csrbf::capi::num;

// The allocator for handles and scratch (csrbf_set_allocator); malloc and free by default.
std::atomic<void* (*)(std::size_t)> g_allocate{nullptr};
std::atomic<void (*)(void*)> g_deallocate{nullptr};

void* allocate(std::size_t bytes) {
  const auto f = g_allocate.load();
  void* p = f ? f(bytes) : std::malloc(bytes);
  if (!p) throw std::bad_alloc();
  return p;
}
void deallocate(void* p) noexcept {
  if (!p) return;
  const auto f = g_deallocate.load();
  if (f)
    f(p);
  else
    std::free(p);
}

/// A std::allocator over allocate()/deallocate() (the scratch of csrbf_deform).
template <class T>
struct HookAllocator {
  using value_type = T;
  HookAllocator() noexcept = default;
  template <class U>
  HookAllocator(const HookAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) { return static_cast<T*>(::allocate(n * sizeof(T))); }
  void deallocate(T* p, std::size_t) noexcept { ::deallocate(p); }
  template <class U>
  bool operator==(const HookAllocator<U>&) const noexcept {
    return true;
  }
};

constexpr std::size_t kNoNormal = CSRBF_NO_NORMAL;

std::vector<Vec3> points(const double* xyz, std::size_t n, const char* what) {
  if (n > 0 && !xyz) throw InvalidInput(std::string(what) + " is null for " + std::to_string(n) + " controls");
  std::vector<Vec3> p(n);
  for (std::size_t i = 0; i < n; ++i) p[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  return p;
}

void check_layout(const csrbf_vertex_buffer& b, const char* name) {
  const std::size_t scalar = b.scalar == CSRBF_FLOAT64 ? 8 : 4;
  if (b.scalar != CSRBF_FLOAT32 && b.scalar != CSRBF_FLOAT64)
    throw InvalidInput(std::string(name) + ".scalar is " + std::to_string(int(b.scalar)) + ", not Float32 or Float64");
  if (b.count == 0) return;
  if (!b.base) throw InvalidInput(std::string(name) + ".base is null for " + std::to_string(b.count) + " vertices");
  const auto fits = [&](std::size_t offset, const char* field) {
    if (offset > b.stride || b.stride - offset < 3 * scalar)
      throw InvalidInput(std::string(name) + "." + field + " is " + std::to_string(offset) +
                         ": three scalars there do not fit in a stride of " + std::to_string(b.stride) + " bytes");
    if (offset % scalar != 0 || b.stride % scalar != 0 || reinterpret_cast<std::uintptr_t>(b.base) % scalar != 0)
      throw InvalidInput(std::string(name) + "." + field + ", its stride or base is not aligned to " +
                         std::to_string(scalar) + "-byte scalars");
  };
  // The last vertex's last scalar must be addressable: (count - 1) * stride + offset + 3 scalars
  // within the address space (a stride near SIZE_MAX wrapped around before the buffer).
  // First the first vertex's own end (base + offset + 3 scalars, which an offset near SIZE_MAX
  // wraps), then the count.
  const std::size_t last_offset = std::max(b.position_offset, b.normal_offset == kNoNormal ? 0 : b.normal_offset);
  const std::uintptr_t top = std::numeric_limits<std::uintptr_t>::max(),
                       base = reinterpret_cast<std::uintptr_t>(b.base);
  if (last_offset > top - 3 * scalar || base > top - (last_offset + 3 * scalar))
    throw InvalidInput(std::string(name) + ": an offset of " + std::to_string(last_offset) + " bytes from " + name +
                       ".base passes the end of the address space");
  if (b.stride != 0 && (b.count - 1 > (top - last_offset - 3 * scalar - base) / b.stride))
    throw InvalidInput(std::string(name) + ": " + std::to_string(b.count) + " vertices of " + std::to_string(b.stride) +
                       " bytes from " + name + ".base pass the end of the address space");
  fits(b.position_offset, "position_offset");
  if (b.normal_offset != kNoNormal) {
    fits(b.normal_offset, "normal_offset");
    const std::size_t gap =
        b.position_offset > b.normal_offset ? b.position_offset - b.normal_offset : b.normal_offset - b.position_offset;
    if (gap < 3 * scalar)
      throw InvalidInput(std::string(name) + ".position_offset " + std::to_string(b.position_offset) + " and " + name +
                         ".normal_offset " + std::to_string(b.normal_offset) + " overlap (three " +
                         std::to_string(scalar) + "-byte scalars each)");
  }
}

template <class T>
T* at(const csrbf_vertex_buffer& b, std::size_t i, std::size_t offset) {
  return reinterpret_cast<T*>(static_cast<unsigned char*>(b.base) + i * b.stride + offset);
}

template <class T>
void deform_as(const SpaceMap* map, const csrbf_vertex_buffer& in, const csrbf_vertex_buffer& out, double phase) {
  const bool normals = in.normal_offset != kNoNormal;
  const std::size_t n = in.count;
  constexpr std::size_t block = 4096;
  // Block by block: each gathered into packed scalars (float in float where the map's float check
  // passes), deformed, and written out, so that in and out may be one buffer and the scratch stays
  // in cache.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, block), [&](const tbb::blocked_range<std::size_t>& r) {
    const std::size_t b = r.begin(), m = r.end() - r.begin();
    std::vector<T, HookAllocator<T>> p(3 * m), nm(normals ? 3 * m : 0);
    for (std::size_t i = 0; i < m; ++i) {
      const T* x = at<T>(in, b + i, in.position_offset);
      for (int c = 0; c < 3; ++c) p[3 * i + std::size_t(c)] = x[c];
      if (normals) {
        const T* v = at<T>(in, b + i, in.normal_offset);
        for (int c = 0; c < 3; ++c) nm[3 * i + std::size_t(c)] = v[c];
      }
    }
    if (map)
      map->apply_with_normals(p.data(), p.data(), m, phase, normals ? nm.data() : nullptr,
                              normals ? nm.data() : nullptr);
    for (std::size_t i = 0; i < m; ++i) {
      T* x = at<T>(out, b + i, out.position_offset);
      for (int c = 0; c < 3; ++c) x[c] = p[3 * i + std::size_t(c)];
      if (normals) {
        T* v = at<T>(out, b + i, out.normal_offset);
        for (int c = 0; c < 3; ++c) v[c] = nm[3 * i + std::size_t(c)];
      }
    }
  });
}

/// A new handle owning map.
csrbf_deformer* make_handle(SpaceMap&& map) {
  auto shared = std::make_shared<const SpaceMap>(std::move(map));
  void* p = allocate(sizeof(csrbf_deformer));
  auto* h = new (p) csrbf_deformer;
  h->map = std::move(shared);
  return h;
}

}  // namespace

extern "C" {

void csrbf_settings_default(csrbf_settings* settings) {
  if (!settings) return;
  settings->radius = 0.0;
  settings->kernel = CSRBF_KERNEL_C2;
  settings->polynomial = CSRBF_POLYNOMIAL_NONE;
  settings->memory_limit_gib = 4.0;
}

csrbf_status csrbf_fit(const double* sources, const double* destinations, size_t n, const csrbf_settings* settings,
                       csrbf_deformer** out, csrbf_result* result) {
  return guarded(result, [&] {
    if (!settings) throw InvalidInput("settings is null");
    if (!out) throw InvalidInput("out is null");
    // The controls' two copies (sources and destinations as points), before they are allocated; the
    // fit then predicts its own memory.
    if (settings->memory_limit_gib > 0 && double(n) * 2 * sizeof(Vec3) > settings->memory_limit_gib * kGiB)
      throw ResourceLimit(std::to_string(n) + " controls take " + num(double(n) * 2 * sizeof(Vec3) / kGiB) +
                          " GiB as points, above the memory limit of " + num(settings->memory_limit_gib) + " GiB");
    const auto s = points(sources, n, "sources");
    const auto d = points(destinations, n, "destinations");
    FitOptions o;
    o.radius = settings->radius;
    switch (settings->kernel) {
      case CSRBF_KERNEL_C0:
        o.kernel = csrbf::Kernel::C0;
        break;
      case CSRBF_KERNEL_C2:
        o.kernel = csrbf::Kernel::C2;
        break;
      case CSRBF_KERNEL_C4:
        o.kernel = csrbf::Kernel::C4;
        break;
      case CSRBF_KERNEL_C6:
        o.kernel = csrbf::Kernel::C6;
        break;
      default:
        throw InvalidInput("settings.kernel is " + std::to_string(settings->kernel) + ", not C0, C2, C4 or C6");
    }
    switch (settings->polynomial) {
      case CSRBF_POLYNOMIAL_NONE:
        o.polynomial = csrbf::Polynomial::None;
        break;
      case CSRBF_POLYNOMIAL_CONSTANT:
        o.polynomial = csrbf::Polynomial::Constant;
        break;
      case CSRBF_POLYNOMIAL_LINEAR:
        o.polynomial = csrbf::Polynomial::Linear;
        break;
      default:
        throw InvalidInput("settings.polynomial is " + std::to_string(settings->polynomial) +
                           ", not None, Constant or Linear");
    }
    if (!(settings->memory_limit_gib > 0) || !(settings->memory_limit_gib <= 1e6))
      throw InvalidInput("settings.memory_limit_gib must be in (0, 1e6], got " + num(settings->memory_limit_gib));
    o.memory_limit_bytes = settings->memory_limit_gib * csrbf::kGiB;
    *out = make_handle(SpaceMap::fit(s, d, o));
  });
}

csrbf_status csrbf_refit(const csrbf_deformer* deformer, const double* destinations, csrbf_deformer** out,
                         csrbf_result* result) {
  return guarded(result, [&] {
    if (!deformer) throw InvalidInput("refit: the deformer is null (this Deformer has not been fitted)");
    if (!out) throw InvalidInput("out is null");
    const auto d = points(destinations, deformer->map->size(), "destinations");
    *out = make_handle(deformer->map->with_destinations(d));
  });
}

csrbf_status csrbf_deform(const csrbf_deformer* deformer, const csrbf_vertex_buffer* in_buffer,
                          const csrbf_vertex_buffer* out_buffer, double phase, csrbf_result* result) {
  return guarded(result, [&] {
    if (!in_buffer || !out_buffer) throw InvalidInput(!in_buffer ? "in is null" : "out is null");
    const csrbf_vertex_buffer& in = *in_buffer;
    const csrbf_vertex_buffer& out = *out_buffer;
    check_layout(in, "in");
    check_layout(out, "out");
    if (in.count != out.count)
      throw InvalidInput("in.count is " + std::to_string(in.count) + " but out.count is " + std::to_string(out.count));
    if (in.scalar != out.scalar) throw InvalidInput("in.scalar and out.scalar differ");
    // One buffer read and written in parallel blocks: only where each vertex stays in its own
    // bytes (the same base and stride), else a block would overwrite vertices another still reads.
    const auto span_of = [](const csrbf_vertex_buffer& b) {
      const auto lo = reinterpret_cast<std::uintptr_t>(b.base);
      return std::pair{lo, b.count == 0 ? lo : lo + (b.count - 1) * b.stride + b.stride};
    };
    const auto [in_lo, in_hi] = span_of(in);
    const auto [out_lo, out_hi] = span_of(out);
    if (in.count > 0 && in_lo < out_hi && out_lo < in_hi && (in.base != out.base || in.stride != out.stride))
      throw InvalidInput("in and out overlap in memory with another base or stride (in.stride " +
                         std::to_string(in.stride) + ", out.stride " + std::to_string(out.stride) +
                         "): deform in place with one layout, or into a separate buffer");
    if ((in.normal_offset == kNoNormal) != (out.normal_offset == kNoNormal))
      throw InvalidInput(in.normal_offset == kNoNormal ? "out has normals but in has none"
                                                       : "in has normals but out has none");
    if (!std::isfinite(phase) || std::abs(phase) > 1e6)
      throw InvalidInput("phase must be a finite number within [-1e6, 1e6], got " + num(phase));
    const SpaceMap* map = deformer ? deformer->map.get() : nullptr;
    if (in.scalar == CSRBF_FLOAT64)
      deform_as<double>(map, in, out, phase);
    else
      deform_as<float>(map, in, out, phase);
  });
}

size_t csrbf_size(const csrbf_deformer* deformer) { return deformer ? deformer->map->size() : 0; }

csrbf_deformer* csrbf_share(const csrbf_deformer* deformer) {
  if (!deformer) return nullptr;
  auto* h = const_cast<csrbf_deformer*>(deformer);
  h->owners.fetch_add(1, std::memory_order_relaxed);
  return h;
}

void csrbf_destroy(csrbf_deformer* deformer) {
  if (!deformer || deformer->owners.fetch_sub(1, std::memory_order_acq_rel) != 1) return;
  deformer->~csrbf_deformer();
  deallocate(deformer);
}

void csrbf_set_allocator(void* (*allocate_fn)(size_t), void (*deallocate_fn)(void*)) {
  g_allocate.store(allocate_fn);
  g_deallocate.store(deallocate_fn);
}

const char* csrbf_version(void) { return csrbf::kVersion; }

}  // extern "C"
