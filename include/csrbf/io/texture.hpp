// Texture files as csrbf checks them before an image library sees them, and what they take
// decoded (csrbf::files; io/scene.hpp includes this header).
#pragma once

#include "csrbf/anim/scene.hpp"

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace csrbf::io {

/// What is wrong with a PNG or JPEG texture file as a whole, or empty when it is sound: a PNG's
/// every chunk with its CRC, IHDR first and IEND last, its image data inflating to the rows IHDR
/// promises with valid filter types; a JPEG ending with its end-of-image marker. Image libraries
/// under VTK crash on a PNG cut short: read_scene checks every texture with this, and so does
/// anything that hands a texture to them from a scene built otherwise.
std::string texture_problem(const std::filesystem::path& file);
/// A PNG's or JPEG's width and height from its header (IHDR, or the first frame marker); (0, 0)
/// where it is neither, with the reason in *why.
std::pair<std::uint64_t, std::uint64_t> texture_size(const std::filesystem::path& file, std::string* why = nullptr);
/// The texture files the scene's objects and parts name, each once (sorted).
std::vector<std::string> texture_files(const anim::Scene& scene);
/// What the scene's textures take once decoded, in bytes, each file once: 4 bytes a pixel, 2.25
/// times (the decoder's image and VTK's copy; rendered, OpenGL's texture). Measured with an 8192 x
/// 8192 PNG: export 517 MB, animate 510 MB above the same scene without it.
/// largest: the largest texture's alone (textures decoded one at a time, to be checked).
double decoded_texture_bytes(const anim::Scene& scene, bool largest = false);

}  // namespace csrbf::io
