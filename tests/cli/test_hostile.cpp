// The adversarial catalogue (issue 15): inputs and situations an attacker, a full disk or a killed
// process makes. Each case fails cleanly (exit 1 for bad data, 2 for usage, a message naming the
// file, line, field or option and the value) or works as a user would expect; no run leaves a file,
// folder or process behind except its complete output, and nothing that existed before a failed
// run changes.
#include "cli/catalogue.hpp"
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <fcntl.h>
#include <random>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace csrbf::test;

namespace {

const std::string kFish = kExamples + "fish.obj";
const std::string kFishControls = kExamples + "fish.controls";

/// Every entry of a folder, names and sizes, to compare before and after a run.
std::string listing(const fs::path& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::error_code ec;
    const auto size = e.is_regular_file(ec) ? fs::file_size(e.path(), ec) : 0;
    v.push_back(e.path().filename().string() + ":" + std::to_string(size));
  }
  std::sort(v.begin(), v.end());
  std::string s;
  for (const auto& x : v) s += x + "\n";
  return s;
}

void le32(std::string& s, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) s.push_back(char((v >> (8 * k)) & 0xff));
}
void lef(std::string& s, float f) {
  std::uint32_t v;
  std::memcpy(&v, &f, 4);
  le32(s, v);
}

/// A binary STL of the given triangles (9 floats each).
std::string binary_stl(const std::vector<std::array<float, 9>>& tris) {
  std::string s(80, '\0');
  le32(s, std::uint32_t(tris.size()));
  for (const auto& t : tris) {
    for (int k = 0; k < 3; ++k) lef(s, 0.0f);
    for (float f : t) lef(s, f);
    s += std::string(2, '\0');
  }
  return s;
}

bool process_alive(pid_t pid) {
  const std::string stat = read_text("/proc/" + std::to_string(pid) + "/stat");
  if (stat.empty()) return false;
  const auto close = stat.rfind(')');
  return close != std::string::npos && close + 2 < stat.size() && stat[close + 2] != 'Z';
}

/// Pids of processes whose command line contains `what` and whose parent is `parent`.
std::vector<pid_t> children_of(pid_t parent) {
  std::vector<pid_t> out;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const std::string stat = read_text(e.path() / "stat");
    const auto close = stat.rfind(')');
    if (close == std::string::npos) continue;
    char state = 0;
    int ppid = 0;
    if (std::sscanf(stat.c_str() + close + 2, "%c %d", &state, &ppid) == 2 && ppid == parent && state != 'Z')
      out.push_back(pid_t(std::stoi(name)));
  }
  return out;
}

}  // namespace

