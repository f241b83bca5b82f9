// csrbf::gltf's exporter with VTK's texture coordinates and image check (render/gltf_export.hpp).
#include "csrbf/render/gltf_export.hpp"

#include "texture_coordinates.hpp"

namespace csrbf::render {

TextureSupport vtk_textures() {
  TextureSupport t;
  t.coordinates = [](const anim::Object& obj, const std::vector<std::uint32_t>& faces, anim::TextureMapping m) {
    return texture_coordinates(obj, faces, m);
  };
  t.check_decodes = [](const std::string& file) { check_image_decodes(file); };
  return t;
}

namespace {
GltfOptions with_textures(const GltfOptions& options) {
  GltfOptions o = options;
  if (!o.textures.coordinates || !o.textures.check_decodes) o.textures = vtk_textures();
  return o;
}
}  // namespace

GltfReport export_gltf(const anim::Scene& scene, const std::filesystem::path& path, const GltfOptions& options) {
  return gltf::export_gltf(scene, path, with_textures(options));
}

std::vector<unsigned char> gltf_binary(const anim::Scene& scene, const GltfOptions& options, GltfReport& report) {
  return gltf::gltf_binary(scene, with_textures(options), report);
}

}  // namespace csrbf::render
