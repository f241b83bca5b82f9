// EXT_meshopt_compression moved to csrbf::gltf (csrbf/gltf/meshopt.hpp): this header keeps the old
// names for code written against csrbf::render.
#pragma once

#include "csrbf/gltf/meshopt.hpp"

namespace csrbf::render {
using gltf::gltf_without_meshopt;
using gltf::MeshoptView;
}  // namespace csrbf::render