TEST(Hostile, BadFilesAndNumbers) {
  TempDir dir;
  const std::string d = dir.path.string();
  write_text(dir / "ok.controls", "0.5 0.5 0.5  0.5 0.5 0.6\n");
  // PLY headers that lie.
  const std::string ply_head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  write_text(dir / "hugeface.ply", ply_head +
                                       "element face 1000000000000\nproperty list uchar int "
                                       "vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  write_text(dir / "junk.ply", ply_head + "element junk 1000000000000000\nend_header\n0 0 0\n1 0 0\n0 1 0\n");
  write_text(dir / "junkb.ply",
             "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty "
             "float z\nelement junk 1000000000000000\nproperty uchar a\nend_header\n" +
                 std::string(12, '\0'));
  write_text(dir / "twice.ply", ply_head +
                                    "element vertex 3\nproperty float x\nproperty float y\nproperty float "
                                    "z\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 0\n1 0 0\n0 1 0\n");
  write_text(dir / "trailing.ply", ply_head + "end_header\n0 0 0\n1 0 0\n0 1 0\n7 7 7\n");
  write_text(dir / "face0.ply",
             ply_head + "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0\n");
  write_text(
      dir / "floatcount.ply",
      ply_head + "element face 1\nproperty list float int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  // OFF.
  write_text(dir / "face2.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n");
  write_text(dir / "hugecount.off", "OFF\n18446744073709551615 1 0\n0 0 0\n");
  write_text(dir / "hugeface.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n18446744073709551615 0 1 2\n");
  // STL and glTF through assimp with NaN.
  write_text(dir / "nan.stl", binary_stl({{0, 0, 0, 1, 0, 0, NAN, 1, 0}}));
  write_text(
      dir / "nolist.ply",
      ply_head + "element face 1\nproperty list uchar int vertex_indexes\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  write_text(dir / "cr.obj", "v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r");
  write_text(dir / "a.smd", "version 1\n");
  write_text(dir / "far.obj", "v 0 0 0\nv 1e300 0 0\nv 0 1 0\nf 1 2 3\n");
  write_text(dir / "dup.json", "{\"radius\": -1, \"radius\": 1}");
  write_text(dir / "nul.controls", std::string("0 0 0 1\0"
                                               "0 0 0\n",
                                               14));
  // Numbers in controls.
  write_text(dir / "plusminus.controls", "0.5 0.5 0.5 +-0.5 0.5 0.6\n");
  write_text(dir / "longline.controls", std::string(200000, '1') + "\n");
  // JSON nested 70 000 deep.
  write_text(dir / "deep.json",
             "{\"radius\": 1, \"sources\": " + std::string(70000, '[') + std::string(70000, ']') + "}");
  write_text(dir / "deep.scene.json",
             "{\"duration\": 1, \"objects\": " + std::string(70000, '[') + std::string(70000, ']') + "}");
  const std::string deform = "deform --mesh " + kFish + " --radius 0.3 -o {dir}/out.obj --controls ";
  const auto mesh = [](const std::string& m) {
    return "deform --mesh {dir}/" + m + " --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj";
  };
  const std::vector<Case> cases{
      {"PLY face count beyond the file", mesh("hugeface.ply"), "declares 1000000000000 entries", 1},
      {"PLY element without properties", mesh("junk.ply"),
       "element 'junk' has 1000000000000000 entries but no properties", 1},
      {"binary PLY element count beyond the file", mesh("junkb.ply"), "can hold at most", 1},
      {"PLY element twice", mesh("twice.ply"), "element 'vertex' twice", 1},
      {"PLY trailing data", mesh("trailing.ply"), "trailing.ply:11: trailing data", 1},
      {"PLY face of 0 vertices", mesh("face0.ply"), "face0.ply:13: a face has 0 vertices", 1},
      {"PLY float list count", mesh("floatcount.ply"), "must have integer count", 1},
      {"OFF face of 2 vertices", mesh("face2.off"), "face2.off:6: a face has 2 vertices", 1},
      {"OFF count 2^64-1", mesh("hugecount.off"), "the file has only 3 lines", 1},
      {"OFF face of 2^64-1 vertices", mesh("hugeface.off"), "hugeface.off:6: bad face", 1},
      {"NaN vertex in a binary STL", mesh("nan.stl"), "nan.stl: mesh 0 vertex", 1},
      {"PLY face element without its vertex list", mesh("nolist.ply"), "has no list property 'vertex_indices'", 1},
      {"old Mac line endings", mesh("cr.obj"), "cr.obj:1: a carriage return inside the line", 1},
      {"a format only assimp reads", mesh("a.smd"), "unknown mesh format '.smd'", 1},
      {"a vertex beyond float for STL",
       "deform --mesh {dir}/far.obj --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.stl",
       "beyond the single precision", 1},
      {"a key twice", "deform --mesh " + kFish + " --deformation {dir}/dup.json -o {dir}/out.obj",
       "the key \"radius\" appears twice", 1},
      {"a NUL in controls", deform + "{dir}/nul.controls", "nul.controls:1: '1\\x000' is not a number", 1},
      {"an ordering for a solver that orders itself",
       "deform --mesh " + kFish +
           " --controls {dir}/ok.controls --radius 0.3 --solver eigen --ordering identity -o {dir}/out.obj",
       "--ordering identity: solver 'eigen' orders the matrix itself", 2},
      {"unknown output format",
       "deform --mesh " + kFish + " --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.foo",
       "unknown output format '.foo'", 2},
      {"+-0.5 in controls", deform + "{dir}/plusminus.controls", "plusminus.controls:1: '+-0.5' is not a number", 1},
      {"a 200 kB line", deform + "{dir}/longline.controls", "longline.controls:1: line longer than 65536 bytes", 1},
      {"deformation nested 70000 deep", "deform --mesh " + kFish + " --deformation {dir}/deep.json -o {dir}/out.obj",
       "deep.json: JSON nested deeper than 64 levels", 1},
      {"scene nested 70000 deep", "animate {dir}/deep.scene.json -o {dir}/out.mp4",
       "deep.scene.json: JSON nested deeper than 64", 1},
      // Usage: every number checked, exit 2 with the option named.
      {"--radius 1e151", deform + "{dir}/ok.controls --radius 1e151",
       "--radius must be a finite number in [1e-150, 1e+150], got '1e151'", 2},
      {"--phase nan", deform + "{dir}/ok.controls --phase nan", "--phase must be a finite number", 2},
      {"--memory-limit nan", deform + "{dir}/ok.controls --memory-limit nan", "--memory-limit must be a finite number",
       2},
      {"--memory-limit inf", deform + "{dir}/ok.controls --memory-limit inf", "--memory-limit", 2},
      {"info --phase 1e300",
       "info --controls {dir}/ok.controls --radius 0.3 --mesh " + kFish + " --check-folds --phase 1e300", "--phase", 2},
      {"bench --seconds nan", "bench --scenario fish --seconds nan", "--seconds", 2},
      {"animate --to inf", "animate " + kExamples + "fish.scene.json -o {dir}/out.mp4 --to inf", "--to", 2},
      {"animate --to 1e7", "animate " + kExamples + "fish.scene.json -o {dir}/out.mp4 --to 1e7", "--to", 2},
      {"animate --fps nan", "animate " + kExamples + "fish.scene.json -o {dir}/out.mp4 --fps nan", "--fps", 2},
      {"animate --size overflow",
       "animate " + kExamples + "fish.scene.json -o {dir}/out.mp4 --size 4294967312x4294967312", "--size", 2},
  };
  write_text(dir / "keep.obj", "precious");
  for (const auto& c : cases) {
    const std::string before = listing(dir.path);
    const auto r = run_shell("env -u DISPLAY " + kCli + " " + expand(c.args, d));
    EXPECT_EQ(r.code, c.code) << c.name << "\n" << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.name << ": the message should say '" << c.message << "'\n"
                                                        << r.out.substr(0, 2000);
    EXPECT_LT(r.out.size(), 2000u) << c.name << ": the message is not cut";
    EXPECT_EQ(listing(dir.path), before) << c.name << ": the folder changed";
  }
}

TEST(Hostile, OutputsThatAreNotOurs) {
  TempDir dir;
  const std::string d = dir.path.string();
  ASSERT_EQ(mkfifo((dir / "fifo.obj").c_str(), 0644), 0);
  ASSERT_EQ(mkfifo((dir / "fifo.mp4").c_str(), 0644), 0);
  write_text(dir / "Makefile", "all:\n");
  fs::create_directory(dir / "notes");
  write_text(dir / "notes" / "todo.txt", "mine");
  const std::string deform = "deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o ";
  const std::string anim = "animate " + kExamples + "fish.scene.json --size 64x48 --to 0.1 -o ";
  const std::vector<Case> cases{
      {"deform onto a FIFO", deform + "{dir}/fifo.obj", "is not a regular file", 1},
      {"deform onto a character device", deform + "/dev/null", "/dev/null': it exists and is not a regular file", 1},
      {"animate onto a FIFO", anim + "{dir}/fifo.mp4", "is not a regular file", 1},
      {"animate onto an extensionless file", anim + "{dir}/Makefile", "Makefile: exists and is not a folder", 1},
      {"animate into a folder of the user's", anim + "{dir}/notes", "the folder holds 'todo.txt'", 1},
      {"animate into the scene's own folder",
       "animate " + kExamples + "fish.scene.json --size 64x48 --to 0.1 -o " + kExamples, "which csrbf did not write",
       1},
  };
  for (const auto& c : cases) {
    const std::string before = listing(dir.path), notes = listing(dir / "notes"), examples = listing(kExamples);
    const auto r = run_shell("env -u DISPLAY " + kCli + " " + expand(c.args, d));
    EXPECT_EQ(r.code, c.code) << c.name << "\n" << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.name << "\n" << r.out;
    EXPECT_EQ(listing(dir.path), before) << c.name;
    EXPECT_EQ(listing(dir / "notes"), notes) << c.name;
    EXPECT_EQ(listing(kExamples), examples) << c.name;
  }
  struct stat st {};
  ASSERT_EQ(stat((dir / "fifo.obj").c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_EQ(read_text(dir / "Makefile"), "all:\n");
  // A replaced file keeps its permissions; a symbolic link stays a link and its file is replaced.
  write_text(dir / "mine.obj", "old");
  fs::permissions(dir / "mine.obj", fs::perms::owner_read | fs::perms::owner_write);
  fs::create_symlink("mine.obj", dir / "link.obj");
  ASSERT_EQ(run_shell(kCli + " " + deform + d + "/link.obj").code, 0);
  EXPECT_TRUE(fs::is_symlink(dir / "link.obj"));
  EXPECT_GT(fs::file_size(dir / "mine.obj"), 1000u);
  EXPECT_EQ(fs::status(dir / "mine.obj").permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
  // glTF's side file: a .bin of someone else's is not replaced; the .bin of an earlier .gltf is.
  write_text(dir / "model.bin", "my firmware");
  const auto g = run_shell(kCli + " " + deform + d + "/model.gltf");
  EXPECT_EQ(g.code, 1) << g.out;
  EXPECT_NE(g.out.find("model.bin' exists and is not the side file"), std::string::npos) << g.out;
  EXPECT_EQ(read_text(dir / "model.bin"), "my firmware");
  EXPECT_FALSE(fs::exists(dir / "model.gltf"));
  fs::remove(dir / "model.bin");
  ASSERT_EQ(run_shell(kCli + " " + deform + d + "/model.gltf").code, 0);
  const auto again = run_shell(kCli + " " + deform + d + "/model.gltf");
  EXPECT_EQ(again.code, 0) << again.out;
  // Usage found late is still usage: an odd size for H.264, a mesh for info without --check-folds.
  const auto odd = run_shell("env -u DISPLAY " + kCli + " " + anim + d + "/odd.mp4 --size 321x240");
  EXPECT_EQ(odd.code, 2) << odd.out;
  const auto info = run_shell(kCli + " info --controls " + kFishControls + " --radius 0.3 --mesh nope.obj");
  EXPECT_EQ(info.code, 2) << info.out;
  // A name of 240 characters is valid: its partial's name must stay within 255.
  const std::string long_name = std::string(236, 'n') + ".obj";
  const auto r = run_shell(kCli + " " + deform + d + "/" + long_name);
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::is_regular_file(dir / long_name));
}

TEST(Hostile, StlAndBomInputsWork) {
  TempDir dir;
  const std::string d = dir.path.string();
  // STL in, STL out (binary and ASCII): works, and the copies of each vertex are joined.
  ASSERT_EQ(run_shell(kCli + " deform --mesh " + kFish + " --controls " + kFishControls +
                      " --radius 0.3 --phase 0 -o " + d + "/a.stl")
                .code,
            0);
  const auto r = run_shell(kCli + " deform --mesh " + d + "/a.stl --controls " + kFishControls + " --radius 0.3 -o " +
                           d + "/b.stl");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("977 vertices"), std::string::npos) << r.out;
  EXPECT_EQ(fs::file_size(dir / "b.stl"), fs::file_size(dir / "a.stl"));
  write_text(dir / "ascii.stl",
             "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 "
             "0\nendloop\nendfacet\nendsolid t\n");
  const auto a = run_shell(kCli + " deform --mesh " + d + "/ascii.stl --controls " + kFishControls +
                           " --radius 0.3 -o " + d + "/c.stl");
  EXPECT_EQ(a.code, 0) << a.out;
  EXPECT_EQ(fs::file_size(dir / "c.stl"), 84u + 50u);
  // An OBJ with a UTF-8 byte order mark keeps its first vertex, and its mark.
  write_text(dir / "bom.obj", "\xEF\xBB\xBFv 0.5 0.5 0.5\nv 0.6 0.5 0.5\nv 0.5 0.6 0.5\nf 1 2 3\n");
  write_text(dir / "c.controls", "0.5 0.5 0.5 0.5 0.5 0.6\n");
  const auto b = run_shell(kCli + " deform --mesh " + d + "/bom.obj --controls " + d + "/c.controls --radius 0.3 -o " +
                           d + "/bom2.obj");
  EXPECT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("3 vertices"), std::string::npos) << b.out;
  EXPECT_EQ(read_text(dir / "bom2.obj").substr(0, 16), "\xEF\xBB\xBFv 0.5 0.5 0.6");
  // 1e-400 is 0, as C reads it; 4.9e-324 as well as before.
  write_text(dir / "tiny.controls", "0.5 0.5 0.5 0.5 0.5 0.6\n1e-400 0 0 4.9e-324 0 0\n");
  const auto t = run_shell(kCli + " info --controls " + d + "/tiny.controls --radius 0.3");
  EXPECT_EQ(t.code, 0) << t.out;
}

TEST(Hostile, FloodsAreSummarised) {
  TempDir dir;
  std::string text;
  for (int i = 0; i < 100000; ++i) text += "0.5 0.5 0.5 0.5 0.5 0.6\n";
  write_text(dir / "dup.controls", text);
  const auto r = run_shell(kCli + " info --controls " + (dir / "dup.controls").string() + " --radius 0.3");
  EXPECT_EQ(r.code, 0) << r.out.substr(0, 2000);
  EXPECT_LT(r.out.size(), 5000u);
  EXPECT_NE(r.out.find("99989 more duplicate lines merged (99999 in all)"), std::string::npos) << r.out.substr(0, 3000);
  // A 50 MB line is not echoed whole.
  write_text(dir / "wide.obj", "v 0 0 " + std::string(50'000'000, 'x') + "\n");
  const auto w = run_shell(kCli + " deform --mesh " + (dir / "wide.obj").string() + " --controls " + kFishControls +
                           " --radius 0.3 -o " + (dir / "o.obj").string());
  EXPECT_EQ(w.code, 1);
  EXPECT_LT(w.out.size(), 1000u);
  EXPECT_NE(w.out.find("wide.obj:1:"), std::string::npos) << w.out;
}

TEST(Hostile, HangsAreBounded) {
  TempDir dir;
  // A FIFO nobody writes to: an error after CSRBF_PIPE_TIMEOUT, not a hang.
  ASSERT_EQ(mkfifo((dir / "c.fifo").c_str(), 0644), 0);
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = run_shell("CSRBF_PIPE_TIMEOUT=2 timeout 60 " + kCli + " info --radius 0.3 --controls " +
                           (dir / "c.fifo").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("c.fifo: nothing was written to this FIFO in 2 s"), std::string::npos) << r.out;
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30));
  // A pipe with a writer still works.
  const auto p = run_shell("bash -c '" + kCli + " info --radius 0.3 --controls <(echo 0.5 0.5 0.5 0.5 0.5 0.6)'");
  EXPECT_EQ(p.code, 0) << p.out;
  // 2000 lights are refused with the field named.
  std::string lights = "[";
  for (int i = 0; i < 2000; ++i) lights += std::string(i ? "," : "") + "{\"headlight\": true}";
  lights += "]";
  write_text(dir / "lights.json",
             "{\"duration\": 1, \"lights\": " + lights + ", \"objects\": [{\"mesh\": \"" + kFish + "\"}]}");
  const auto l = run_shell("env -u DISPLAY " + kCli + " animate " + (dir / "lights.json").string() + " -o " +
                           (dir / "l.mp4").string());
  EXPECT_EQ(l.code, 1) << l.out;
  EXPECT_NE(l.out.find("lights: at most 16 lights"), std::string::npos) << l.out;
  // An ffmpeg that stops reading (a stand-in that sleeps) fails after the timeout, leaves nothing,
  // and is not left running.
  fs::create_directory(dir / "bin");
  write_text(dir / "bin" / "ffmpeg", "#!/bin/sh\nexec sleep 600\n");
  fs::permissions(dir / "bin" / "ffmpeg", fs::perms::owner_all);
  const auto f =
      run_shell("PATH=" + (dir / "bin").string() + ":$PATH CSRBF_PIPE_TIMEOUT=2 env -u DISPLAY timeout 120 " + kCli +
                " animate " + kExamples + "fish.scene.json --size 320x240 --to 1 -o " + (dir / "s.mp4").string());
  EXPECT_EQ(f.code, 1) << f.out;
  EXPECT_NE(f.out.find("ffmpeg stopped reading frames for 2 s"), std::string::npos) << f.out;
  EXPECT_FALSE(fs::exists(dir / "s.mp4"));
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".csrbf-partial-"), std::string::npos) << e.path();
  EXPECT_EQ(run_shell("pgrep -f 'slee[p] 600'").code, 1) << "the stalled child is still running";
  // An ffmpeg that reads every frame but never exits: an error after the timeout, not a hang; and
  // a Ctrl-C while it is awaited stops the run (exit 130) with the old movie kept.
  write_text(dir / "bin" / "ffmpeg", "#!/bin/sh\ncat > /dev/null\nexec sleep 601\n");
  write_text(dir / "keep.mp4", "old movie");
  const std::string env = "PATH=" + (dir / "bin").string() + ":$PATH env -u DISPLAY ";
  const std::string run =
      kCli + " animate " + kExamples + "fish.scene.json --size 64x48 --to 0.2 -o " + (dir / "keep.mp4").string();
  const auto n = run_shell(env + "CSRBF_PIPE_TIMEOUT=2 timeout 120 " + run);
  EXPECT_EQ(n.code, 1) << n.out;
  EXPECT_NE(n.out.find("ffmpeg did not finish within 2 s of the last frame"), std::string::npos) << n.out;
  const auto c =
      run_shell("(" + env + run + " > /dev/null 2>&1 & p=$!; sleep 4; kill -INT $p; wait $p; echo status=$?)");
  EXPECT_NE(c.out.find("status=130"), std::string::npos) << c.out;
  EXPECT_EQ(read_text(dir / "keep.mp4"), "old movie");
  EXPECT_EQ(run_shell("pgrep -f 'slee[p] 601'").code, 1) << "the child is still running";
}

