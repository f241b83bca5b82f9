// Issue 30 (nothing lost, round three): inputs never written, "must be new" outputs created once,
// partials removed only with proof, names printed escaped, near-coplanar linear fits refused.
// Each case failed before its fix.
#include "cli/catalogue.hpp"
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <sys/xattr.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <random>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;
using namespace csrbf::test;

namespace {

const std::string kFish = kExamples + "fish.obj";
const std::string kFishControls = kExamples + "fish.controls";

/// A two-tetrahedron Gmsh 2.2 mesh with a moving patch "base" and its motion file.
void write_gmsh_case(const fs::path& dir) {
  write_text(dir / "two.msh",
             "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 1 \"base\"\n3 2 \"solid\"\n$EndPhysicalNames\n"
             "$Nodes\n5\n10 0 0 0\n11 1 0 0\n12 0 1 0\n13 0 0 1\n14 0 0 -1\n$EndNodes\n"
             "$Elements\n3\n1 2 2 1 1 10 11 12\n2 4 2 2 2 10 11 12 13\n3 4 2 2 2 10 12 11 14\n$EndElements\n");
  write_text(dir / "motion.json", R"({"radius": 3, "patches": {"base": {"translate": [0, 0, 0.01]}}})");
}

/// A control at every vertex of the fish (977), moved by up to 0.01 in y (seeded): with R = 3 to 5
/// every vertex is a neighbour of every other.
std::string every_fish_vertex() {
  std::mt19937 rng(977);
  std::uniform_real_distribution<double> u(-0.01, 0.01);
  std::string controls;
  std::istringstream obj(read_text(kFish));
  for (std::string row; std::getline(obj, row);) {
    double x = 0, y = 0, z = 0;
    if (row.rfind("v ", 0) != 0 || std::sscanf(row.c_str(), "v %lf %lf %lf", &x, &y, &z) != 3) continue;
    char line[200];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g %.17g %.17g\n", x, y, z, x, y + u(rng), z);
    controls += line;
  }
  return controls;
}

/// A binary PLY of n random vertices in the unit cube and `faces` random triangles (seeded).
std::string random_binary_ply(std::size_t n, std::size_t faces, unsigned seed) {
  std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) +
                    "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(faces) +
                    "\nproperty list uchar int vertex_indices\nend_header\n";
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  std::uniform_int_distribution<std::int32_t> pick(0, std::int32_t(n - 1));
  for (std::size_t i = 0; i < n; ++i) {
    const float v[3] = {u(rng), u(rng), u(rng)};
    ply.append(reinterpret_cast<const char*>(v), sizeof v);
  }
  for (std::size_t f = 0; f < faces; ++f) {
    ply += char(3);
    const std::int32_t c[3] = {pick(rng), pick(rng), pick(rng)};
    ply.append(reinterpret_cast<const char*>(c), sizeof c);
  }
  return ply;
}

/// Runs a shell command (its output to `log`) and gives its exit status and its peak resident memory
/// in bytes, as wait4 reports it for the child and what it waited for.
std::pair<int, double> run_measured(const std::string& command, const fs::path& log) {
  const std::string line = command + " > '" + log.string() + "' 2>&1";
  const pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", line.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), double(usage.ru_maxrss) * 1024.0};
}

}  // namespace

TEST(Trust, AnOutputThatIsAnInputIsRefusedByNameAndByLink) {
  TempDir dir;
  const std::string d = dir.path.string();
  fs::copy_file(kFish, dir / "fish.obj");
  fs::copy_file(kFishControls, dir / "fish.controls");
  fs::create_symlink(dir / "fish.obj", dir / "link.obj");
  ASSERT_EQ(::link((dir / "fish.controls").c_str(), (dir / "hard.obj").c_str()), 0);
  write_text(dir / "d.json", R"({"radius": 0.3, "controls": "fish.controls"})");
  const std::string mesh = read_text(dir / "fish.obj"), controls = read_text(dir / "fish.controls");
  const std::string deform = kCli + " deform --mesh " + d + "/fish.obj --controls " + d + "/fish.controls --radius 0.3";
  const std::vector<std::pair<std::string, std::string>> cases{
      {deform + " -o " + d + "/fish.obj", "is the input '" + d + "/fish.obj'"},
      {deform + " -o " + d + "/../" + dir.path.filename().string() + "/fish.obj", "is the input"},
      {deform + " -o " + d + "/link.obj", "is the input '" + d + "/fish.obj'"},
      {deform + " -o " + d + "/hard.obj", "is the input '" + d + "/fish.controls'"},
      {kCli + " deform --mesh " + d + "/fish.obj --deformation " + d + "/d.json -o " + d + "/hard.obj",
       "is the input '" + d + "/fish.controls'"},
  };
  for (const auto& [command, message] : cases) {
    const auto r = run_shell(command);
    EXPECT_EQ(r.code, 2) << command << "\n" << r.out;
    EXPECT_NE(r.out.find(message), std::string::npos) << command << "\n" << r.out;
    EXPECT_EQ(read_text(dir / "fish.obj"), mesh);
    EXPECT_EQ(read_text(dir / "fish.controls"), controls);
  }
  // export -o the scene's mesh.
  fs::copy_file(kExamples + "fish.scene.json", dir / "fish.scene.json");
  for (const auto& e : fs::directory_iterator(kExamples))
    if (e.path().filename().string().starts_with("fish-") && !fs::exists(dir / e.path().filename()))
      fs::copy_file(e.path(), dir / e.path().filename());
  const auto r = run_shell(kCli + " export " + d + "/fish.scene.json -o " + d + "/link.obj.glb");
  EXPECT_EQ(r.code, 0) << r.out;  // a new name is fine
  fs::create_symlink(dir / "fish.obj", dir / "mesh.glb");
  const auto e = run_shell(kCli + " export " + d + "/fish.scene.json -o " + d + "/mesh.glb");
  EXPECT_EQ(e.code, 2) << e.out;
  EXPECT_NE(e.out.find("is the input '" + d + "/fish.obj'"), std::string::npos) << e.out;
  EXPECT_EQ(read_text(dir / "fish.obj"), mesh);
}

