// A scene to a movie: the loop of `csrbf animate`, shared with the Animation Composer so that both
// make the same file. Needs X (see Display).
#pragma once

#include "csrbf/anim/scene.hpp"

#include <cstddef>
#include <filesystem>
#include <functional>

namespace csrbf::render {

struct MovieOptions {
  int width = 640, height = 480;
  double from = 0.0;
  double to = -1.0;  ///< < from: the scene's duration
  /// Asked between frames and while the encoder finishes: true stops, and nothing is written.
  std::function<bool()> cancelled;
};

struct MovieStats {
  std::size_t frames = 0;
  bool cancelled = false;  ///< progress() asked to stop: nothing was written
  double compute_seconds = 0, render_seconds = 0, encode_seconds = 0;  ///< totals over the frames
};

/// Renders frames at from + k / scene.fps to `out` (.mp4, .avi or a folder of PNG frames, see
/// MovieWriter). progress(done, total) is called after each frame; returning false stops and
/// removes the partial output. Throws RenderError or the scene's errors; the target is then untouched.
MovieStats render_movie(const anim::Scene& scene, const std::filesystem::path& out, const MovieOptions& options,
                        const std::function<bool(std::size_t, std::size_t)>& progress = {});

}  // namespace csrbf::render