TEST(Hostile, TexturesAreCheckedBeforeDecoding) {
  TempDir dir;
  // A PNG whose header declares 30000 x 30000 pixels, and one of 100000 x 100000.
  const auto png = [](std::uint32_t w, std::uint32_t h) {
    std::string s = "\x89PNG\r\n\x1a\n";
    s += std::string("\0\0\0\x0dIHDR", 8);
    for (std::uint32_t v : {w, h})
      for (int k = 3; k >= 0; --k) s.push_back(char((v >> (8 * k)) & 0xff));
    s += std::string("\x08\x02\0\0\0", 5) + std::string(4, '\0');
    return s;
  };
  write_text(dir / "big.png", png(30000, 30000));
  write_text(dir / "huge.png", png(100000, 100000));
  for (const std::string t : {"big.png", "huge.png", "fish.obj"}) {
    const std::string tex = t == "fish.obj" ? kFish : (dir / t).string();
    write_text(dir / "s.json",
               "{\"duration\": 1, \"objects\": [{\"mesh\": \"" + kFish + "\", \"texture\": \"" + tex + "\"}]}");
    const auto r = run_shell("env -u DISPLAY " + kCli + " animate " + (dir / "s.json").string() + " --to 0.1 -o " +
                             (dir / "o.mp4").string());
    EXPECT_EQ(r.code, 1) << t << "\n" << r.out;
    EXPECT_NE(r.out.find("objects[0].texture"), std::string::npos) << t << "\n" << r.out;
    EXPECT_NE(r.out.find(t == "fish.obj" ? "is not a PNG or JPEG" : "textures must be 1 to 16384 pixels"),
              std::string::npos)
        << r.out;
    EXPECT_FALSE(fs::exists(dir / "o.mp4"));
  }
}

