// The bad-input catalogue: every bad input we know of, at the command line and at the library API.
// Each gets a clear message naming the file, line, field or value, the right exit status, no new
// output file, and an existing output file unchanged. (`csrbf animate`'s cases, Ctrl-C and a full
// disk during a movie included, are in test_animate.cpp; the GUIs' in their own tests.)
#include "csrbf/io/controls.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/space_map.hpp"
#include "cli/catalogue.hpp"
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace fs = std::filesystem;
using csrbf::Vec3;
using csrbf::test::Case;
using csrbf::test::expand;
using csrbf::test::kCli;
using csrbf::test::kExamples;
using csrbf::test::read_text;
using csrbf::test::run_shell;
using csrbf::test::TempDir;
using csrbf::test::write_text;

TEST(BadInput, CommandLine) {
  TempDir dir;
  const std::string d = dir.path.string();
  // Inputs.
  write_text(dir / "ok.controls", "0.5 0.5 0.5  0.5 0.5 0.6\n");
  write_text(dir / "nan.controls", "0 0 0 0 0 0\n0.5 nan 0.5 0.5 0.5 0.6\n");
  write_text(dir / "inf.controls", "0.5 0.5 0.5 inf 0.5 0.6\n");
  write_text(dir / "short.controls", "0.5 0.5 0.5 0.5 0.5\n");
  write_text(dir / "words.controls", "0.5 0.5 zero 0.5 0.5 0.6\n");
  write_text(dir / "empty.controls", "# nothing\n\n");
  write_text(dir / "conflict.controls", "0 0 0 0 0 1\n0 0 0 0 0 2\n");
  write_text(dir / "planar.controls", "0 0 0 0 0 0.1\n1 0 0 1 0 0\n0 1 0 0 1 0\n1 1 0 1 1 0\n");
  std::string garbage;
  std::mt19937 rng(4);
  for (int i = 0; i < 4096; ++i) garbage.push_back(char(rng() & 0xff));
  write_text(dir / "garbage.controls", garbage);
  write_text(dir / "garbage.obj", garbage);
  write_text(dir / "garbage.ply",
             "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n"
             "property float y\nproperty float z\nend_header\n" +
                 garbage.substr(0, 40));
  write_text(dir / "garbage.stl", garbage);
  write_text(dir / "truncated.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  write_text(dir / "badnumber.obj", "v 0 0 0\nv 1 0 x\n");
  write_text(dir / "novertices.obj", "# only a comment\n");
  write_text(dir / "noheader.off", "3 1 0\n0 0 0\n");
  fs::create_directory(dir / "folder");
  // A dense system: 12000 sources in a unit cube and R = 100 (3.2 GiB for its neighbour graph and factor, so
  // that a limit of 1 GiB refuses it however much the program itself holds: 0.05 GiB here, 0.11 GiB under the
  // sanitizers, where a limit of 0.1 was refused before the fit was predicted).
  {
    std::string text;
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 12000; ++i) {
      const double x = u(rng), y = u(rng), z = u(rng);
      text += std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + " " + std::to_string(x) + " " +
              std::to_string(y) + " " + std::to_string(z + 0.01) + "\n";
    }
    write_text(dir / "many.controls", text);
  }
  const std::string fish = kExamples + "fish.obj";
  const std::string deform = "deform --mesh " + fish + " --radius 0.3 -o {dir}/out.obj --controls ";
  const std::vector<Case> cases{
      // Controls files.
      {"missing controls", deform + "{dir}/missing.controls", "missing.controls: no such file", 1},
      {"controls is a folder", deform + "{dir}/folder", "is a folder", 1},
      {"controls is a device", deform + "/dev/zero", "/dev/zero: is not a regular file", 1},
      {"NaN in controls", deform + "{dir}/nan.controls", "nan.controls:2", 1},
      {"infinity in controls", deform + "{dir}/inf.controls", "inf.controls:1", 1},
      {"five numbers", deform + "{dir}/short.controls", "short.controls:1", 1},
      {"a word", deform + "{dir}/words.controls", "'zero'", 1},
      {"no controls", deform + "{dir}/empty.controls", "empty.controls", 1},
      {"one source, two destinations", deform + "{dir}/conflict.controls", "conflict.controls:2", 1},
      {"binary garbage controls", deform + "{dir}/garbage.controls", "garbage.controls:", 1},
      // Meshes.
      {"missing mesh", "deform --mesh {dir}/missing.obj --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj",
       "missing.obj: no such file", 1},
      {"garbage OBJ", "deform --mesh {dir}/garbage.obj --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj",
       "garbage.obj", 1},
      {"truncated binary PLY",
       "deform --mesh {dir}/garbage.ply --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.ply", "garbage.ply", 1},
      {"garbage STL (assimp)",
       "deform --mesh {dir}/garbage.stl --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.stl", "garbage.stl", 1},
      {"face past the vertices",
       "deform --mesh {dir}/truncated.obj --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj",
       "truncated.obj:3", 1},
      {"bad number in a mesh",
       "deform --mesh {dir}/badnumber.obj --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj",
       "badnumber.obj:2", 1},
      {"no vertices", "deform --mesh {dir}/novertices.obj --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj",
       "no vertices", 1},
      {"OFF without header",
       "deform --mesh {dir}/noheader.off --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj", "noheader.off",
       1},
      {"mesh is a device", "deform --mesh /dev/urandom --controls {dir}/ok.controls --radius 0.3 -o {dir}/out.obj",
       "not a regular file", 1},
      // Options.
      {"radius 0", "deform --mesh " + fish + " --controls {dir}/ok.controls --radius 0 -o {dir}/out.obj", "--radius",
       2},
      {"radius NaN", "deform --mesh " + fish + " --controls {dir}/ok.controls --radius nan -o {dir}/out.obj",
       "--radius", 2},
      {"radius a word", "deform --mesh " + fish + " --controls {dir}/ok.controls --radius big -o {dir}/out.obj",
       "--radius", 2},
      {"unknown kernel", deform + "{dir}/ok.controls --kernel c3", "c3", 2},
      {"phase NaN", deform + "{dir}/ok.controls --phase nan", "--phase", 2},
      {"linear polynomial on a plane", deform + "{dir}/planar.controls --polynomial linear", "coplanar", 1},
      {"dense beyond the memory limit", "info --controls {dir}/many.controls --radius 100 --memory-limit 1",
       "GiB for its neighbour graph", 1},
      // Outputs.
      {"output folder missing",
       "deform --mesh " + fish + " --controls {dir}/ok.controls --radius 0.3 -o {dir}/no/out.obj", "no", 1},
      {"output is a folder", "deform --mesh " + fish + " --controls {dir}/ok.controls --radius 0.3 -o {dir}/folder",
       "folder", 1},
  };
  write_text(dir / "keep.obj", "precious");
  for (const auto& c : cases) {
    const auto before = csrbf::test::files_in(dir.path);
    const auto r = run_shell(kCli + " " + expand(c.args, d));
    EXPECT_EQ(r.code, c.code) << c.name << "\n" << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.name << ": the message should name '" << c.message << "'\n"
                                                        << r.out;
    EXPECT_EQ(csrbf::test::files_in(dir.path), before) << c.name << ": a file appeared";
    EXPECT_FALSE(fs::exists(dir / "out.obj")) << c.name;
  }
  // An existing output is untouched by a failed run, whichever input failed.
  for (const std::string bad : {"{dir}/nan.controls", "{dir}/garbage.controls"}) {
    const auto r =
        run_shell(kCli + " deform --mesh " + fish + " --radius 0.3 -o " + d + "/keep.obj --controls " + expand(bad, d));
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(read_text(dir / "keep.obj"), "precious");
  }
  // A full disk (a file size limit of 8 KiB: the fish needs 60 KiB) leaves the old file and nothing else.
  const auto before = csrbf::test::files_in(dir.path);
  const auto r = run_shell("ulimit -f 8; " + kCli + " deform --mesh " + fish + " --controls " + kExamples +
                           "fish.controls --radius 0.3 -o " + d + "/keep.obj");
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_EQ(read_text(dir / "keep.obj"), "precious");
  EXPECT_EQ(csrbf::test::files_in(dir.path), before);
}

