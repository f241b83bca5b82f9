// Scene JSON (docs/scene-format.md): objects with meshes, parts, deformations on a schedule,
// trajectories and orientation keys; camera, lights, duration and frame rate. Paths in the file are
// relative to its folder.
#pragma once

#include "csrbf/anim/scene.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/texture.hpp"
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

}  // namespace csrbf::io