TEST(Hostile, DamagedTexturesAreAnErrorNotACrash) {
  // libpng under VTK dies of a segmentation fault on a PNG cut short: the whole file is checked
  // first (every chunk's CRC, the image data inflating to the rows IHDR promises).
  TempDir dir;
  const std::string png = read_text(fs::path(CSRBF_SOURCE_DIR) / "examples" / "checker.png");
  std::string flipped = png;
  flipped[png.size() / 2] = char(flipped[png.size() / 2] ^ 0x40);
  const std::vector<std::pair<std::string, std::string>> cases{{png.substr(0, 200), "runs past the end"},
                                                               {png.substr(0, png.size() - 20), "cut short"},
                                                               {flipped, "fails its CRC"}};
  for (const auto& [bytes, words] : cases) {
    write_text(dir / "t.png", bytes);
    write_text(dir / "s.json", "{\"duration\": 1, \"objects\": [{\"mesh\": \"" + kFish + "\", \"texture\": \"" +
                                   (dir / "t.png").string() + "\"}]}");
    for (const std::string cmd : {"animate", "export"}) {
      const std::string out = (dir / (cmd == "animate" ? "o.mp4" : "o.glb")).string();
      const auto r = run_shell("env -u DISPLAY " + kCli + " " + cmd + " " + (dir / "s.json").string() +
                               (cmd == "animate" ? " --to 0.1" : "") + " -o " + out);
      EXPECT_EQ(r.code, 1) << cmd << " " << words << "\n" << r.out;
      EXPECT_NE(r.out.find("objects[0].texture: texture file"), std::string::npos) << r.out;
      EXPECT_NE(r.out.find(words), std::string::npos) << r.out;
      EXPECT_FALSE(fs::exists(out));
    }
  }
}

