// Frames to a movie through ffmpeg (csrbf/render/movie_writer.hpp): the format by the output's name,
// which outputs may be written, frames that read back as written (PNG frames and the uncompressed
// AVI bit for bit, the MP4 frame for frame), and nothing left behind without a successful finish().
#include "csrbf/render/movie_writer.hpp"

#include "io/test_helpers.hpp"
#include "render/render_test_helpers.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <sys/stat.h>
#include <vector>

using namespace csrbf;
using namespace csrbf::render;
namespace fs = std::filesystem;

namespace {

std::string refusal(const fs::path& out) {
  try {
    check_movie_output(out);
  } catch (const RenderError& e) {
    return e.what();
  }
  return "accepted";
}

/// Frame k of 16 x 16: a gradient that differs in every pixel and every frame.
std::vector<std::uint8_t> frame(int k) {
  std::vector<std::uint8_t> rgb(16 * 16 * 3);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      std::uint8_t* p = &rgb[std::size_t(3 * (16 * y + x))];
      p[0] = std::uint8_t(16 * x + k), p[1] = std::uint8_t(16 * y), p[2] = std::uint8_t(40 * k + 5);
    }
  return rgb;
}

std::string frames(int n) {
  std::string all;
  for (int k = 0; k < n; ++k) {
    const auto f = frame(k);
    all.append(f.begin(), f.end());
  }
  return all;
}

/// Writes n frames to out at 10 fps; the writer's frame count.
std::size_t write_movie(const fs::path& out, int n) {
  MovieWriter w(out, 16, 16, 10);
  for (int k = 0; k < n; ++k) EXPECT_TRUE(w.write(frame(k).data()));
  EXPECT_TRUE(w.finish());
  return w.frames();
}

}  // namespace

TEST(MovieWriter, TheFormatIsTheOutputsExtension) {
  test::TempDir dir;
  EXPECT_EQ(movie_format_for("take.mp4"), MovieFormat::Mp4);
  EXPECT_EQ(movie_format_for("TAKE.MP4"), MovieFormat::Mp4);
  EXPECT_EQ(movie_format_for("take.avi"), MovieFormat::Avi);
  EXPECT_EQ(movie_format_for("frames"), MovieFormat::PngFolder);
  EXPECT_EQ(movie_format_for("take2.5/"), MovieFormat::PngFolder);
  fs::create_directory(dir / "folder.mp4");
  EXPECT_EQ(movie_format_for(dir / "folder.mp4"), MovieFormat::PngFolder);
  try {
    movie_format_for("take.gif");
    FAIL() << ".gif was taken";
  } catch (const RenderError& e) {
    EXPECT_STREQ(e.what(),
                 "take.gif: unknown movie type '.gif' (use .mp4, .avi, or a folder name for numbered PNG frames)");
  }
}

TEST(MovieWriter, OnlyNewFilesAndFoldersOfFramesAreWritten) {
  test::TempDir dir;
  EXPECT_EQ(refusal(dir / "new.mp4"), "accepted");
  test::write_text(dir / "old.avi", "an earlier movie");
  EXPECT_EQ(refusal(dir / "old.avi"), "accepted");  // a regular file is replaced
  EXPECT_EQ(refusal(dir / "frames/"), "accepted");
  fs::create_directory(dir / "frames");
  test::write_text(dir / "frames/frame_00000.png", "");
  EXPECT_EQ(refusal(dir / "frames"), "accepted");  // an earlier run's frames
  test::write_text(dir / "frames/notes.txt", "mine");
  EXPECT_EQ(refusal(dir / "frames/"),
            (dir / "frames").string() +
                ": the folder holds 'notes.txt', which csrbf did not write; frames go only into a new or empty folder, "
                "or one that holds only frame_NNNNN.png files (an earlier run's frames, which are replaced); nothing "
                "was changed");
  EXPECT_EQ(refusal(dir / "missing" / "frames"),
            (dir / "missing" / "frames").string() + ": the folder '" + (dir / "missing").string() + "' does not exist");
  ASSERT_EQ(::mkfifo((dir / "pipe.mp4").c_str(), 0644), 0);
  EXPECT_NE(refusal(dir / "pipe.mp4"), "accepted");  // never replaced
  // The target: a folder without its slash, a movie through its link.
  EXPECT_EQ(movie_target(dir / "frames/"), dir / "frames");
  fs::create_symlink(dir / "old.avi", dir / "link.avi");
  EXPECT_EQ(fs::canonical(movie_target(dir / "link.avi")), fs::canonical(dir / "old.avi"));
}

TEST(MovieWriter, FramesReadBackAsWritten) {
  test::TempDir dir;
  ASSERT_EQ(write_movie(dir / "frames", 3), 3u);
  EXPECT_EQ(test::files_in(dir / "frames"), 3u);
  for (int k = 0; k < 3; ++k) {
    const auto want = frame(k);
    EXPECT_EQ(test::decoded_rgb(dir / "frames" / ("frame_0000" + std::to_string(k) + ".png")),
              std::string(want.begin(), want.end()))
        << "frame " << k;
  }
  ASSERT_EQ(write_movie(dir / "take.avi", 3), 3u);  // full, uncompressed frames
  EXPECT_EQ(test::decoded_rgb(dir / "take.avi"), frames(3));
  ASSERT_EQ(write_movie(dir / "take.mp4", 3), 3u);  // H.264: lossy, but every frame there at its size
  Child probe({"ffprobe", "-v", "error", "-select_streams", "v:0", "-count_frames", "-show_entries",
               "stream=width,height,nb_read_frames", "-of", "csv=p=0", (dir / "take.mp4").string()},
              false, -1, true);
  ASSERT_EQ(probe.finish(), 0) << probe.error_output();
  EXPECT_EQ(probe.output(), "16,16,3\n");
  EXPECT_EQ(test::files_in(dir.path), 3u);  // no partial files left beside them
}

TEST(MovieWriter, SizesAndRatesOutOfRangeAreRefused) {
  test::TempDir dir;
  const auto refused = [&](const fs::path& out, int w, int h, double fps) {
    try {
      MovieWriter writer(out, w, h, fps);
    } catch (const RenderError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(refused(dir / "a.mp4", 17, 16, 10), "H.264 (.mp4) needs an even width and height, got 17x16");
  EXPECT_EQ(refused(dir / "a.avi", 8, 16, 10), "frame size 8x16 is out of range (16 to 16384 pixels a side)");
  EXPECT_EQ(refused(dir / "a.avi", 16, 16, 0), "fps must be a finite number > 0");
  EXPECT_EQ(test::files_in(dir.path), 0u);
}

TEST(MovieWriter, NothingIsWrittenWithoutASuccessfulFinish) {
  test::TempDir dir;
  {
    MovieWriter w(dir / "dropped.avi", 16, 16, 10);
    EXPECT_TRUE(w.write(frame(0).data()));
  }  // destroyed unfinished
  {
    MovieWriter w(dir / "cancelled", 16, 16, 10);
    EXPECT_TRUE(w.write(frame(0).data()));
    w.set_cancel([] { return true; });
    EXPECT_FALSE(w.finish());
    EXPECT_EQ(w.frames(), 1u);
  }
  EXPECT_EQ(test::files_in(dir.path), 0u);
}