TEST(Trust, OfEightWritersOfOneNewFileExactlyOneSucceeds) {
  TempDir dir;
  write_gmsh_case(dir.path);
  const std::string d = dir.path.string();
  // A small mesh, and the airfoil (0.3 s a morph: the first writer finishes while the others are
  // still fitting, and found the name new when they started).
  const std::vector<std::string> meshes{
      d + "/two.msh --motion " + d + "/motion.json",
      kExamples + "airfoil/airfoil.msh --motion " + kExamples + "airfoil/motion.json"};
  for (int round = 0; round < 2; ++round) {  // each mesh once (two more rounds repeated the same races)
    const std::string out = d + "/new" + std::to_string(round) + ".msh";
    const std::string& mesh = meshes[std::size_t(round) % 2];
    std::vector<ShellRun> runs(8);
    std::vector<std::thread> threads;
    for (auto& r : runs)
      threads.emplace_back([&r, &mesh, &out] { r = run_shell(kCli + " morph " + mesh + " -o " + out); });
    for (auto& t : threads) t.join();
    int ok = 0;
    for (const auto& r : runs) {
      if (r.code == 0) {
        ++ok;
      } else {
        EXPECT_EQ(r.code, 1) << r.out;
        EXPECT_NE(r.out.find("exists"), std::string::npos) << r.out;
      }
    }
    EXPECT_EQ(ok, 1) << "round " << round;
  }
  // deform and export replace an existing output, but never one that was new when they started:
  // each run succeeds or fails with "exists" (one that starts after another finished replaces it),
  // and the file is whole.
  for (const std::string& cmd : {"deform --mesh " + kExamples + "bunny.obj --controls " + kExamples +
                                     "bunny.controls --radius 2.5 -o " + d + "/new.obj",
                                 "export " + kExamples + "face.scene.json -o " + d + "/new.glb"}) {
    std::vector<ShellRun> runs(8);
    std::vector<std::thread> threads;
    for (auto& r : runs) threads.emplace_back([&r, &cmd] { r = run_shell(kCli + " " + cmd); });
    for (auto& t : threads) t.join();
    int ok = 0;
    for (const auto& r : runs) {
      ok += r.code == 0;
      if (r.code != 0) {
        EXPECT_EQ(r.code, 1) << r.out;
        EXPECT_NE(r.out.find("exists"), std::string::npos) << r.out;
      }
    }
    EXPECT_GE(ok, 1) << cmd;
  }
  EXPECT_EQ(run_shell(kCli + " deform --mesh " + d + "/new.obj --controls " + kExamples +
                      "bunny.controls --radius 2.5 -o " + d + "/again.obj")
                .code,
            0);
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".csrbf-partial-"), std::string::npos) << e.path();
}

TEST(Trust, AGltfInputsBuffersAreInputsToo) {
  TempDir dir;
  const std::string d = dir.path.string();
  ASSERT_EQ(
      run_shell(kCli + " deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o " + d + "/a.gltf")
          .code,
      0);
  const std::string bin = read_text(dir / "a.bin");
  ASSERT_FALSE(bin.empty());
  fs::create_symlink(dir / "a.bin", dir / "link.obj");
  const std::string deform = kCli + " deform --mesh " + d + "/a.gltf --controls " + kFishControls + " --radius 0.3 -o ";
  // Its buffer through a link, and as the side file a .gltf output would write.
  auto r = run_shell(deform + d + "/link.obj");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("is the input '" + d + "/a.bin'"), std::string::npos) << r.out;
  fs::copy_file(dir / "a.gltf", dir / "c.gltf");
  r = run_shell(deform + d + "/c.gltf");  // c.gltf is new enough, but its c.bin would be... a.bin? no:
  EXPECT_EQ(r.code, 0) << r.out;          // c.bin is not an input: written
  fs::create_hard_link(dir / "a.bin", dir / "h.bin");
  r = run_shell(deform + d + "/h.gltf");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("would write its buffer '" + d + "/h.bin', which is the input '" + d + "/a.bin'"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(read_text(dir / "a.bin"), bin);
}