TEST(Hostile, SceneNumbersNamedByPath) {
  TempDir dir;
  const std::string obj = "{\"mesh\": \"" + kFish + "\"";
  const std::vector<std::pair<std::string, std::string>> cases{
      // Keys at +-1e308: refused where they are, not NaN frames.
      {obj + ", \"trajectory\": {\"keys\": [{\"time\": 0, \"position\": [1e308, 0, 0]}, {\"time\": 1, \"position\": "
             "[-1e308, 0, 0]}]}}",
       "objects[0].trajectory.keys[0].position[0]"},
      {obj + ", \"parts\": [{\"deformations\": [{\"contact\": {\"collider\": \"x\", \"collider_radius\": 1e-300}, "
             "\"radius\": 0.3}]}]}",
       "collider_radius"},
  };
  for (const auto& [o, where] : cases) {
    write_text(dir / "s.json", "{\"duration\": 1, \"objects\": [" + o + "]}");
    const auto r = run_shell("env -u DISPLAY " + kCli + " animate " + (dir / "s.json").string() + " --to 0.1 -o " +
                             (dir / "o.mp4").string());
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(where), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir / "o.mp4"));
  }
  // A quaternion [1e200, 1e200, 0, 0] is a rotation of 90 degrees about x, as its direction says.
  write_text(dir / "q.json",
             "{\"duration\": 0.2, \"objects\": [" + obj +
                 ", \"orientation\": {\"keys\": [{\"time\": 0, \"quaternion\": [1e200, 1e200, 0, 0]}]}}]}");
  const auto q = run_shell("env -u DISPLAY " + kCli + " animate " + (dir / "q.json").string() + " --size 64x48 -o " +
                           (dir / "q.mp4").string());
  EXPECT_EQ(q.code, 0) << q.out;
}

