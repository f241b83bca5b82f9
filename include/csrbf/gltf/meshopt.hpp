// EXT_meshopt_compression (glTF): buffer views compressed by meshoptimizer's vertex and index
// codecs (Debian's libmeshoptimizer), which three.js, Babylon.js and gltfpack's readers decode.
// `csrbf export --meshopt` writes them; csrbf::gltf::GltfRuntime and the tests read them back.
#pragma once

#include <cstddef>
#include <vector>

namespace csrbf::gltf {

/// How a buffer view is compressed: meshoptimizer's modes, and the element's bytes.
struct MeshoptView {
  enum class Mode { None, Attributes, Triangles, Indices };
  Mode mode = Mode::None;
  std::size_t stride = 0;  ///< bytes an element (Attributes: a multiple of 4, at most 256; indices: 2 or 4)
};

/// The same glb with every EXT_meshopt_compression view decoded into its own buffer's bytes: one
/// buffer, no extension (an uncompressed file any reader reads). A glb without the extension is
/// returned as it is. Throws InvalidInput naming the view whose data does not decode.
std::vector<unsigned char> gltf_without_meshopt(const std::vector<unsigned char>& glb);

}  // namespace csrbf::gltf