TEST(Trust, PartialsAreRemovedOnlyWithProofNeverByName) {
  TempDir dir;
  const std::string d = dir.path.string();
  // The user's own folder and file, named as partials are, and old enough to be stale.
  fs::create_directory(dir / ".x.csrbf-partial-0123456789abcdef");
  write_text(dir / ".x.csrbf-partial-0123456789abcdef" / "thesis.tex", "years of work");
  write_text(dir / ".y.obj.csrbf-partial-fedcba9876543210", "the user's");
  // (A partial that a killed csrbf left is removed: test_io's AtomicFile tests.)
  std::this_thread::sleep_for(std::chrono::milliseconds(2200));
  const auto r = run_shell(kCli + " deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o " + d +
                           "/out.obj");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(read_text(dir / ".x.csrbf-partial-0123456789abcdef" / "thesis.tex"), "years of work");
  EXPECT_EQ(read_text(dir / ".y.obj.csrbf-partial-fedcba9876543210"), "the user's");
  // The output carries no mark of csrbf's.
  char buf[64];
  EXPECT_LT(::getxattr((dir / "out.obj").c_str(), "user.csrbf.partial", buf, sizeof buf), 0);
}

TEST(Trust, ControlCharactersInNamesArePrintedEscaped) {
  TempDir dir;
  const std::string d = dir.path.string();
  const std::string evil = d + "/a\x1b[2J\x07.obj";
  const auto r = run_shell(kCli + " deform --mesh '" + evil + "' --controls " + kFishControls + " --radius 0.3 -o " +
                           d + "/o.obj");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_EQ(r.out.find('\x1b'), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find('\x07'), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("a\\u001b[2J\\u0007.obj"), std::string::npos) << r.out;
  // Names in a successful run's report too.
  const auto ok = run_shell(kCli + " deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o '" +
                            d + "/b\x1b[31m.obj'");
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_EQ(ok.out.find('\x1b'), std::string::npos) << ok.out;
  EXPECT_NE(ok.out.find("b\\u001b[31m.obj"), std::string::npos) << ok.out;
  // A refused option value, through CLI11.
  const auto k = run_shell(kCli + " deform --mesh " + kFish + " --controls " + kFishControls +
                           " --radius 0.3 --kernel $'c\\x1b[31m' -o " + d + "/o.obj");
  EXPECT_EQ(k.code, 2) << k.out;
  EXPECT_EQ(k.out.find('\x1b'), std::string::npos) << k.out;
  // A NUL in a JSON key no longer ends the message early.
  write_text(dir / "nul.json", std::string("{\"radius\": 0.3, \"sou\\u0000rces\": []}"));
  const auto n = run_shell(kCli + " deform --mesh " + kFish + " --deformation " + d + "/nul.json -o " + d + "/o.obj");
  EXPECT_EQ(n.code, 1) << n.out;
  EXPECT_NE(n.out.find("sou\\u0000rces"), std::string::npos) << n.out;
}

TEST(Trust, NearlyCoplanarSourcesWithALinearPolynomialAreRefused) {
  TempDir dir;
  const std::string d = dir.path.string();
  // Sources on z = 0 but one, 1e-6 off the plane, with motions of 0.1 that no affine map fits:
  // the linear part's gradient across the plane was set by the noise (+-103 for motions of 0.1).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::string text;
  for (int i = 0; i < 40; ++i) {
    const double x = u(rng), y = u(rng), z = i == 0 ? 1e-6 : 0.0;
    char line[200];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g %.17g %.17g\n", x, y, z, x + 0.1 * u(rng),
                  y + 0.1 * u(rng), z + 0.1 * u(rng));
    text += line;
  }
  write_text(dir / "flat.controls", text);
  const auto r = run_shell(kCli + " info --controls " + d + "/flat.controls --radius 0.5 --polynomial linear");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("nearly coplanar or collinear (condition of the polynomial block"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("use polynomial 'constant' or 'none'"), std::string::npos) << r.out;
  // The same sources without the polynomial, and a consistent affine motion of them, fit.
  EXPECT_EQ(run_shell(kCli + " info --controls " + d + "/flat.controls --radius 0.5").code, 0);
  std::string affine;
  for (int i = 0; i < 40; ++i) {
    const double x = u(rng), y = u(rng), z = i == 0 ? 1e-6 : 0.0;
    char line[200];
    std::snprintf(line, sizeof line, "%.17g %.17g %.17g %.17g %.17g %.17g\n", x, y, z, x + 0.1 * y, y - 0.1 * x, z);
    affine += line;
  }
  write_text(dir / "turn.controls", affine);
  const auto t = run_shell(kCli + " info --controls " + d + "/turn.controls --radius 0.5 --polynomial linear");
  EXPECT_EQ(t.code, 0) << t.out;
}

