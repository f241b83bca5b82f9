// The glTF exporter with VTK's texture coordinates and image check: csrbf::gltf's export_gltf and
// gltf_binary (csrbf/gltf/export.hpp), the textures' support filled in (GltfOptions::textures), as
// `csrbf export` runs them. The types keep their csrbf::render names.
#pragma once

#include "csrbf/gltf/export.hpp"

namespace csrbf::render {

using gltf::Bake;
using gltf::base64;
using gltf::Compact;
using gltf::glb_to_gltf;
using gltf::GltfObjectReport;
using gltf::GltfOptions;
using gltf::GltfPartReport;
using gltf::GltfReport;
using gltf::TextureSupport;
using gltf::write_base64;
using gltf::write_gltf;

/// VTK's texture coordinates (the renderer's projection of the rest shape) and image check.
TextureSupport vtk_textures();

/// gltf::export_gltf and gltf::gltf_binary with vtk_textures() (where options has none of its own).
GltfReport export_gltf(const anim::Scene& scene, const std::filesystem::path& path, const GltfOptions& options = {});
std::vector<unsigned char> gltf_binary(const anim::Scene& scene, const GltfOptions& options, GltfReport& report);

}  // namespace csrbf::render