TEST(BadInput, LibraryApi) {
  using namespace csrbf;
  const std::vector<Vec3> s{Vec3(0, 0, 0), Vec3(1, 0, 0)}, d{Vec3(0, 0, 0.1), Vec3(1, 0, 0)};
  const auto expect = [](auto&& f, const std::string& words) {
    try {
      f();
      ADD_FAILURE() << "no error; expected one naming '" << words << "'";
    } catch (const InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  expect([&] { SpaceMap::fit({}, {}, FitOptions{1.0}); }, "none given");
  expect([&] { SpaceMap::fit(s, std::vector<Vec3>{d[0]}, FitOptions{1.0}); }, "2 sources but 1 destinations");
  expect([&] { SpaceMap::fit(s, d, FitOptions{-1.0}); },
         "radius must be a positive finite number in [1e-150, 1e150], got -1");
  // Found by fuzz_spacemap: with R = 1e-304, R^2 underflows to 0 and two sources at one point passed
  // as different ones.
  expect([&] { SpaceMap::fit(std::vector<Vec3>{s[0], s[0]}, d, FitOptions{1e-304}); }, "[1e-150, 1e150]");
  expect(
      [&] {
        SpaceMap::fit(std::vector<Vec3>{Vec3(1e200, 0, 0), s[1]}, d, FitOptions{1.0});
      },
      "source 0 is out of range");
  expect([&] { SpaceMap::fit(s, d, FitOptions{NAN}); }, "radius must be a positive finite number");
  expect(
      [&] {
        SpaceMap::fit(std::vector<Vec3>{Vec3(0, NAN, 0), s[1]}, d, FitOptions{1.0});
      },
      "source 0 is not finite");
  expect(
      [&] {
        SpaceMap::fit(s, std::vector<Vec3>{d[0], Vec3(INFINITY, 0, 0)}, FitOptions{1.0});
      },
      "destination 1 is not finite");
  expect([&] { SpaceMap::fit(std::vector<Vec3>{s[0], s[0]}, d, FitOptions{1.0}); }, "same");
  expect([&] { SpaceMap::fit(s, d, FitOptions{1.0, Kernel::C2, Polynomial::Linear}); }, "linear");
  const auto map = SpaceMap::fit(s, d, FitOptions{1.0});
  expect([&] { map.map(Vec3::Zero(), NAN); }, "phase");
  std::vector<Vec3> out(1);
  expect([&] { map.apply(s, out); }, "sizes differ");
  expect([&] { map.with_destinations(std::vector<Vec3>{d[0]}); }, "2 sources but 1 destinations");
  // Dense beyond the memory limit: 30000 sources with R = 10 would need about 30 GiB.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> many(30000);
  for (auto& p : many) p = Vec3(u(rng), u(rng), u(rng));
  try {
    SpaceMap::fit(many, many, FitOptions{10.0});
    ADD_FAILURE() << "a dense 30000-source system was accepted";
  } catch (const ResourceLimit& e) {
    EXPECT_NE(std::string(e.what()).find("GiB for its neighbour graph and factor, above the limit of 4 GiB"),
              std::string::npos)
        << e.what();
  }
  // NaN points in apply give NaN out for that point only, never a crash; the others are exact.
  const double in[6] = {0, 0, 0, NAN, 0, 0};
  double o[6];
  map.apply(in, o, 2, 1.0);
  EXPECT_NEAR(o[2], 0.1, 1e-12);
  EXPECT_TRUE(std::isnan(o[3]));
}

TEST(BadInput, TenMillionVerticesFitInMemory) {
  // 1e7 vertices (120 MB in float, in and out) through the fast path: finite, and the ones far from
  // every control unmoved.
  const std::vector<Vec3> s{Vec3(0.5, 0.5, 0.5)}, d{Vec3(0.5, 0.5, 0.6)};
  const auto map = csrbf::SpaceMap::fit(s, d, csrbf::FitOptions{0.2});
  const std::size_t n = 10'000'000;
  std::vector<float> pts(3 * n), out(3 * n);
  std::mt19937 rng(6);
  std::uniform_real_distribution<float> u(0, 1);
  for (auto& x : pts) x = u(rng);
  map.apply(pts.data(), out.data(), n, 1.0);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_TRUE(std::isfinite(out[3 * i + 2]));
    const float dx = pts[3 * i] - 0.5f, dy = pts[3 * i + 1] - 0.5f, dz = pts[3 * i + 2] - 0.5f;
    if (dx * dx + dy * dy + dz * dz > 0.21f * 0.21f) {
      ASSERT_EQ(out[3 * i + 2], pts[3 * i + 2]);
    }
    moved += out[3 * i + 2] != pts[3 * i + 2];
  }
  EXPECT_GT(moved, n / 100);
}
