// Scene JSON (docs/scene-format.md): objects with meshes, parts, deformations on a schedule,
// trajectories and orientation keys; camera, lights, duration and frame rate. Paths in the file are
// relative to its folder.
#pragma once

#include "csrbf/anim/scene.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/units.hpp"

#include <cstdint>
#include <vector>
#include <utility>
#include <filesystem>
#include <string>

namespace csrbf::io {

/// Reads the scene, its meshes and its deformations, and fits every fixed deformation. Throws
/// FileError naming the file and the JSON path (e.g. "objects[1].trajectory.keys[3].time") of a
/// bad, unknown or missing value, a missing file, or keys out of time order; errors from the engine
/// (a degenerate polynomial, duplicate sources) are reported with the path of their deformation.
/// memory_limit_bytes bounds the whole process as --memory-limit does: each mesh is read within it,
/// deformation files within a sixteenth of it, and each fit gets what the program, the meshes and
/// the fits before it leave of it (FitOptions::memory_limit_bytes, also for contacts' fits).
anim::Scene read_scene(const std::filesystem::path& path, double memory_limit_bytes = 4.0 * kGiB);
/// The same from JSON text (an editor's scene before it is saved): name is used in messages, base
/// resolves relative paths.
anim::Scene read_scene_text(const std::string& text, const std::string& name, const std::filesystem::path& base,
                            double memory_limit_bytes = 4.0 * kGiB);

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