TEST(Trust, EveryCommandEndsUnderAnAddressSpaceLimit) {
  // Under ulimit -v 300000 every command hung at exit: OpenBLAS's threads, started as it loads,
  // spun for memory they could not have, and the exit waited for them. Each now ends, with its
  // result or a clear error (Gmsh's and Mesa's libraries need more than 300 MB of address space).
#if defined(__SANITIZE_ADDRESS__)
  // AddressSanitizer's shadow memory alone is beyond any such limit (the release pass runs this).
  GTEST_SKIP() << "an address-space limit and AddressSanitizer do not mix";
#endif
  TempDir dir;
  const std::string d = dir.path.string();
  const std::vector<std::string> commands{
      "info --controls " + kFishControls + " --radius 0.3",
      "deform --mesh " + kFish + " --controls " + kFishControls + " --radius 0.3 -o " + d + "/f.obj",
      "export " + kExamples + "fish.scene.json -o " + d + "/f.glb",
      "morph " + kExamples + "airfoil/airfoil.msh --motion " + kExamples + "airfoil/motion.json -o " + d + "/a.msh",
      "animate " + kExamples + "fish.scene.json --to 0.1 --size 64x64 -o " + d + "/f.mp4",
      "bench --scenario fish --seconds 0.05",
  };
  for (const auto& c : commands) {
    const auto r = run_shell("ulimit -v 300000; env -u DISPLAY timeout 120 " + kCli + " " + c);
    EXPECT_TRUE(r.code == 0 || r.code == 1) << c << " (status " << r.code << ")\n" << r.out;
    if (r.code == 1) {
      EXPECT_NE(r.out.find("csrbf: error: "), std::string::npos) << c << "\n" << r.out;
    }
  }
  EXPECT_TRUE(fs::exists(dir / "f.obj"));
  EXPECT_TRUE(fs::exists(dir / "f.glb"));
  // CHOLMOD's factor runs OpenBLAS, which retried the mapping of its buffers for ever under this
  // limit (a control at every fish vertex, R = 5): refused now before it starts, with the limit named;
  // Auto turns to another solver and finishes.
  write_text(dir / "all.controls", every_fish_vertex());
  const std::string all = "info --controls " + d + "/all.controls --radius 5";
  const auto forced =
      run_shell("ulimit -v 300000; env -u DISPLAY timeout 120 " + kCli + " " + all + " --solver cholmod");
  EXPECT_EQ(forced.code, 1) << forced.out;
  EXPECT_NE(forced.out.find("the address-space limit (ulimit -v) leaves"), std::string::npos) << forced.out;
  const auto automatic = run_shell("ulimit -v 300000; env -u DISPLAY timeout 120 " + kCli + " " + all);
  EXPECT_EQ(automatic.code, 0) << automatic.out;
  // An OpenFOAM morph (csrbf-morph) under tighter limits: it padded its heap by 64 MiB, which
  // could not be had while its libraries loaded, and libgfortran's start-up overflowed its stack
  // (exit 139 at 80000-120000); below that, running out of memory inside the four parallel
  // readers ended in std::terminate (exit 134). Each limit now ends with the morph or with
  // "out of memory".
  int k = 0;
  for (const int kib : {60000, 70000, 80000, 100000, 120000, 300000}) {
    const std::string c = "morph " + kExamples + "airfoil/case --motion " + kExamples + "airfoil/motion.json -o " + d +
                          "/foam" + std::to_string(k++);
    for (const char* tunables : {"", "GLIBC_TUNABLES=glibc.malloc.top_pad=0 "}) {
      const auto r = run_shell("ulimit -v " + std::to_string(kib) + "; env -u DISPLAY " + tunables + "timeout 120 " +
                               kCli + " " + c + " --quiet");
      EXPECT_TRUE(r.code == 0 || r.code == 1) << kib << " KiB " << tunables << c << " (status " << r.code << ")\n"
                                              << r.out;
      if (r.code == 1) {
        EXPECT_NE(r.out.find("csrbf: error: "), std::string::npos) << kib << " " << c << "\n" << r.out;
      }
      if (r.code == 0) break;  // written: the next setting would find its output there
    }
  }
  EXPECT_TRUE(fs::exists(dir / "foam5" / "constant" / "polyMesh"));
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".csrbf-partial-"), std::string::npos) << e.path();
}

