// `csrbf animate` end to end: scenes to movies, checked with ffprobe and by reading frames back.
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

extern char** environ;

namespace fs = std::filesystem;
using csrbf::test::read_text;
using csrbf::test::TempDir;
using csrbf::test::write_text;

namespace {

using Shell = csrbf::test::ShellRun;
Shell shell(const std::string& cmd) { return csrbf::test::run_shell(cmd); }

const std::string kCli = CSRBF_CLI;
const std::string kExamples = std::string(CSRBF_SOURCE_DIR) + "/examples/";

/// "env -u DISPLAY csrbf animate ..." : no display, as on a server.
Shell animate(const std::string& args) { return shell("env -u DISPLAY " + kCli + " animate " + args); }

struct Probe {
  std::string codec;
  int width = 0, height = 0, frames = 0;
};

Probe probe(const fs::path& movie) {
  const Shell r = shell(
      "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
      "stream=codec_name,width,height,nb_read_frames -of csv=p=0 '" +
      movie.string() + "'");
  Probe p;
  char codec[64] = {};
  if (std::sscanf(r.out.c_str(), "%63[^,],%d,%d,%d", codec, &p.width, &p.height, &p.frames) == 4) p.codec = codec;
  return p;
}

/// Every frame of a movie (or the PNG frames of a folder), decoded by ffmpeg to RGB.
std::vector<std::vector<unsigned char>> frames_of(const std::string& input, int w, int h) {
  const Shell r = shell("ffmpeg -v error -i '" + input + "' -f rawvideo -pix_fmt rgb24 -");
  const std::size_t size = std::size_t(w) * std::size_t(h) * 3;
  std::vector<std::vector<unsigned char>> out;
  for (std::size_t at = 0; at + size <= r.out.size(); at += size)
    out.emplace_back(r.out.begin() + std::ptrdiff_t(at), r.out.begin() + std::ptrdiff_t(at + size));
  return out;
}

/// Share of pixels differing from the frame's corner (the background) by more than 30 levels.
double covered(const std::vector<unsigned char>& f) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < f.size(); i += 3)
    n += std::abs(int(f[i]) - int(f[0])) + std::abs(int(f[i + 1]) - int(f[1])) + std::abs(int(f[i + 2]) - int(f[2])) >
         30;
  return double(n) / double(f.size() / 3);
}

/// Mean absolute difference of two frames, in levels.
double difference(const std::vector<unsigned char>& a, const std::vector<unsigned char>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += std::abs(int(a[i]) - int(b[i]));
  return s / double(a.size());
}

std::size_t entries(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

}  // namespace

