// Frames to a movie through the ffmpeg program (Debian's VTK has no FFMPEG writer): MP4 (H.264),
// AVI with full, uncompressed frames (as the paper saved its movies), or a folder of numbered PNG
// frames. Nothing half-written: frames go to a hidden temporary file or folder beside the target,
// which replaces the target only when finish() succeeds.
#pragma once

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/render/process.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>

namespace csrbf::render {

enum class MovieFormat { Mp4, Avi, PngFolder };

/// .mp4 and .avi by extension (case-insensitive); anything else (no extension, a trailing '/', an
/// existing folder) is a folder of PNG frames. Throws RenderError for another extension.
MovieFormat movie_format_for(const std::filesystem::path& out);

/// Throws RenderError unless out may be written: a movie file may be new or replace a regular file;
/// a PNG frame folder may be new, empty, or hold only frame_NNNNN.png files (an earlier run's). A
/// device, FIFO, socket or any other file is never replaced.
void check_movie_output(const std::filesystem::path& out);

/// The path a movie writer writes for -o out: a frame folder without its trailing '/', a movie file
/// with its links resolved (io::resolve_output).
std::filesystem::path movie_target(const std::filesystem::path& out);

class MovieWriter {
 public:
  /// width x height pixels (even for MP4), fps > 0. Throws RenderError when the target's folder is
  /// missing or ffmpeg cannot be started.
  MovieWriter(const std::filesystem::path& out, int width, int height, double fps);
  /// Without a successful finish(): stops ffmpeg and removes the temporary output.
  ~MovieWriter();
  MovieWriter(const MovieWriter&) = delete;
  MovieWriter& operator=(const MovieWriter&) = delete;

  /// Asked while ffmpeg is slow to read or to finish: true gives up (write() and finish() return
  /// false, nothing is written).
  void set_cancel(std::function<bool()> cancelled) { cancelled_ = std::move(cancelled); }
  /// One frame, RGB, 8 bits a channel, rows top to bottom (width * height * 3 bytes). False when
  /// cancelled.
  bool write(const std::uint8_t* rgb);
  /// Waits for ffmpeg (at most CSRBF_PIPE_TIMEOUT, default 120 s) and moves the verified result
  /// over the target; false when cancelled first (the partial is removed). Throws RenderError with
  /// ffmpeg's message on failure (the target is then untouched).
  bool finish();
  MovieFormat format() const noexcept { return format_; }
  std::size_t frames() const noexcept { return frames_; }

 private:
  void abandon() noexcept;
  [[noreturn]] void fail(const std::string& message);
  std::size_t count_frames(const std::filesystem::path& movie) const;
  std::filesystem::path out_;
  std::unique_ptr<io::Partial> partial_;
  MovieFormat format_;
  int width_, height_;
  std::size_t frames_ = 0;
  std::unique_ptr<Child> ffmpeg_;
  std::function<bool()> cancelled_;
  bool done_ = false;
};

}  // namespace csrbf::render