// Issue 30, point 12: --time-limit ends a fit that cannot be asked to stop (Eigen's factorisation of
// a dense matrix: 8000 controls, R = half the cube, minutes here), with exit 1 and nothing written.
TEST(Trust, ATimeLimitEndsASlowFitAndWritesNothing) {
  TempDir dir;
  const std::string d = dir.path.string();
  std::mt19937 rng(30);
  std::uniform_real_distribution<double> u(0, 1);
  std::string controls;
  for (int i = 0; i < 8000; ++i) {
    const double x = u(rng), y = u(rng), z = u(rng);
    controls += std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + " " + std::to_string(x) + " " +
                std::to_string(y) + " " + std::to_string(z + 0.01 * u(rng)) + "\n";
  }
  write_text(dir / "big.controls", controls);
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = run_shell(kCli + " deform --mesh " + kFish + " --controls " + d +
                           "/big.controls --radius 0.5 --solver eigen --time-limit 1 -o " + d + "/out.obj");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("the time limit of 1 s (--time-limit) was reached; nothing was written"), std::string::npos)
      << r.out;
  EXPECT_LT(seconds, 20.0);  // the limit, start-up and the controls' parse; not the fit
  EXPECT_FALSE(fs::exists(dir / "out.obj"));
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path)) ++entries;
  EXPECT_EQ(entries, 1u) << "a partial was left";
  // Within the limit, the same command with a small radius finishes as before.
  const auto ok = run_shell(kCli + " deform --mesh " + kFish + " --controls " + d +
                            "/big.controls --radius 0.05 --time-limit 600 -o " + d + "/out.obj");
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::exists(dir / "out.obj"));
  // A limit that is no number of seconds is a usage error.
  for (const std::string bad : {"0", "-1", "nan", "1e7"})
    EXPECT_EQ(run_shell(kCli + " morph x --motion y -o z --time-limit " + bad).code, 2) << bad;
}

// Issue 30, point 11: where conjugate gradients give way (Auto) or stagnate, the solver that takes
// over counts what CG holds beside it, and the envelope solver takes over where the memory limit
// refuses the direct one. A control at each of the fish's 977 vertices with R = 3 (every vertex a
// neighbour of every other) under --memory-limit 0.08: CHOLMOD took over beside CG's copy of A and
// peaked at 0.103 GiB (with R = 5 it was refused, CG ran again and stagnated: exit 1); face.obj's
// 6158 vertices with R = 0.8 under --memory-limit 1 peaked at 1.455 GiB and stagnated. Now the
// envelope solver takes over in both (0.085 and 0.94 GiB; the face in 27 s).
TEST(Trust, TheSolverThatTakesOverFromConjugateGradientsKeepsTheMemoryLimit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory is beyond a limit of 0.08 GiB (the release pass runs this)";
#endif
  TempDir dir;
  const std::string controls = every_fish_vertex();
  ASSERT_EQ(std::count(controls.begin(), controls.end(), '\n'), 977);
  write_text(dir / "all.controls", controls);
  const double limit = 0.08;
  const auto [code, peak] = run_measured(kCli + " info --controls " + (dir / "all.controls").string() +
                                             " --radius 3 --memory-limit " + std::to_string(limit),
                                         dir / "log");
  const std::string out = read_text(dir / "log");
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("solver             envelope"), std::string::npos) << out;
  EXPECT_NE(out.find("conjugate gradients gave way"), std::string::npos) << out;
  EXPECT_LE(peak, 1.1 * limit * double(1ull << 30)) << out;
  // Without the limit, Auto's direct solver (CHOLMOD, or Eigen's) takes over, as before.
  const auto free = run_shell(kCli + " info --controls " + (dir / "all.controls").string() + " --radius 3");
  EXPECT_EQ(free.code, 0) << free.out;
  EXPECT_EQ(free.out.find("solver             envelope"), std::string::npos) << free.out;
}

// Found by the attacker's trial (round three): Eigen's simplicial solver took A's lower triangle by
// value and copied it again into its member (Eigen 3.4's SparseMatrix has no move constructor), so
// three triangles lived through its AMD analysis: 1.11 times --memory-limit 0.07, refused only after.
TEST(Trust, EigensAnalysisHoldsOneCopyOfTheMatrix) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory is beyond a limit of 0.07 GiB (the release pass runs this)";
#endif
  TempDir dir;
  write_text(dir / "all.controls", every_fish_vertex());
  for (const double limit : {0.07, 0.1, 0.14}) {
    const auto [code, peak] =
        run_measured(kCli + " deform --mesh " + kFish + " --controls " + (dir / "all.controls").string() +
                         " --radius 0.5 --solver eigen --memory-limit " + std::to_string(limit) + " -o " +
                         (dir / "out.obj").string(),
                     dir / "log");
    const std::string out = read_text(dir / "log");
    EXPECT_EQ(code, limit < 0.12 ? 1 : 0) << limit << ": " << out;
    EXPECT_EQ(fs::exists(dir / "out.obj"), code == 0) << out;
    EXPECT_LE(peak, 1.1 * limit * double(1ull << 30)) << limit << ": " << out;
    fs::remove(dir / "out.obj");
  }
}