TEST(Hostile, FullDiskAndFileSizeLimits) {
  TempDir dir;
  const std::string d = dir.path.string();
  const std::string deform = kCli + " deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o ";
  // ulimit -f: every writer fails and keeps the old file (STL and glTF through assimp included).
  for (const std::string name : {"k.stl", "k.glb", "k.obj", "k.ply"}) {
    write_text(dir / name, "precious");
    const std::string before = listing(dir.path);
    const auto r = run_shell("ulimit -f 16; " + deform + d + "/" + name);
    EXPECT_EQ(r.code, 1) << name << "\n" << r.out;
    EXPECT_NE(r.out.find("cannot write"), std::string::npos) << r.out;
    EXPECT_EQ(read_text(dir / name), "precious") << name;
    EXPECT_EQ(listing(dir.path), before) << name;
  }
  // ulimit -v: out of memory names the file, no std::bad_alloc. (Not under AddressSanitizer, whose
  // shadow memory alone is beyond any such limit.)
#if !defined(__SANITIZE_ADDRESS__)
  {
    std::string big =
        "ply\nformat ascii 1.0\nelement vertex 4000000\nproperty float x\nproperty float y\nproperty float "
        "z\nend_header\n";
    for (int i = 0; i < 4000000; ++i) big += "0.5 0.5 0.5\n";
    write_text(dir / "big.ply", big);
    const auto r = run_shell("ulimit -v 600000; " + kCli + " deform --mesh " + d + "/big.ply --controls " +
                             kFishControls + " --radius 0.3 -o " + d + "/big2.ply");
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_EQ(r.out.find("std::bad_alloc"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("memory"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir / "big2.ply"));
    fs::remove(dir / "big.ply");
  }
#endif
  // A full file system: a 1 MiB tmpfs where the machine lets us mount one.
  fs::create_directory(dir / "full");
  if (run_shell("mount -t tmpfs -o size=1m tmpfs " + d + "/full").code != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs here (not root): the full-disk part is skipped";
  }
  struct Unmount {
    std::string p;
    ~Unmount() { run_shell("umount " + p); }
  } unmount{d + "/full"};
  write_text(dir / "full" / "keep.avi", "old movie");
  write_text(dir / "full" / "keep.stl", "old mesh");
  const auto a = run_shell("env -u DISPLAY " + kCli + " animate " + kExamples +
                           "fish.scene.json --size 320x240 --to 1 -o " + d + "/full/keep.avi");
  EXPECT_EQ(a.code, 1) << a.out;
  EXPECT_EQ(read_text(dir / "full" / "keep.avi"), "old movie");
  write_text(dir / "full" / "filler", std::string(1000000, 'x'));
  const auto s = run_shell(deform + d + "/full/keep.stl");
  EXPECT_EQ(s.code, 1) << s.out;
  EXPECT_EQ(read_text(dir / "full" / "keep.stl"), "old mesh");
  fs::remove(dir / "full" / "filler");
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir / "full")) ++entries;
  EXPECT_EQ(entries, 2u) << listing(dir / "full");
}

