// GltfRuntime moved to csrbf::gltf (csrbf/gltf/runtime.hpp), a component that needs the core alone:
// this header keeps the old name for code written against csrbf::render.
#pragma once

#include "csrbf/gltf/runtime.hpp"

namespace csrbf::render {
using gltf::GltfRuntime;
}  // namespace csrbf::render