TEST(Animate, EachExampleRendersAMovieThatMoves) {
  TempDir dir;
  // 0.4 s at 25 fps: 11 frames.
  std::size_t made = 0;
  for (const std::string name : {"fish", "face", "ball"}) {
    const fs::path out = dir / (name + ".mp4");
    const Shell r = animate(kExamples + name + ".scene.json -o " + out.string() + " --size 192x144 --to 0.4");
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("frames: 11"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("computation:"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("rendering:"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("private X display"), std::string::npos) << r.out;  // DISPLAY was unset
    const Probe p = probe(out);
    EXPECT_EQ(p.codec, "h264") << name;
    EXPECT_EQ(p.width, 192);
    EXPECT_EQ(p.height, 144);
    EXPECT_EQ(p.frames, 11) << name;
    const auto frames = frames_of(out.string(), 192, 144);
    ASSERT_EQ(frames.size(), 11u) << name;
    for (const auto& f : frames) {
      EXPECT_GT(covered(f), 0.01) << name << ": a frame is blank";
    }
    // The object moved (and deformed) between the first and the last frame.
    EXPECT_GT(difference(frames.front(), frames.back()), 0.5) << name;
    EXPECT_EQ(entries(dir.path), ++made) << "temporary files left behind";
  }
}

TEST(Animate, FullFrameAviAndPngFolder) {
  TempDir dir;
  const Shell avi = animate(kExamples + "ball.scene.json -o " + (dir / "ball.avi").string() +
                            " --size 96x64 --fps 10 --from 0.5 --to 1.0");
  ASSERT_EQ(avi.code, 0) << avi.out;
  const Probe p = probe(dir / "ball.avi");
  EXPECT_EQ(p.codec, "rawvideo");
  EXPECT_EQ(p.frames, 6);
  EXPECT_EQ(p.width, 96);
  // Uncompressed: at least the frames' bytes.
  EXPECT_GE(fs::file_size(dir / "ball.avi"), std::uintmax_t(6 * 96 * 64 * 3));

  const Shell png =
      animate(kExamples + "fish.scene.json -o " + (dir / "frames/").string() + " --size 96x64 --fps 5 --to 1");
  ASSERT_EQ(png.code, 0) << png.out;
  ASSERT_TRUE(fs::is_directory(dir / "frames"));
  EXPECT_EQ(entries(dir / "frames"), 6u);
  EXPECT_EQ(read_text(dir / "frames" / "frame_00000.png").substr(1, 3), "PNG");
  const auto a = frames_of((dir / "frames" / "frame_00000.png").string(), 96, 64);
  const auto b = frames_of((dir / "frames" / "frame_00005.png").string(), 96, 64);
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_GT(difference(a[0], b[0]), 0.5);
  // A file csrbf did not write in the folder: refused, and nothing in it changes.
  write_text(dir / "frames" / "notes.txt", "mine");
  const Shell refused =
      animate(kExamples + "fish.scene.json -o " + (dir / "frames").string() + " --size 96x64 --fps 5 --to 0.4");
  EXPECT_EQ(refused.code, 1) << refused.out;
  EXPECT_NE(refused.out.find("notes.txt"), std::string::npos) << refused.out;
  EXPECT_EQ(entries(dir / "frames"), 7u);
  EXPECT_EQ(read_text(dir / "frames" / "notes.txt"), "mine");
  // Frames of an earlier run are replaced whole, only at the end.
  fs::remove(dir / "frames" / "notes.txt");
  ASSERT_EQ(
      animate(kExamples + "fish.scene.json -o " + (dir / "frames").string() + " --size 96x64 --fps 5 --to 0.4").code,
      0);
  EXPECT_EQ(entries(dir / "frames"), 3u);
  EXPECT_EQ(entries(dir.path), 2u);
}

TEST(Animate, UsesAnExistingDisplay) {
  TempDir dir;
  const Shell r =
      shell("bash " + std::string(CSRBF_SOURCE_DIR) + "/tests/with-xvfb.sh 1280x1024x24 " + kCli + " animate " +
            kExamples + "face.scene.json -o " + (dir / "f.mp4").string() + " --size 64x64 --to 0.1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("private X display"), std::string::npos) << r.out;
  EXPECT_EQ(probe(dir / "f.mp4").frames, 3);
}

TEST(Animate, BadInputFailsAndWritesNothing) {
  TempDir dir;
  write_text(dir / "keep.mp4", "precious");
  const std::string scene = kExamples + "fish.scene.json";
  struct Case {
    std::string args, words;
    int code;
  };
  const std::vector<Case> cases{
      {scene + " -o " + (dir / "x.mov").string(), "unknown movie type '.mov'", 1},
      {scene + " -o " + (dir / "nowhere" / "x.mp4").string(), "does not exist", 1},
      {scene + " -o " + (dir / "x.mp4").string() + " --size 101x100", "even width and height", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --size big", "--size", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --size 4294967312x4294967312", "--size", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --from 2 --to 1", "--from 2 is after --to 1", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --to inf", "--to", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --from -inf", "--from", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --from -1e300 --to 1e300", "--from", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --to 1e5", "at most 1e+06", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --fps nan", "--fps", 2},
      {scene + " -o " + (dir / "x.mp4").string() + " --fps 0", "--fps", 2},
      {kExamples + "missing.scene.json -o " + (dir / "keep.mp4").string(), "missing.scene.json", 1},
      {kExamples + "fish.obj -o " + (dir / "keep.mp4").string(), "not valid JSON", 1},
  };
  for (const auto& c : cases) {
    const Shell r = animate(c.args);
    EXPECT_EQ(r.code, c.code) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.words), std::string::npos) << c.args << "\n" << r.out;
  }
  // A scene error names the JSON path, and the existing movie is untouched.
  write_text(dir / "bad.json", R"({"duration": 1, "objects": [{"mesh": ")" + kExamples +
                                   R"(fish.obj", "parts": [{"colour": [1,0,0]}]}]})");
  const Shell r = animate((dir / "bad.json").string() + " -o " + (dir / "keep.mp4").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("objects[0].parts[0].colour: unknown key"), std::string::npos) << r.out;
  EXPECT_EQ(read_text(dir / "keep.mp4"), "precious");
  EXPECT_EQ(entries(dir.path), 2u);  // keep.mp4 and bad.json: nothing else appeared
}

