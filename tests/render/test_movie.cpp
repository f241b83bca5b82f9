// A scene to a movie (csrbf/render/movie.hpp): frame k is what the renderer draws at from + k / fps,
// progress is told of each frame, and a movie stopped or refused leaves nothing behind.
#include "csrbf/render/movie.hpp"
#include "csrbf/render/process.hpp"
#include "csrbf/render/scene_renderer.hpp"

#include "io/test_helpers.hpp"
#include "render/render_test_helpers.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

using namespace csrbf;
using namespace csrbf::render;
namespace fs = std::filesystem;

namespace {

std::string frame_name(std::size_t k) {
  std::string n = std::to_string(k);
  return "frame_" + std::string(5 - n.size(), '0') + n + ".png";
}

}  // namespace

TEST(RenderMovie, FrameKIsTheSceneAtFromPlusKOverFps) {
  const Display display;
  const anim::Scene scene = test::moving_ball();
  test::TempDir dir;
  MovieOptions o;
  o.width = 64;
  o.height = 48;
  o.from = 0.1;  // to the end: 0.1, 0.2 and 0.3
  std::vector<std::pair<std::size_t, std::size_t>> told;
  const MovieStats stats = render_movie(scene, dir / "frames", o, [&](std::size_t done, std::size_t total) {
    told.emplace_back(done, total);
    return true;
  });
  EXPECT_FALSE(stats.cancelled);
  ASSERT_EQ(stats.frames, scene.frame_count(0.1, 0.3));
  ASSERT_EQ(stats.frames, 3u);
  EXPECT_EQ(told, (std::vector<std::pair<std::size_t, std::size_t>>{{1, 3}, {2, 3}, {3, 3}}));
  EXPECT_EQ(test::files_in(dir / "frames"), 3u);
  // Each frame as a renderer of its own draws the scene at its time.
  anim::Player player(scene);
  SceneRenderer renderer(scene);
  renderer.open_offscreen(64, 48);
  std::vector<std::uint8_t> rgb;
  for (std::size_t k = 0; k < 3; ++k) {
    player.evaluate(0.1 + double(k) / scene.fps);
    renderer.update(player);
    renderer.render_rgb(rgb);
    EXPECT_EQ(test::decoded_rgb(dir / "frames" / frame_name(k)), std::string(rgb.begin(), rgb.end())) << k;
  }
}

TEST(RenderMovie, AMovieStoppedOrRefusedLeavesNothing) {
  const Display display;
  const anim::Scene scene = test::moving_ball();
  test::TempDir dir;
  MovieOptions o;
  o.width = o.height = 32;
  // progress() says stop after the second frame.
  MovieStats stats =
      render_movie(scene, dir / "stopped.avi", o, [](std::size_t done, std::size_t) { return done < 2; });
  EXPECT_TRUE(stats.cancelled);
  EXPECT_EQ(stats.frames, 2u);
  // options.cancelled says stop.
  o.cancelled = [] { return true; };
  stats = render_movie(scene, dir / "cancelled", o);
  EXPECT_TRUE(stats.cancelled);
  EXPECT_EQ(stats.frames, 1u);
  EXPECT_EQ(test::files_in(dir.path), 0u);
  // An output it may not write is refused before any frame, and left as it was.
  o.cancelled = nullptr;
  fs::create_directory(dir / "mine");
  test::write_text(dir / "mine/notes.txt", "mine");
  EXPECT_THROW(render_movie(scene, dir / "mine", o), RenderError);
  EXPECT_THROW(render_movie(scene, dir / "take.gif", o), RenderError);
  EXPECT_EQ(test::read_text(dir / "mine/notes.txt"), "mine");
  EXPECT_EQ(test::files_in(dir.path), 1u);
}