// Issue 30, point 11: a binary PLY of 1.5e6 vertices (24.5 MB) under --memory-limit 0.3 peaked at
// 0.335 GiB (its vectors doubled as they grew, and each vertex kept 6 offsets); now 0.25 GiB.
TEST(Trust, ABinaryPlyIsDeformedWithinTheMemoryLimit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory counts against the limit (the release pass runs this)";
#endif
  TempDir dir;
  write_text(dir / "big.ply", random_binary_ply(1500000, 500000, 15));
  const double limit = 0.3;
  const auto [code, peak] =
      run_measured(kCli + " deform --mesh " + (dir / "big.ply").string() + " --controls " + kFishControls +
                       " --radius 0.3 --memory-limit " + std::to_string(limit) + " -o " + (dir / "out.ply").string(),
                   dir / "log");
  EXPECT_EQ(code, 0) << read_text(dir / "log");
  EXPECT_LE(peak, 1.1 * limit * double(1ull << 30)) << read_text(dir / "log");
  EXPECT_EQ(fs::file_size(dir / "out.ply"), fs::file_size(dir / "big.ply"));
}

// Issue 30, point 11: export and animate took no --memory-limit and no --time-limit. Both now read
// the scene's meshes and fit its deformations within the limit, animate refuses a frame size the
// limit cannot render (64 bytes a pixel, measured), export refuses baking beyond it; --time-limit
// ends them with nothing written, a partial frame folder included.
TEST(Trust, ExportAndAnimateKeepTheMemoryAndTimeLimits) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory counts against the limits (the release pass runs this)";
#endif
  TempDir dir;
  const std::string d = dir.path.string(), scene = kExamples + "fish.scene.json";
  const auto big = run_shell("env -u DISPLAY " + kCli + " animate " + scene +
                             " --to 0.08 --size 4096x4096 --memory-limit 0.5 -o " + d + "/big.mp4");
  EXPECT_EQ(big.code, 1) << big.out;
  EXPECT_NE(big.out.find("--size 4096x4096: the movie takes about 1.09 GiB (the player 0.000284, the renderer 1.09: "
                         "96 MiB, 64 bytes a pixel, the meshes' copies and the textures), more than the"),
            std::string::npos)
      << big.out;
  EXPECT_NE(big.out.find("or a smaller --size"), std::string::npos) << big.out;
  // The renderer's own 96 MiB count too: a 640x480 movie under 0.1 GiB peaked at 0.159.
  const auto small = run_shell("env -u DISPLAY " + kCli + " animate " + scene + " --to 0.08 --memory-limit 0.1 -o " +
                               d + "/small.mp4");
  EXPECT_EQ(small.code, 1) << small.out;
  EXPECT_NE(small.out.find("--size 640x480: the movie takes about 0.113 GiB"), std::string::npos) << small.out;
  const auto tiny =
      run_shell("env -u DISPLAY " + kCli + " animate " + scene + " --to 0.08 --memory-limit 0.02 -o " + d + "/t.mp4");
  EXPECT_EQ(tiny.code, 1) << tiny.out;
  EXPECT_NE(tiny.out.find("--memory-limit 0.02 GiB is too small: csrbf already holds"), std::string::npos) << tiny.out;
  // 0.045: between what the program holds as it starts (0.037 GiB since MPI and PETSc are loaded only
  // under mpirun) and what baking needs beside it.
  const auto bake = run_shell(kCli + " export " + scene + " --bake always --memory-limit 0.045 -o " + d + "/b.glb");
  EXPECT_EQ(bake.code, 1) << bake.out;
  EXPECT_NE(bake.out.find("export: writing the glTF takes about 0.0164 GiB (the player 0.000284, the buffer 0.00591, "
                          "morph targets and baked frames 0.00878), more than the"),
            std::string::npos)
      << bake.out;
  EXPECT_NE(bake.out.find("a lower --fps, or bake less"), std::string::npos) << bake.out;
  // Within the limits, as before, and the peak is within the limit plus 10 %.
  const auto [code, peak] =
      run_measured("env -u DISPLAY " + kCli + " animate " + scene + " --to 0.2 --memory-limit 0.25 -o " + d + "/ok.mp4",
                   dir / "log");
  EXPECT_EQ(code, 0) << read_text(dir / "log");
  EXPECT_LE(peak, 1.1 * 0.25 * double(1ull << 30));
  EXPECT_EQ(run_shell(kCli + " export " + scene + " --memory-limit 0.25 -o " + d + "/ok.glb").code, 0);
  // --time-limit ends a movie into a frame folder: no folder, no partial.
  const auto slow = run_shell("env -u DISPLAY " + kCli + " animate " + scene + " --time-limit 1 -o " + d + "/frames");
  EXPECT_EQ(slow.code, 1) << slow.out;
  EXPECT_NE(slow.out.find("the time limit of 1 s (--time-limit) was reached; nothing was written"), std::string::npos)
      << slow.out;
  EXPECT_FALSE(fs::exists(dir / "frames"));
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".csrbf-partial-"), std::string::npos) << e.path();
}

