// Meshes on disk. OBJ, PLY (ascii and binary), OFF and .xyz are read and written here so that a
// deformed mesh keeps the input's vertex count, order, faces and every other attribute: only the
// positions change, and normals are recomputed where the file has them. STL, glTF/GLB and the other
// formats assimp reads go through assimp (vertex order is then assimp's; node transforms are baked
// into the positions).
#pragma once

#include "csrbf/io/error.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/units.hpp"

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace csrbf::io {

enum class MeshFormat { Obj, Ply, Off, Xyz, Stl, Gltf, Glb, Assimp };
/// The format for a file name's extension (case-insensitive); Assimp for anything else.
MeshFormat format_for(const std::filesystem::path& path);
const char* format_name(MeshFormat f) noexcept;

/// A loaded mesh: positions and polygons (0-based), plus what is needed to write the original file
/// back with new positions. Move-only.
class MeshDocument {
 public:
  /// Throws FileError naming the file, the line (for text formats) and the bad text.
  /// memory_limit_bytes: a file that would take more once read is refused before it is read.
  static MeshDocument load(const std::filesystem::path& path, double memory_limit_bytes = 4.0 * kGiB);
  MeshDocument(MeshDocument&&) noexcept;
  MeshDocument& operator=(MeshDocument&&) noexcept;
  ~MeshDocument();

  MeshFormat format() const noexcept;
  std::vector<Vec3>& positions() noexcept;
  const std::vector<Vec3>& positions() const noexcept;
  const PolygonList& faces() const noexcept;
  bool has_normals() const noexcept;
  /// Named face groups (OBJ `g` and `o` lines): group name -> indices into faces(). Empty for
  /// other formats.
  const std::map<std::string, std::vector<std::uint32_t>>& groups() const noexcept;
  /// Faces by material (OBJ `usemtl`): material name -> indices into faces().
  const std::map<std::string, std::vector<std::uint32_t>>& materials() const noexcept;

  /// Writes the mesh with the current positions, in the format of path's extension, atomically.
  /// The same format as loaded (OBJ, PLY, OFF, .xyz) rewrites the original, changing only
  /// positions and normals; another format writes positions and faces.
  void save(const std::filesystem::path& path) const;

  struct Impl;

 private:
  explicit MeshDocument(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Area-weighted polygon normal (Newell's method); zero for degenerate polygons.
Vec3 polygon_normal(const std::vector<Vec3>& positions, std::span<const std::uint32_t> face);

}  // namespace csrbf::io
