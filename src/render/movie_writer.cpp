#include "csrbf/render/movie_writer.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <cctype>
#include <csignal>
#include <sstream>
#include <unistd.h>

namespace csrbf::render {

namespace fs = std::filesystem;

namespace {
std::string lower_extension(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

/// A PNG frame folder that exists must hold only frames csrbf wrote; anything else in it is the
/// user's and would be lost.
void check_frame_folder(const fs::path& out) {
  std::error_code ec;
  const auto st = fs::symlink_status(out, ec);
  if (st.type() == fs::file_type::not_found) return;
  if (st.type() == fs::file_type::symlink)
    throw RenderError(out.string() + ": is a symbolic link; give the folder of PNG frames itself");
  if (st.type() != fs::file_type::directory)
    throw RenderError(out.string() +
                      ": exists and is not a folder; a folder of PNG frames must be new, empty, or "
                      "hold only frames csrbf wrote (frame_NNNNN.png). Give a new name, or .mp4 / .avi for a movie");
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code e2;
    if (!io::is_frame_name(name) || !it->is_regular_file(e2))
      throw RenderError(
          out.string() + ": the folder holds '" + name +
          "', which csrbf did not write; frames go only into a new or empty folder, or one that holds "
          "only frame_NNNNN.png files (an earlier run's frames, which are replaced); nothing was changed");
  }
  if (ec) throw RenderError(out.string() + ": cannot list the folder: " + ec.message());
}

/// A PNG file that is whole: the signature, and the IEND chunk at its end.
bool complete_png(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  unsigned char head[8] = {}, tail[12] = {};
  if (!in.read(reinterpret_cast<char*>(head), 8)) return false;
  static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (std::memcmp(head, sig, 8) != 0) return false;
  in.seekg(-12, std::ios::end);
  if (!in.read(reinterpret_cast<char*>(tail), 12)) return false;
  static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
  return std::memcmp(tail, iend, 12) == 0;
}
}  // namespace

MovieFormat movie_format_for(const fs::path& out) {
  const std::string ext = lower_extension(out);
  std::error_code ec;
  if (out.string().ends_with("/") || fs::is_directory(out, ec) || ext.empty()) return MovieFormat::PngFolder;
  if (ext == ".mp4") return MovieFormat::Mp4;
  if (ext == ".avi") return MovieFormat::Avi;
  throw RenderError(out.string() + ": unknown movie type '" + ext +
                    "' (use .mp4, .avi, or a folder name for numbered PNG frames)");
}

void check_movie_output(const fs::path& out_in) {
  fs::path out = out_in;
  if (out.filename().empty()) out = out.parent_path();  // "frames/" -> "frames"
  const MovieFormat f = movie_format_for(out_in);
  if (f == MovieFormat::PngFolder) {
    const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
    std::error_code ec;
    if (!fs::is_directory(dir, ec))
      throw RenderError(out.string() + ": the folder '" + dir.string() + "' does not exist");
    check_frame_folder(out);
    return;
  }
  try {
    io::check_output_path(out);
  } catch (const io::FileError& e) {
    throw RenderError(e.what());
  }
}

fs::path movie_target(const fs::path& out_in) {
  fs::path out = out_in;
  if (out.filename().empty()) out = out.parent_path();  // "frames/" -> "frames"
  return movie_format_for(out_in) == MovieFormat::PngFolder ? out : io::resolve_output(out);
}

MovieWriter::MovieWriter(const fs::path& out_in, int width, int height, double fps)
    : format_(movie_format_for(out_in)), width_(width), height_(height) {
  out_ = movie_target(out_in);
  if (width < 16 || height < 16 || width > 16384 || height > 16384)
    throw RenderError("frame size " + std::to_string(width) + "x" + std::to_string(height) +
                      " is out of range (16 to 16384 pixels a side)");
  if (format_ == MovieFormat::Mp4 && (width % 2 || height % 2))
    throw RenderError("H.264 (.mp4) needs an even width and height, got " + std::to_string(width) + "x" +
                      std::to_string(height));
  if (!(fps > 0) || !std::isfinite(fps)) throw RenderError("fps must be a finite number > 0");
  check_movie_output(out_in);  // its trailing slash says "a folder" ("take2.5/")
  std::ostringstream rate;
  rate << fps;
  std::vector<std::string> argv{
      "ffmpeg",     "-nostdin", "-hide_banner", "-loglevel",
      "error",      "-y",       "-f",           "rawvideo",
      "-pix_fmt",   "rgb24",    "-s",           std::to_string(width) + "x" + std::to_string(height),
      "-framerate", rate.str(), "-i",           "pipe:0"};
  try {
    switch (format_) {
      case MovieFormat::Mp4:
        partial_ = std::make_unique<io::Partial>(out_, io::Partial::Kind::File, ".mp4");
        argv.insert(argv.end(), {"-c:v", "libx264", "-preset", "medium", "-crf", "18", "-pix_fmt", "yuv420p",
                                 "-movflags", "+faststart", "-f", "mp4", partial_->path().string()});
        break;
      case MovieFormat::Avi:
        partial_ = std::make_unique<io::Partial>(out_, io::Partial::Kind::File, ".avi");
        argv.insert(argv.end(), {"-c:v", "rawvideo", "-pix_fmt", "bgr24", "-f", "avi", partial_->path().string()});
        break;
      case MovieFormat::PngFolder:
        partial_ = std::make_unique<io::Partial>(out_, io::Partial::Kind::Folder);
        argv.insert(argv.end(), {"-start_number", "0", "-f", "image2", (partial_->path() / "frame_%05d.png").string()});
        break;
    }
  } catch (const io::FileError& e) {
    throw RenderError(e.what());
  }
  // A reader that exits must not kill us by SIGPIPE: write() reports it instead.
  std::signal(SIGPIPE, SIG_IGN);
  ffmpeg_ = std::make_unique<Child>(argv, true);
}

MovieWriter::~MovieWriter() {
  if (!done_) abandon();
}

void MovieWriter::abandon() noexcept {
  if (ffmpeg_) ffmpeg_->kill();
  partial_.reset();  // removes the partial file or folder
}

void MovieWriter::fail(const std::string& message) {
  abandon();
  done_ = true;
  throw RenderError(out_.string() + ": " + message);
}

bool MovieWriter::write(const std::uint8_t* rgb) {
  const int stall = io::pipe_timeout_seconds(120);
  if (!ffmpeg_->write(rgb, std::size_t(width_) * std::size_t(height_) * 3, stall, cancelled_)) {
    if (cancelled_ && cancelled_()) {
      abandon();
      done_ = true;
      return false;
    }
    if (ffmpeg_->stalled())
      fail("ffmpeg stopped reading frames for " + std::to_string(stall) + " s after " + std::to_string(frames_) +
           " frames");
    ffmpeg_->finish();
    const std::string err = ffmpeg_->error_output();
    fail("ffmpeg stopped after " + std::to_string(frames_) + " frames" + (err.empty() ? std::string() : ": " + err));
  }
  ++frames_;
  return true;
}

std::size_t MovieWriter::count_frames(const fs::path& movie) const {
  Child probe({"ffprobe", "-v", "error", "-select_streams", "v:0", "-count_packets", "-show_entries",
               "stream=nb_read_packets", "-of", "csv=p=0", movie.string()},
              false, -1, true);
  const int st = probe.finish();
  if (st != 0) {
    const std::string err = probe.error_output();
    throw RenderError(out_.string() + ": ffprobe cannot read the movie ffmpeg wrote (exit status " +
                      std::to_string(st) + ")" + (err.empty() ? std::string() : ": " + err));
  }
  const std::string text = probe.output();
  std::size_t n = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), n);
  if (r.ec != std::errc())
    throw RenderError(out_.string() + ": ffprobe gave no frame count ('" + text.substr(0, 80) + "')");
  return n;
}

