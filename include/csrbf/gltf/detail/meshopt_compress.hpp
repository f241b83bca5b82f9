// The exporter's side of EXT_meshopt_compression (src/gltf/meshopt.cpp): for csrbf::render's glTF
// export, which builds its document with nlohmann::json (a consumer of this header needs that library).
#pragma once

#include "csrbf/gltf/meshopt.hpp"

#include <nlohmann/json.hpp>

#include <vector>

namespace csrbf::gltf {

/// Compresses the views of a glTF whose data is bin (one buffer) by views[v]'s mode: each such view
/// moves to a fallback buffer without data, its compressed bytes into bin, each checked to decode
/// to its own bytes first (InvalidInput otherwise). Lists the extension as used and required.
void meshopt_compress(nlohmann::json& doc, std::vector<unsigned char>& bin, const std::vector<MeshoptView>& views);

}  // namespace csrbf::gltf
