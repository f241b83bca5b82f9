#include "csrbf/render/movie.hpp"
#include "csrbf/units.hpp"

#include "csrbf/render/movie_writer.hpp"
#include "csrbf/render/scene_renderer.hpp"

#include <chrono>

namespace csrbf::render {

MovieStats render_movie(const anim::Scene& scene, const std::filesystem::path& out, const MovieOptions& o,
                        const std::function<bool(std::size_t, std::size_t)>& progress) {
  const double to = o.to < o.from ? scene.duration : o.to;
  MovieStats stats;
  const std::size_t total = scene.frame_count(o.from, to);
  anim::Player player(scene);
  SceneRenderer renderer(scene);
  renderer.open_offscreen(o.width, o.height);
  MovieWriter writer(out, o.width, o.height, scene.fps);
  writer.set_cancel(o.cancelled);
  std::vector<std::uint8_t> rgb;
  for (std::size_t k = 0; k < total; ++k) {
    auto t0 = Clock::now();
    player.evaluate(o.from + double(k) / scene.fps);
    stats.compute_seconds += seconds_since(t0);
    t0 = Clock::now();
    renderer.update(player);
    renderer.render_rgb(rgb);
    stats.render_seconds += seconds_since(t0);
    t0 = Clock::now();
    const bool written = writer.write(rgb.data());
    stats.encode_seconds += seconds_since(t0);
    stats.frames = k + 1;
    if (!written || (o.cancelled && o.cancelled()) || (progress && !progress(k + 1, total))) {
      stats.cancelled = true;
      return stats;  // the writer's destructor removes the partial output
    }
  }
  const auto t0 = Clock::now();
  stats.cancelled = !writer.finish();
  stats.encode_seconds += seconds_since(t0);
  return stats;
}

}  // namespace csrbf::render
