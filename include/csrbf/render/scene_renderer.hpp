// Draws an animation scene with VTK: one actor per part (its colour, opacity, texture) over points
// shared by the object's parts, updated from a Player each frame. Renders offscreen into an RGB
// buffer for movies, or into any VTK render window (the GUIs).
#pragma once

#include "csrbf/anim/scene.hpp"

#include <cstdint>
#include <memory>
#include <vector>

class vtkRenderer;
class vtkRenderWindow;

namespace csrbf::render {

class SceneRenderer {
 public:
  /// Builds the actors; the scene must outlive the renderer. Needs no window yet.
  explicit SceneRenderer(const anim::Scene& scene);
  ~SceneRenderer();
  /// What a renderer of `scene` with a width x height window holds at most, in bytes, before it is
  /// made (for memory limits); measured with Mesa's llvmpipe: see the definition.
  static double bytes(const anim::Scene& scene, int width, int height);
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  /// Copies the player's positions of every object into the actors' points.
  void update(const anim::Player& player);
  vtkRenderer* renderer() const;

  /// An offscreen window of width x height for frames (needs X: see Display).
  void open_offscreen(int width, int height);
  /// Renders and reads the frame back: RGB, rows top to bottom (width * height * 3 bytes).
  void render_rgb(std::vector<std::uint8_t>& rgb);
  vtkRenderWindow* window() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace csrbf::render
