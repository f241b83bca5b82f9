#include "animate.hpp"
#include "commands.hpp"
#include "fit_input.hpp"
#include "commands.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/io/memory.hpp"

#include "csrbf/io/scene.hpp"
#include "csrbf/render/movie.hpp"
#include "csrbf/render/movie_writer.hpp"
#include "csrbf/render/process.hpp"
#include "csrbf/render/scene_renderer.hpp"
#include "csrbf/units.hpp"

#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <unistd.h>

namespace csrbf::cli {
namespace {

volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_signal(int sig) { g_interrupted = sig; }

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::string clock_text(double s) {
  char buf[32];
  if (s >= 60)
    std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  else
    std::snprintf(buf, sizeof buf, "%.1fs", s);
  return buf;
}

/// A bar redrawn in place on a terminal; otherwise a plain line at every tenth of the frames.
class Progress {
 public:
  explicit Progress(std::size_t total) : total_(total), tty_(isatty(STDOUT_FILENO) != 0), start_(Clock::now()) {}
  void frame(std::size_t done) {
    const double el = seconds_since(start_);
    const double rate = el > 0 ? double(done) / el : 0.0;
    const double left = rate > 0 ? double(total_ - done) / rate : 0.0;
    if (tty_) {
      constexpr int width = 30;
      const int fill = int(double(width) * double(done) / double(total_));
      std::printf("\r[%s%s] %zu/%zu frames  %.1f fps  %s left ", std::string(std::size_t(fill), '#').c_str(),
                  std::string(std::size_t(width - fill), '.').c_str(), done, total_, rate, clock_text(left).c_str());
      if (done == total_) std::printf("\n");
      std::fflush(stdout);
    } else {
      const std::size_t step = std::max<std::size_t>(1, total_ / 10);
      if (done % step == 0 || done == total_)
        std::printf("frame %zu/%zu, %.1f fps, %s left\n", done, total_, rate, clock_text(left).c_str());
      std::fflush(stdout);
    }
  }

 private:
  std::size_t total_;
  bool tty_;
  Clock::time_point start_;
};

std::pair<int, int> parse_size(const std::string& s) {
  const auto bad = [&] { return UsageError("--size: expected WIDTHxHEIGHT with each in 16..16384, got '" + s + "'"); };
  const auto x = s.find('x');
  if (x == std::string::npos) throw bad();
  int w = 0, h = 0;
  const char* e1 = s.data() + x;
  const char* e2 = s.data() + s.size();
  const auto r1 = std::from_chars(s.data(), e1, w);
  const auto r2 = std::from_chars(e1 + 1, e2, h);
  if (r1.ec != std::errc() || r1.ptr != e1 || r2.ec != std::errc() || r2.ptr != e2 || w < 16 || h < 16 || w > 16384 ||
      h > 16384)
    throw bad();
  return {w, h};
}

}  // namespace

int run_animate(const AnimateOptions& o) {
  const auto [width, height] = parse_size(o.size);
  // Check the target before the (slow) scene load, so a typo fails at once.
  render::check_movie_output(o.out);
  // A movie (or frame folder) that does not exist now is written new: one that appears meanwhile is
  // never replaced.
  io::must_be_new(render::movie_target(o.out));
  if (render::movie_format_for(o.out) == render::MovieFormat::Mp4 && (width % 2 || height % 2))
    throw UsageError("--size: H.264 (.mp4) needs an even width and height, got '" + o.size + "'");
  {
    const std::vector<std::filesystem::path> inputs = io::referenced_files(o.scene, o.memory_limit_gib * kGiB);
    check_not_an_input("-o", o.out, inputs);
    // A folder of PNG frames replaces the frame files in it: none of them may be an input, by
    // device and inode (an input reached through a symbolic or hard link to a frame file was deleted).
    std::error_code ec;
    if (std::filesystem::is_directory(o.out, ec))
      for (std::filesystem::directory_iterator it(o.out, ec), end; !ec && it != end; it.increment(ec)) {
        if (!io::is_frame_name(it->path().filename().string())) continue;
        const std::filesystem::path same = io::same_file_as(it->path(), inputs);
        if (!same.empty())
          throw UsageError("-o '" + printable(o.out) + "': its frame file '" + printable(it->path().string()) +
                           "' is the scene's input '" + printable(same.string()) +
                           "'; csrbf never writes an input: choose another folder");
      }
  }
  anim::Scene scene = io::read_scene(o.scene, o.memory_limit_gib * kGiB);
  if (o.fps) scene.fps = *o.fps;
  const double from = o.from.value_or(0.0), to = o.to.value_or(scene.duration);
  if (!(to >= from)) {
    std::ostringstream m;
    m << "--from " << from << " is after --to " << to;
    throw UsageError(m.str());
  }
  // Bounded before anything is allocated or started: 1e6 frames is 11 hours at 25 fps.
  constexpr double kMaxFrames = 1e6;
  if ((to - from) * scene.fps + 1 > kMaxFrames) {
    std::ostringstream m;
    m << "--from " << from << " --to " << to << " at " << scene.fps << " fps is " << (to - from) * scene.fps + 1
      << " frames; at most " << kMaxFrames << " are rendered at once";
    throw UsageError(m.str());
  }
  const std::size_t frames = scene.frame_count(from, to);
  // What the movie holds beyond the scene: the player and the renderer (its fixed part, the frame's
  // pixels and each mesh's copies), predicted before either is made.
  const double player_bytes = anim::Player::bytes(scene),
               renderer_bytes = render::SceneRenderer::bytes(scene, width, height);
  const double limit = o.memory_limit_gib * kGiB, left = io::memory_left(limit);
  if (player_bytes + renderer_bytes > left) {
    std::ostringstream m;
    m.precision(3);
    m << "--size " << o.size << ": the movie takes about " << (player_bytes + renderer_bytes) / kGiB
      << " GiB (the player " << player_bytes / kGiB << ", the renderer " << renderer_bytes / kGiB
      << ": 96 MiB, 64 bytes a pixel, the meshes' copies and the textures), more than the " << left / kGiB
      << " GiB that --memory-limit leaves after the scene; give --memory-limit "
      << std::ceil(100 * (limit - left + player_bytes + renderer_bytes) / kGiB) / 100 << " or more"
      << (64.0 * double(width) * double(height) > 0.25 * renderer_bytes ? ", or a smaller --size" : "");
    throw io::FileError(m.str());
  }

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);