TEST(Hostile, SignalsLeaveNothing) {
  TempDir dir;
  const std::string d = dir.path.string();
  // deform of a big mesh, stopped while it writes: the partial file goes with it.
  {
    std::string big =
        "ply\nformat ascii 1.0\nelement vertex 1000000\nproperty float x\nproperty float y\nproperty float "
        "z\nend_header\n";
    std::mt19937 rng(15);
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 1000000; ++i)
      big += std::to_string(u(rng)) + " " + std::to_string(u(rng)) + " " + std::to_string(u(rng)) + "\n";
    write_text(dir / "big.ply", big);
  }
  for (const char* sig : {"INT", "TERM", "HUP"}) {
    // The signal comes while the output is written (the fit and the read take most of the time
    // before that): sent repeatedly until the program is gone.
    const auto r = run_shell(
        "(" + kCli + " deform --mesh " + d + "/big.ply --controls " + kFishControls + " --radius 0.3 -o " + d +
        "/out.ply & p=$!; while kill -0 $p 2>/dev/null; do "
        "if ls -a " +
        d + " | grep -q csrbf-partial; then kill -" + sig + " $p; fi; sleep 0.01; done; wait $p; echo status=$?)");
    EXPECT_NE(r.out.find("status="), std::string::npos) << r.out;
    for (const auto& e : fs::directory_iterator(dir.path))
      EXPECT_EQ(e.path().filename().string().find(".csrbf-partial-"), std::string::npos) << sig << ": " << e.path();
    // Either nothing, or (when the signal came after the rename) the complete output.
    if (fs::exists(dir / "out.ply")) {
      const std::string out = read_text(dir / "out.ply");
      EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1000007) << sig << r.out;
    }
    fs::remove(dir / "out.ply");
  }
}

