// CHOLMOD loaded on first use (cholmod_loader.cpp; private to csrbf::core).
#pragma once

#include <string>

namespace csrbf::detail {

/// Opens CHOLMOD on the first call: true where its library and the seven functions csrbf calls
/// were found.
bool cholmod_loaded() noexcept;
/// Why CHOLMOD cannot be used: this build has none, or the loader's reason (dlerror, a missing
/// function).
std::string cholmod_load_error();

}  // namespace csrbf::detail