  render::Display display(o.private_display);
  std::cout << "csrbf animate: " << printable(o.scene) << " -> " << printable(o.out) << ": " << frames << " frames, "
            << width << "x" << height << " at " << scene.fps << " fps, t = " << from << " .. " << to << " s"
            << (display.is_private() ? ", private X display " + display.name() : "")
            << (display.unreachable_display().empty()
                    ? ""
                    : " (DISPLAY " + display.unreachable_display() + " does not open)")
            << "\n";
  std::cout.flush();

  Progress progress(frames);
  render::MovieOptions mo;
  mo.width = width;
  mo.height = height;
  mo.from = from;
  mo.to = to;
  mo.cancelled = [] { return g_interrupted != 0; };
  const render::MovieStats st = render::render_movie(scene, o.out, mo, [&](std::size_t done, std::size_t) {
    if (g_interrupted) return false;
    progress.frame(done);
    return true;
  });
  if (st.cancelled) {
    std::cerr << "\ncsrbf animate: interrupted after " << st.frames << " of " << frames << " frames; "
              << printable(o.out) << " was not written\n";
    return 128 + int(g_interrupted);  // 130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP
  }
  const double n = double(frames);
  std::printf(
      "frames: %zu\ncomputation: %.3f ms/frame (mean)\nrendering: %.3f ms/frame (mean)\nencoding: %.3f ms/frame "
      "(mean)\nwrote %s\n",
      frames, 1e3 * st.compute_seconds / n, 1e3 * st.render_seconds / n, 1e3 * st.encode_seconds / n,
      printable(o.out).c_str());
  return 0;
}

CLI::App* add_animate_command(CLI::App& app, AnimateOptions& o) {
  auto* animate =
      app.add_subcommand("animate", "Render a scene file to a movie, without a display (docs/scene-format.md)");
  animate->add_option("scene", o.scene, "Scene JSON file")->required();
  animate
      ->add_option("-o,--output", o.out,
                   "Movie: .mp4 (H.264), .avi (full uncompressed frames) or a folder of numbered PNG frames")
      ->required();
  animate->add_option("--fps", o.fps, "Frames per second (default: the scene's)")
      ->check(finite_in(0.1, 1000.0, "--fps"));
  animate->add_option("--size", o.size, "Frame size WIDTHxHEIGHT")->capture_default_str();
  animate->add_option("--from", o.from, "Start time in seconds (default 0)")->check(finite_in(-1e6, 1e6, "--from"));
  animate->add_option("--to", o.to, "End time in seconds (default: the scene's duration)")
      ->check(finite_in(-1e6, 1e6, "--to"));
  animate->add_flag("--private-display", o.private_display,
                    "Render on a private Xvfb even when DISPLAY is set (one is started anyway when it is not)");
  add_scene_memory_limit(animate, o.memory_limit_gib);
  return animate;
}

}  // namespace csrbf::cli
