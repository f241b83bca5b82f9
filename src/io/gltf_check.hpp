// glTF 2.0 checked before assimp reads it (private to csrbf::io). assimp trusts what a glTF says: an
// accessor's count (2^32 elements from a 1 kB file), a strip's element count (0 - 1 faces: 64 GB),
// a sparse accessor's offsets (out-of-bounds reads), a chunk's length, a node named as the child of
// two nodes (2^40 instances), JSON and node trees a million deep (stack overflow). Every such claim
// is checked against the bytes that back it, and the positions must be what glTF says they are:
// VEC3 of floats.
#pragma once

#include <filesystem>

namespace csrbf::io::detail {

/// Throws FileError naming the file, the glTF field (accessors[3].sparse.count) and the value. binary:
/// a .glb; max_bytes: the most the file, its buffers and the vertices it instances may take.
void check_gltf(const std::filesystem::path& path, bool binary, double max_bytes);

}  // namespace csrbf::io::detail
