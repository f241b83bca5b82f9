#include "csrbf/render/movie_writer.hpp"

#include <algorithm>
#include <cctype>
#include <csignal>
#include <sstream>
#include <unistd.h>

namespace csrbf::render {

namespace fs = std::filesystem;

namespace {
/// ".name.what-pid": a hidden name beside the target. (Built by appending: GCC 12 warns falsely on
/// "." + std::string.)
std::string hidden_name(const fs::path& target, const char* what) {
  std::string s(".");
  s += target.filename().string();
  s += what;
  s += std::to_string(::getpid());
  return s;
}
}  // namespace

MovieFormat movie_format_for(const fs::path& out) {
  std::string ext = out.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  std::error_code ec;
  if (out.string().ends_with("/") || fs::is_directory(out, ec) || ext.empty()) return MovieFormat::PngFolder;
  if (ext == ".mp4") return MovieFormat::Mp4;
  if (ext == ".avi") return MovieFormat::Avi;
  throw RenderError(out.string() + ": unknown movie type '" + ext +
                    "' (use .mp4, .avi, or a folder name for numbered PNG frames)");
}

MovieWriter::MovieWriter(const fs::path& out_in, int width, int height, double fps)
    : format_(movie_format_for(out_in)), width_(width), height_(height) {
  fs::path out = out_in;
  if (out.filename().empty()) out = out.parent_path();  // "frames/" -> "frames"
  out_ = out;
  if (width < 16 || height < 16 || width > 16384 || height > 16384)
    throw RenderError("frame size " + std::to_string(width) + "x" + std::to_string(height) +
                      " is out of range (16 to 16384 pixels a side)");
  if (format_ == MovieFormat::Mp4 && (width % 2 || height % 2))
    throw RenderError("H.264 (.mp4) needs an even width and height, got " + std::to_string(width) + "x" +
                      std::to_string(height));
  if (!(fps > 0)) throw RenderError("fps must be > 0");
  const fs::path dir = out_.has_parent_path() ? out_.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw RenderError(out_.string() + ": the folder '" + dir.string() + "' does not exist");
  const std::string stem = hidden_name(out_, ".partial-");
  std::ostringstream rate;
  rate << fps;
  std::vector<std::string> argv{"ffmpeg", "-nostdin", "-hide_banner", "-loglevel", "error", "-y",
                                "-f", "rawvideo", "-pix_fmt", "rgb24",
                                "-s", std::to_string(width) + "x" + std::to_string(height),
                                "-framerate", rate.str(), "-i", "pipe:0"};
  switch (format_) {
    case MovieFormat::Mp4:
      temp_ = dir / (stem + ".mp4");
      argv.insert(argv.end(), {"-c:v", "libx264", "-preset", "medium", "-crf", "18", "-pix_fmt", "yuv420p",
                               "-movflags", "+faststart", "-f", "mp4", temp_.string()});
      break;
    case MovieFormat::Avi:
      temp_ = dir / (stem + ".avi");
      argv.insert(argv.end(), {"-c:v", "rawvideo", "-pix_fmt", "bgr24", "-f", "avi", temp_.string()});
      break;
    case MovieFormat::PngFolder:
      temp_ = dir / stem;
      fs::create_directory(temp_, ec);
      if (ec) throw RenderError(out_.string() + ": cannot create the folder '" + temp_.string() + "': " + ec.message());
      argv.insert(argv.end(), {"-start_number", "0", "-f", "image2", (temp_ / "frame_%05d.png").string()});
      break;
  }
  // A reader that exits must not kill us by SIGPIPE: write() reports it instead.
  std::signal(SIGPIPE, SIG_IGN);
  try {
    ffmpeg_ = std::make_unique<Child>(argv, true);
  } catch (...) {
    abandon();
    throw;
  }
}

MovieWriter::~MovieWriter() {
  if (!done_) abandon();
}

void MovieWriter::abandon() noexcept {
  if (ffmpeg_) ffmpeg_->kill();
  std::error_code ec;
  fs::remove_all(temp_, ec);
}

void MovieWriter::write(const std::uint8_t* rgb) {
  if (!ffmpeg_->write(rgb, std::size_t(width_) * std::size_t(height_) * 3)) {
    ffmpeg_->finish();
    const std::string err = ffmpeg_->error_output();
    abandon();
    done_ = true;
    throw RenderError(out_.string() + ": ffmpeg stopped after " + std::to_string(frames_) + " frames" +
                      (err.empty() ? std::string() : ": " + err));
  }
  ++frames_;
}

void MovieWriter::finish() {
  const int status = ffmpeg_->finish();
  if (status != 0) {
    const std::string err = ffmpeg_->error_output();
    abandon();
    done_ = true;
    throw RenderError(out_.string() + ": ffmpeg failed (exit status " + std::to_string(status) + ")" +
                      (err.empty() ? std::string() : ": " + err));
  }
  std::error_code ec;
  if (format_ == MovieFormat::PngFolder && fs::exists(out_, ec)) {
    // An existing folder is replaced whole, only now that the new frames are complete.
    const fs::path old = out_.parent_path() / hidden_name(out_, ".old-");
    fs::rename(out_, old, ec);
    if (ec) {
      abandon();
      done_ = true;
      throw RenderError(out_.string() + ": cannot replace the existing folder: " + ec.message());
    }
    fs::rename(temp_, out_, ec);
    if (ec) {
      fs::rename(old, out_);
      abandon();
      done_ = true;
      throw RenderError(out_.string() + ": cannot move the frames into place: " + ec.message());
    }
    fs::remove_all(old, ec);
  } else {
    fs::rename(temp_, out_, ec);
    if (ec) {
      abandon();
      done_ = true;
      throw RenderError(out_.string() + ": cannot move the movie into place: " + ec.message());
    }
  }
  done_ = true;
}

}  // namespace csrbf::render
