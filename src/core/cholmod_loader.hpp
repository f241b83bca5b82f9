// CHOLMOD loaded on first use (cholmod_loader.cpp; private to csrbf::core).
#pragma once

namespace csrbf::detail {

/// Opens CHOLMOD on the first call: true where its library and the seven functions csrbf calls
/// were found.
bool cholmod_loaded() noexcept;

}  // namespace csrbf::detail
