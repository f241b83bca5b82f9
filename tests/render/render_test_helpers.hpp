// Helpers shared by the csrbf::render tests (tests/render/test_*.cpp, one executable: test_render):
// a small animated scene, and images decoded by ffmpeg for comparison with the frames written.
#pragma once

#include "csrbf/anim/scene.hpp"
#include "csrbf/io/scene.hpp"
#include "csrbf/render/process.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace csrbf::test {

/// A red ball (examples/sphere.obj, radius 0.2) on black, moving from the top left of the view at
/// t = 0 to its bottom right at t = 0.3, at 10 frames a second (4 frames).
inline anim::Scene moving_ball() {
  return io::read_scene_text(R"({"format": "csrbf-scene", "version": 1, "duration": 0.3, "fps": 10,
      "background": [0, 0, 0],
      "camera": {"position": [0.5, 0.5, 4], "focal_point": [0.5, 0.5, 0.5], "view_angle": 30},
      "objects": [{"name": "ball", "mesh": "sphere.obj", "color": [1, 0, 0], "specular": 0,
                   "trajectory": {"keys": [{"time": 0, "position": [0, 1, 0.5]},
                                           {"time": 0.3, "position": [1, 0, 0.5]}]}}]})",
                             "moving ball", std::filesystem::path(CSRBF_SOURCE_DIR) / "examples");
}

/// An image or a movie decoded by ffmpeg into RGB bytes, 8 bits a channel, rows top to bottom,
/// frame after frame.
inline std::string decoded_rgb(const std::filesystem::path& file) {
  render::Child ffmpeg(
      {"ffmpeg", "-nostdin", "-v", "error", "-i", file.string(), "-f", "rawvideo", "-pix_fmt", "rgb24", "pipe:1"},
      false, -1, true);
  EXPECT_EQ(ffmpeg.finish(), 0) << ffmpeg.error_output();
  return ffmpeg.output();
}

}  // namespace csrbf::test