bool MovieWriter::finish() {
  const int wait = io::pipe_timeout_seconds(120);
  const int status = ffmpeg_->finish(wait, cancelled_);
  if (cancelled_ && cancelled_()) {
    abandon();
    done_ = true;
    return false;
  }
  if (status < 0) fail("ffmpeg did not finish within " + std::to_string(wait) + " s of the last frame");
  if (status != 0) {
    const std::string err = ffmpeg_->error_output();
    fail("ffmpeg failed (exit status " + std::to_string(status) + ")" + (err.empty() ? std::string() : ": " + err));
  }
  // ffmpeg can exit 0 after a failed write (a full disk): check what it left before anything moves.
  const std::string err = ffmpeg_->error_output();
  const std::string why = err.empty() ? std::string() : " (ffmpeg: " + err + ")";
  std::error_code ec;
  if (format_ == MovieFormat::PngFolder) {
    std::size_t found = 0;
    for (fs::directory_iterator it(partial_->path(), ec), end; !ec && it != end; it.increment(ec)) {
      if (!io::is_frame_name(it->path().filename().string()) || !complete_png(it->path()))
        fail("frame file '" + it->path().filename().string() + "' is not a complete PNG" + why);
      ++found;
    }
    if (ec || found != frames_)
      fail("ffmpeg wrote " + std::to_string(found) + " of " + std::to_string(frames_) + " frames" + why);
    if (cancelled_ && cancelled_()) {
      abandon();
      done_ = true;
      return false;
    }
    // Frames replace an earlier run's frames only: checked again now, as the folder may have changed.
    try {
      check_frame_folder(out_);
    } catch (const RenderError& e) {
      fail(std::string(e.what()).substr(out_.string().size() + 2));
    }
    if (fs::exists(out_, ec)) {
      if (io::registered_new(out_))
        fail(
            "it was made by another program while the frames were rendered (csrbf writes a new folder, and never "
            "replaces it)");
      // Move the old frames aside under a partial's name (so that even a crash now leaves nothing
      // that the next run would not remove), then the new folder in, then drop the old frames.
      std::unique_ptr<io::Partial> old;
      try {
        old = std::make_unique<io::Partial>(out_, io::Partial::Kind::Folder);
      } catch (const io::FileError& e) {
        fail(e.what());
      }
      io::keep_mode(out_, partial_->path());
      fs::rename(out_, old->path(), ec);  // replaces the empty folder Partial made
      if (ec) fail("cannot move the earlier frames aside: " + ec.message());
      fs::rename(partial_->path(), out_, ec);
      if (ec) {
        std::error_code e2;
        fs::rename(old->path(), out_, e2);
        old->release();
        fail("cannot move the frames into place: " + ec.message());
      }
      partial_->release();
      old.reset();  // removes the earlier frames (regular files) and their folder
    } else {
      try {
        partial_->commit_new(out_);  // a folder made there since the start is never replaced
      } catch (const io::FileError& e) {
        fail(e.what());
      }
    }
  } else {
    if (fs::file_size(partial_->path(), ec) == 0 || ec) fail("ffmpeg wrote an empty file" + why);
    std::size_t n = 0;
    try {
      n = count_frames(partial_->path());
    } catch (const RenderError& e) {
      fail(std::string(e.what()).substr(out_.string().size() + 2));
    }
    if (n != frames_) fail("the movie holds " + std::to_string(n) + " of " + std::to_string(frames_) + " frames" + why);
    if (cancelled_ && cancelled_()) {
      abandon();
      done_ = true;
      return false;
    }
    try {
      partial_->commit(out_);
    } catch (const io::FileError& e) {
      fail(e.what());
    }
  }
  done_ = true;
  return true;
}

}  // namespace csrbf::render
