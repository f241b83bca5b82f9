// Texture coordinates projected from an object's rest shape with VTK's texture-mapping filters:
// one function for the renderer and the glTF export, so that both put the image in the same place.
#pragma once

#include "csrbf/anim/scene.hpp"

#include <vtkDataArray.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <cstdint>
#include <string>
#include <vector>

namespace csrbf::render {

/// (s, t) for every point of rest (VTK's convention: t = 0 at the image's bottom row).
vtkSmartPointer<vtkDataArray> texture_coordinates(vtkPolyData* rest, anim::TextureMapping mapping);

/// The same for an object's faces (indices into obj.faces) over all its rest vertices, as glTF
/// wants them: (u, v) a vertex, v = 0 at the image's top row.
std::vector<float> texture_coordinates(const anim::Object& obj, const std::vector<std::uint32_t>& faces,
                                       anim::TextureMapping mapping);

/// Decodes an image file with VTK (as the renderer does) and throws io::FileError naming it when it
/// does not decode to a non-empty image: a texture cut short fails here, not in the user's engine.
void check_image_decodes(const std::string& file);

}  // namespace csrbf::render