TEST(Animate, AFullDiskLeavesNothing) {
  TempDir dir;
  write_text(dir / "keep.avi", "precious");
  // A file size limit of 100 KiB (inherited by ffmpeg) stands in for a full disk: the AVI of 20
  // frames of 96x64 needs 370 KiB.
  const Shell r = shell("ulimit -f 100; env -u DISPLAY " + kCli + " animate " + kExamples + "ball.scene.json -o " +
                        (dir / "keep.avi").string() + " --size 96x64 --to 0.8");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("ffmpeg"), std::string::npos) << r.out;
  EXPECT_EQ(read_text(dir / "keep.avi"), "precious");
  EXPECT_EQ(entries(dir.path), 1u);
}

namespace {
/// csrbf animate SCENE -o OUT started in the background, its output going to log; returns its pid
/// once it prints its first frame (0 when it never does within 60 s).
pid_t start_animate(const std::string& scene, const fs::path& out, const fs::path& log) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  std::vector<std::string> args{kCli, "animate", scene, "-o", out.string()};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, kCli.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) return 0;
  for (int i = 0; i < 600; ++i) {  // up to 60 s for the first progress line
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (read_text(log).find("frame ") != std::string::npos) return pid;
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  return 0;
}
}  // namespace

TEST(Animate, CtrlCStopsCleanly) {
  TempDir dir;
  const fs::path out = dir / "fish.mp4", log = dir.path.parent_path() / (dir.path.filename().string() + ".log");
  // The whole 8 s fish at 640x480 takes seconds: interrupt it once frames are flowing.
  const pid_t pid = start_animate(kExamples + "fish.scene.json", out, log);
  ASSERT_NE(pid, 0) << read_text(log);
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  const std::string text = read_text(log);
  fs::remove(log);
  ASSERT_TRUE(WIFEXITED(status)) << text;
  EXPECT_EQ(WEXITSTATUS(status), 130) << text;
  EXPECT_NE(text.find("interrupted"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(entries(dir.path), 0u) << "a partial movie was left behind";
}

TEST(Animate, AMovieMadeMeanwhileIsNeverReplaced) {
  // The output did not exist when animate started; another program makes it while frames render:
  // animate fails naming it, and the other program's movie (or frame folder) is kept.
  for (const std::string name : {"fish.mp4", "frames"}) {
    TempDir dir;
    const fs::path out = dir / name, log = dir.path.parent_path() / (dir.path.filename().string() + ".log");
    const pid_t pid = start_animate(kExamples + "fish.scene.json", out, log);
    ASSERT_NE(pid, 0) << read_text(log);
    const fs::path theirs = name == "frames" ? out / "frame_00000.png" : out;
    if (name == "frames") fs::create_directory(out);
    write_text(theirs, "theirs");
    int status = 0;
    waitpid(pid, &status, 0);
    const std::string text = read_text(log);
    fs::remove(log);
    ASSERT_TRUE(WIFEXITED(status)) << text;
    EXPECT_EQ(WEXITSTATUS(status), 1) << name << ": " << text;
    EXPECT_NE(text.find(out.string()), std::string::npos) << text;
    EXPECT_TRUE(text.find("it exists") != std::string::npos || text.find("another program") != std::string::npos)
        << text;
    EXPECT_EQ(read_text(theirs), "theirs") << name;
    EXPECT_EQ(entries(dir.path), 1u) << name << ": a partial was left behind";
    if (name == "frames") EXPECT_EQ(entries(out), 1u);
  }
}
