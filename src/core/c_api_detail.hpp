// What the C API's files share (c_api.cpp, gpu_layout.cpp): the handle behind csrbf_deformer and
// the boundary where csrbf's exceptions become status codes and a message.
#pragma once

#include "csrbf/csrbf.h"
#include "csrbf/errors.hpp"
#include "csrbf/units.hpp"
#include "csrbf/space_map.hpp"

#include <atomic>
#include <cstddef>
#include <cstdio>
#include <memory>
#include <new>
#include <string>

struct csrbf_deformer {
  std::atomic<std::size_t> owners{1};
  std::shared_ptr<const csrbf::SpaceMap> map;
};

namespace csrbf::capi {

inline csrbf_status failure(csrbf_status s, const std::string& what, csrbf_result* r) noexcept {
  if (r) {
    r->status = s;
    std::snprintf(r->message, sizeof r->message, "%s", what.c_str());
  }
  return s;
}

/// Runs f, turning whatever it throws into a status (and r's message).
template <class F>
csrbf_status guarded(csrbf_result* r, F&& f) noexcept {
  try {
    f();
    if (r) {
      r->status = CSRBF_OK;
      r->message[0] = '\0';
    }
    return CSRBF_OK;
  } catch (const DuplicateSource& e) {
    return failure(CSRBF_DUPLICATE_SOURCE, e.what(), r);
  } catch (const DegeneratePolynomial& e) {
    return failure(CSRBF_DEGENERATE_POLYNOMIAL, e.what(), r);
  } catch (const IllConditioned& e) {
    return failure(CSRBF_ILL_CONDITIONED, e.what(), r);
  } catch (const InvalidInput& e) {
    return failure(CSRBF_INVALID_INPUT, e.what(), r);
  } catch (const NotPositiveDefinite& e) {
    return failure(CSRBF_NOT_POSITIVE_DEFINITE, e.what(), r);
  } catch (const ResourceLimit& e) {
    // The core names its own option; here it is the settings' memory_limit_gib.
    return failure(CSRBF_RESOURCE_LIMIT, std::string(e.what()) + " [here: Settings::memory_limit_gib]", r);
  } catch (const std::bad_alloc&) {
    return failure(CSRBF_OUT_OF_MEMORY, "out of memory", r);
  } catch (const std::exception& e) {
    return failure(CSRBF_INTERNAL, e.what(), r);
  } catch (...) {
    return failure(CSRBF_INTERNAL, "unknown error", r);
  }
}

/// A number as a message shows it (6 significant digits, not std::to_string's 300-digit %f).
inline std::string num(double v) { return format_significant(v, 6); }

}  // namespace csrbf::capi