TEST(Hostile, KillNineLeavesNoProcessAndTheNextRunCleansUp) {
  TempDir dir;
  const std::string d = dir.path.string();
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    unsetenv("DISPLAY");
    const std::string out = d + "/movie.mp4", scene = kExamples + "fish.scene.json";
    const int null_fd = ::open("/dev/null", O_WRONLY);
    dup2(null_fd, 1);
    dup2(null_fd, 2);
    execl(kCli.c_str(), kCli.c_str(), "animate", scene.c_str(), "-o", out.c_str(), "--size", "640x480", "--fps", "200",
          "--to", "30", static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until it renders: its children (Xvfb, ffmpeg) are running and the partial exists.
  std::vector<pid_t> kids;
  bool partial = false;
  for (int i = 0; i < 300 && (kids.size() < 2 || !partial); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    kids = children_of(pid);
    partial = false;
    for (const auto& e : fs::directory_iterator(dir.path))
      partial = partial || e.path().filename().string().find(".csrbf-partial-") != std::string::npos;
  }
  ASSERT_GE(kids.size(), 2u) << "Xvfb and ffmpeg should be running";
  ASSERT_TRUE(partial);
  kill(pid, SIGKILL);
  int st = 0;
  waitpid(pid, &st, 0);
  // Its children die with it (PR_SET_PDEATHSIG).
  for (int i = 0; i < 100; ++i) {
    bool any = false;
    for (pid_t k : kids) any = any || process_alive(k);
    if (!any) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  for (pid_t k : kids) EXPECT_FALSE(process_alive(k)) << "child " << k << " outlived csrbf";
  EXPECT_FALSE(fs::exists(dir / "movie.mp4"));
  // The next write into the folder removes the dead run's partial (older than 2 s), nothing else.
  write_text(dir / "mine.txt", "mine");
  std::this_thread::sleep_for(std::chrono::milliseconds(2100));
  const auto r =
      run_shell(kCli + " deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o " + d + "/x.obj");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(listing(dir.path), "mine.txt:4\nx.obj:" + std::to_string(fs::file_size(dir / "x.obj")) + "\n");
}

TEST(Hostile, DeadDisplayFallsBackToAPrivateOne) {
  TempDir dir;
  // A display number no X server holds now (:77 was taken once by an Xvfb beside the suite).
  int dead = 77;
  while (fs::exists("/tmp/.X11-unix/X" + std::to_string(dead)) ||
         fs::exists("/tmp/.X" + std::to_string(dead) + "-lock"))
    ++dead;
  const std::string display = ":" + std::to_string(dead);
  const auto r = run_shell("DISPLAY=" + display + " " + kCli + " animate " + kExamples +
                           "face.scene.json --size 64x48 --to 0.1 -o " + (dir / "f.mp4").string());
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("DISPLAY " + display + " does not open"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::is_regular_file(dir / "f.mp4"));
}