// Found by the attacker's trial: export and animate of scenes with big meshes counted the meshes as
// read, but not the player's, the glTF buffer's and the renderer's copies of them (animate peaked at
// 2.77 GiB and export at 1.83 GiB under --memory-limit 0.7). Each is predicted before it is made.
TEST(Trust, ExportAndAnimateOfBigMeshesKeepTheMemoryLimit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory counts against the limit (the release pass runs this)";
#endif
  TempDir dir;
  write_text(dir / "m.ply", random_binary_ply(300000, 600000, 17));
  // The fish's scene with the big mesh (its parts and deformations act on the first 977 vertices).
  std::string scene = read_text(kExamples + "fish.scene.json");
  scene.replace(scene.find("\"fish.obj\""), 10, "\"m.ply\"");
  for (std::size_t at = scene.find("\"fish-"); at != std::string::npos; at = scene.find("\"fish-", at + 10))
    scene.insert(at + 1, kExamples);
  write_text(dir / "big.scene.json", scene);
  const std::string s = (dir / "big.scene.json").string(), d = dir.path.string();
  const auto refused = run_shell(kCli + " export " + s + " --memory-limit 0.3 -o " + d + "/x.glb");
  EXPECT_EQ(refused.code, 1) << refused.out;
  EXPECT_NE(refused.out.find("export: writing the glTF takes about 0.211 GiB (the player 0.0872, the buffer 0.0492, "
                             "morph targets and baked frames 0.0268), more than the"),
            std::string::npos)
      << refused.out;
  const auto [code, peak] =
      run_measured(kCli + " export " + s + " --memory-limit 0.4 -o " + d + "/x.gltf", dir / "log");
  EXPECT_EQ(code, 0) << read_text(dir / "log");
  EXPECT_LE(peak, 1.1 * 0.4 * double(1ull << 30));
  const auto movie =
      run_shell("env -u DISPLAY " + kCli + " animate " + s + " --to 0.04 --memory-limit 0.45 -o " + d + "/x.mp4");
  EXPECT_EQ(movie.code, 1) << movie.out;
  EXPECT_NE(movie.out.find("the movie takes about 0.396 GiB (the player 0.0872, the renderer 0.309"), std::string::npos)
      << movie.out;
  EXPECT_EQ(movie.out.find("--size"), movie.out.find("--size 640x480")) << movie.out;  // not the remedy here
  EXPECT_EQ(movie.out.find("smaller --size"), std::string::npos) << movie.out;
  EXPECT_FALSE(fs::exists(dir / "x.glb"));
  EXPECT_FALSE(fs::exists(dir / "x.mp4"));
}

// Found by the attacker's trial: deform to a format assimp writes (.glb, .gltf, .stl) went past the
// limit (0.645 GiB under --memory-limit 0.2): assimp's copies of the mesh are predicted (glTF 290
// bytes a vertex and 270 a face, STL 25 and 210, measured), kept from the fit, and refused beyond it.
TEST(Trust, ADeformWrittenByAssimpKeepsTheMemoryLimit) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory counts against the limit (the release pass runs this)";
#endif
  TempDir dir;
  write_text(dir / "m.ply", random_binary_ply(500000, 1000000, 16));
  const std::string deform = kCli + " deform --mesh " + (dir / "m.ply").string() + " --controls " + kFishControls +
                             " --radius 0.3 --memory-limit ";
  const auto refused = run_shell(deform + "0.3 -o " + (dir / "x.glb").string());
  EXPECT_EQ(refused.code, 1) << refused.out;
  EXPECT_NE(refused.out.find("writing 500000 vertices and 1000000 faces as GLB takes about 0.425 GiB"),
            std::string::npos)
      << refused.out;
  EXPECT_FALSE(fs::exists(dir / "x.glb"));
  for (const char* out : {"x.glb", "x.stl"}) {
    const auto [code, peak] = run_measured(deform + "0.6 -o " + (dir / out).string(), dir / "log");
    EXPECT_EQ(code, 0) << read_text(dir / "log");
    EXPECT_LE(peak, 1.1 * 0.6 * double(1ull << 30)) << out;
  }
}

