// Drawing a scene with VTK (csrbf/render/scene_renderer.hpp): the memory a renderer is allowed
// before it is made, and offscreen frames whose rows run top to bottom, that follow the player, and
// that are the same every time the same instant is drawn.
#include "csrbf/render/process.hpp"
#include "csrbf/render/scene_renderer.hpp"

#include "render/render_test_helpers.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

using namespace csrbf;
using namespace csrbf::render;

namespace {

struct Centroid {
  double x = 0, y = 0;
  std::size_t pixels = 0;
};

/// The centre of the pixels that are not the black background, in pixels from the top left.
Centroid lit(const std::vector<std::uint8_t>& rgb, int width, int height) {
  Centroid c;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const std::uint8_t* p = &rgb[std::size_t(3 * (width * y + x))];
      if (p[0] + p[1] + p[2] == 0) continue;
      EXPECT_GT(p[0], p[1]);  // the ball is red
      EXPECT_GT(p[0], p[2]);
      c.x += x, c.y += y, ++c.pixels;
    }
  if (c.pixels) c.x /= double(c.pixels), c.y /= double(c.pixels);
  return c;
}

}  // namespace

TEST(SceneRenderer, BytesAreTheWindowsAndTheMeshesShare) {
  const anim::Scene scene = test::moving_ball();
  const anim::Object& ball = scene.objects.at(0);
  double triangles = 0;
  for (const auto& f : ball.faces) triangles += double(f.size()) - 2;
  // 96 MiB whatever the scene, 64 bytes a pixel, 64 a vertex and 320 a triangle (no texture).
  EXPECT_EQ(SceneRenderer::bytes(scene, 640, 480),
            96.0 * (1 << 20) + 64.0 * 640 * 480 + 64.0 * double(ball.rest.size()) + 320.0 * triangles);
  EXPECT_EQ(SceneRenderer::bytes(scene, 1280, 960) - SceneRenderer::bytes(scene, 640, 480),
            64.0 * (1280 * 960 - 640 * 480));
}

TEST(SceneRenderer, OffscreenFramesFollowThePlayer) {
  const Display display;
  const anim::Scene scene = test::moving_ball();
  anim::Player player(scene);
  SceneRenderer renderer(scene);
  renderer.open_offscreen(64, 48);
  ASSERT_NE(renderer.window(), nullptr);
  ASSERT_NE(renderer.renderer(), nullptr);
  const auto draw = [&](double t) {
    player.evaluate(t);
    renderer.update(player);
    std::vector<std::uint8_t> rgb;
    renderer.render_rgb(rgb);
    EXPECT_EQ(rgb.size(), 64u * 48u * 3u);
    return rgb;
  };
  const auto first = draw(0.0), last = draw(0.3);
  // The corners are the background; the ball is at the top left, then at the bottom right.
  for (const std::size_t corner : {std::size_t(0), std::size_t(3 * 63), std::size_t(3 * 64 * 47)})
    EXPECT_EQ(first[corner] + first[corner + 1] + first[corner + 2], 0);
  const Centroid a = lit(first, 64, 48), b = lit(last, 64, 48);
  ASSERT_GT(a.pixels, 20u);
  ASSERT_GT(b.pixels, 20u);
  EXPECT_LT(a.x, 32);
  EXPECT_LT(a.y, 24);  // row 0 is the top
  EXPECT_GT(b.x, 32);
  EXPECT_GT(b.y, 24);
  EXPECT_EQ(a.pixels, b.pixels);  // the same ball, seen the same way
  // The same instant draws the same frame.
  EXPECT_EQ(draw(0.0), first);
}
