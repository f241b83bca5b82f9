// The engine API (csrbf/engine.hpp): csrbf's exceptions turned into status codes at this boundary,
// strided vertex buffers gathered into packed scalars of their type, deformed with their Jacobians,
// and scattered.
#include "csrbf/engine.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/space_map.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>
#include <utility>
#include <string>
#include <vector>

namespace csrbf::engine {
namespace {

Result failure(Status s, const std::string& what) noexcept {
  Result r;
  r.status = s;
  std::snprintf(r.message, sizeof r.message, "%s", what.c_str());
  return r;
}

/// Runs f, turning whatever it throws into a Result.
template <class F>
Result guarded(F&& f) noexcept {
  try {
    f();
    return {};
  } catch (const DuplicateSource& e) {
    return failure(Status::DuplicateSource, e.what());
  } catch (const DegeneratePolynomial& e) {
    return failure(Status::DegeneratePolynomial, e.what());
  } catch (const IllConditioned& e) {
    return failure(Status::IllConditioned, e.what());
  } catch (const InvalidInput& e) {
    return failure(Status::InvalidInput, e.what());
  } catch (const NotPositiveDefinite& e) {
    return failure(Status::NotPositiveDefinite, e.what());
  } catch (const ResourceLimit& e) {
    // The core names its own option; the engine's is Settings::memory_limit_gib.
    return failure(Status::ResourceLimit, std::string(e.what()) + " [here: Settings::memory_limit_gib]");
  } catch (const std::bad_alloc&) {
    return failure(Status::OutOfMemory, "out of memory");
  } catch (const std::exception& e) {
    return failure(Status::Internal, e.what());
  } catch (...) {
    return failure(Status::Internal, "unknown error");
  }
}

/// A number as a message shows it (6 significant digits, not std::to_string's 300-digit %f).
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::vector<Vec3> points(const double* xyz, std::size_t n, const char* what) {
  if (n > 0 && !xyz) throw InvalidInput(std::string(what) + " is null for " + std::to_string(n) + " controls");
  std::vector<Vec3> p(n);
  for (std::size_t i = 0; i < n; ++i) p[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  return p;
}

void check_layout(const VertexBuffer& b, const char* name) {
  const std::size_t scalar = b.scalar == Scalar::Float64 ? 8 : 4;
  if (b.scalar != Scalar::Float32 && b.scalar != Scalar::Float64)
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
  const std::size_t last_offset = std::max(b.position_offset, b.normal_offset == kNoNormal ? 0 : b.normal_offset);
  if (b.stride != 0 && (b.count - 1 > (std::numeric_limits<std::uintptr_t>::max() - last_offset - 3 * scalar -
                                       reinterpret_cast<std::uintptr_t>(b.base)) /
                                          b.stride))
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
T* at(const VertexBuffer& b, std::size_t i, std::size_t offset) {
  return reinterpret_cast<T*>(static_cast<unsigned char*>(b.base) + i * b.stride + offset);
}

template <class T>
void deform_as(const SpaceMap* map, const VertexBuffer& in, const VertexBuffer& out, double phase) {
  const bool normals = in.normal_offset != kNoNormal;
  const std::size_t n = in.count;
  constexpr std::size_t block = 4096;
  // Block by block: each gathered into packed scalars (float in float where the map's float check
  // passes), deformed, and written out, so that in and out may be one buffer and the scratch stays
  // in cache.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, block), [&](const tbb::blocked_range<std::size_t>& r) {
    const std::size_t b = r.begin(), m = r.end() - r.begin();
    std::vector<T> p(3 * m), nm(normals ? 3 * m : 0);
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

}  // namespace

Result Deformer::fit(const double* sources, const double* destinations, std::size_t n, const Settings& settings,
                     Deformer& out) noexcept {
  return guarded([&] {
    const auto s = points(sources, n, "sources");
    const auto d = points(destinations, n, "destinations");
    FitOptions o;
    o.radius = settings.radius;
    switch (settings.kernel) {
      case engine::Kernel::C0:
        o.kernel = csrbf::Kernel::C0;
        break;
      case engine::Kernel::C2:
        o.kernel = csrbf::Kernel::C2;
        break;
      case engine::Kernel::C4:
        o.kernel = csrbf::Kernel::C4;
        break;
      case engine::Kernel::C6:
        o.kernel = csrbf::Kernel::C6;
        break;
      default:
        throw InvalidInput("settings.kernel is " + std::to_string(int(settings.kernel)) + ", not C0, C2, C4 or C6");
    }
    switch (settings.polynomial) {
      case engine::Polynomial::None:
        o.polynomial = csrbf::Polynomial::None;
        break;
      case engine::Polynomial::Constant:
        o.polynomial = csrbf::Polynomial::Constant;
        break;
      case engine::Polynomial::Linear:
        o.polynomial = csrbf::Polynomial::Linear;
        break;
      default:
        throw InvalidInput("settings.polynomial is " + std::to_string(int(settings.polynomial)) +
                           ", not None, Constant or Linear");
    }
    if (!(settings.memory_limit_gib > 0) || !(settings.memory_limit_gib <= 1e6))
      throw InvalidInput("settings.memory_limit_gib must be in (0, 1e6], got " + num(settings.memory_limit_gib));
    o.memory_limit_bytes = settings.memory_limit_gib * double(1ull << 30);
    out.map_ = std::make_shared<const SpaceMap>(SpaceMap::fit(s, d, o));
  });
}

Result Deformer::refit(const double* destinations, Deformer& out) const noexcept {
  return guarded([&] {
    if (!map_) throw InvalidInput("refit: this Deformer has not been fitted");
    const auto d = points(destinations, map_->size(), "destinations");
    out.map_ = std::make_shared<const SpaceMap>(map_->with_destinations(d));
  });
}

Result Deformer::deform(const VertexBuffer& in, const VertexBuffer& out, double phase) const noexcept {
  return guarded([&] {
    check_layout(in, "in");
    check_layout(out, "out");
    if (in.count != out.count)
      throw InvalidInput("in.count is " + std::to_string(in.count) + " but out.count is " + std::to_string(out.count));
    if (in.scalar != out.scalar) throw InvalidInput("in.scalar and out.scalar differ");
    // One buffer read and written in parallel blocks: only where each vertex stays in its own
    // bytes (the same base and stride), else a block would overwrite vertices another still reads.
    const auto span_of = [](const VertexBuffer& b) {
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
    if (in.scalar == Scalar::Float64)
      deform_as<double>(map_.get(), in, out, phase);
    else
      deform_as<float>(map_.get(), in, out, phase);
  });
}

std::size_t Deformer::size() const noexcept { return map_ ? map_->size() : 0; }

}  // namespace csrbf::engine