// Found by the attacker's trial (round two): animate into a folder of PNG frames deleted an input
// reached through a symbolic link to one of its frame files (compared by name, not by file); JSON
// was parsed before its size was weighed against the limit (a 50 MB deformation peaked at 357 MB
// under --memory-limit 0.1, a 124 MB scene at 804 MB); a decoded texture was not counted (an
// 8192 x 8192 PNG: 577 MB under 0.1); names were printed raw in the reports of success.
TEST(Trust, LinksIntoAFrameFolderBigJsonTexturesAndNamesInReports) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's own memory counts against the limits (the release pass runs this)";
#endif
  TempDir dir;
  const std::string d = dir.path.string();
  // A controls file that is a frame file of the output folder, named through a link.
  fs::create_directory(dir / "fr");
  fs::copy_file(kExamples + "fish-mouth.controls", dir / "fr" / "frame_00002.png");
  fs::create_symlink(dir / "fr" / "frame_00002.png", dir / "my.controls");
  const std::string escaped_name = "o\\u001b]0;pwn\\u0007";
  write_text(dir / "s.json",
             "{\"duration\": 0.2, \"objects\": [{\"name\": \"" + escaped_name + "\", \"mesh\": \"" + kExamples +
                 "fish.obj\", \"parts\": [{\"name\": \"body\", \"deformations\": " +
                 "[{\"name\": \"m\", \"controls\": \"my.controls\", \"radius\": 0.3, \"phase\": 1}]}]}]}");
  const std::string before = read_text(dir / "my.controls");
  const auto movie = run_shell("env -u DISPLAY " + kCli + " animate " + d + "/s.json --size 64x48 -o " + d + "/fr");
  EXPECT_EQ(movie.code, 2) << movie.out;
  EXPECT_NE(movie.out.find("frame_00002.png' is the scene's input"), std::string::npos) << movie.out;
  EXPECT_EQ(read_text(dir / "my.controls"), before);
  // The report of a success escapes the names (an ESC would retitle the terminal).
  const auto ok = run_shell(kCli + " export " + d + "/s.json -o " + d + "/s.glb");
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_EQ(ok.out.find('\x1b'), std::string::npos) << ok.out;
  EXPECT_NE(ok.out.find("object 'o\\u001b]0;pwn\\u0007'"), std::string::npos) << ok.out;
  // A 12 MB deformation and a 12 MB scene under --memory-limit 0.07: refused before parsing.
  std::string big = "{\"format\": \"csrbf-deformation\", \"version\": 1, \"radius\": 0.3, \"sources\": [";
  for (int k = 0; k < 400000; ++k) big += std::string(k ? "," : "") + "[0.1,0.2,0.3]";
  write_text(dir / "big.json", big + "], \"destinations\": []}");
  write_text(dir / "big.scene.json", "{\"objects\": [], \"padding\": \"" + std::string(12000000, 'x') + "\"}");
  for (const std::string& cmd :
       {kCli + " deform --mesh " + kFish + " --deformation " + d + "/big.json --memory-limit 0.07 -o " + d + "/x.obj",
        kCli + " export " + d + "/big.scene.json --memory-limit 0.07 -o " + d + "/x.glb"}) {
    const auto [code, peak] = run_measured(cmd, dir / "log");
    EXPECT_EQ(code, 1) << read_text(dir / "log");
    EXPECT_NE(read_text(dir / "log").find("bytes allowed for a JSON file (--memory-limit)"), std::string::npos)
        << read_text(dir / "log");
    EXPECT_LE(peak, 1.1 * 0.07 * double(1ull << 30)) << cmd;
  }
  // 250000 controls (17 MB): read within the limit, then refused before they are parsed (a tree of
  // every source and the text's copy took 3.6 times the limit with 3e6 controls).
  std::string lines;
  for (int k = 0; k < 250000; ++k) {
    char line[96];
    std::snprintf(line, sizeof line, "%.9f %.9f 0.5 %.9f %.9f 0.5\n", k * 1e-6, 0.25, k * 1e-6, 0.26);
    lines += line;
  }
  write_text(dir / "many.controls", lines);
  const auto [ccode, cpeak] =
      run_measured(kCli + " info --controls " + d + "/many.controls --radius 0.01 --memory-limit 0.058", dir / "log");
  EXPECT_EQ(ccode, 1) << read_text(dir / "log");
  EXPECT_NE(read_text(dir / "log").find("250001 lines would take about"), std::string::npos) << read_text(dir / "log");
  EXPECT_LE(cpeak, 1.1 * 0.058 * double(1ull << 30));
  // A 4096 x 4096 texture: counted decoded (151 MB), refused under 0.1, within 0.3 when allowed.
  ASSERT_EQ(run_shell("/usr/bin/python3 -c \"import zlib,struct\nw=h=4096\ndef c(t,d): return "
                      "struct.pack('>I',len(d))+t+d+struct.pack('>I',zlib.crc32(t+d))\nopen('" +
                      d +
                      "/t.png','wb').write(b'\\x89PNG\\r\\n\\x1a\\n'+c(b'IHDR',struct.pack('>IIBBBBB',w,h,8,6,0,0,0))"
                      "+c(b'IDAT',zlib.compress((b'\\x00'+b'\\x80\\x40\\x20\\xff'*w)*h,9))+c(b'IEND',b''))\"")
                .code,
            0);
  write_text(dir / "t.json", "{\"duration\": 0.2, \"objects\": [{\"name\": \"fish\", \"mesh\": \"" + kFish +
                                 "\", \"texture\": \"t.png\", \"texture_mapping\": \"sphere\"}]}");
  const auto refused = run_shell(kCli + " export " + d + "/t.json --memory-limit 0.1 -o " + d + "/t.glb");
  EXPECT_EQ(refused.code, 1) << refused.out;
  EXPECT_NE(refused.out.find("a texture decoded 0.141"), std::string::npos) << refused.out;
  const auto [code, peak] =
      run_measured(kCli + " export " + d + "/t.json --memory-limit 0.3 -o " + d + "/t.glb", dir / "log");
  EXPECT_EQ(code, 0) << read_text(dir / "log");
  EXPECT_LE(peak, 1.1 * 0.3 * double(1ull << 30));
}
