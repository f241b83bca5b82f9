// The OpenFOAM polyMesh reader and writer (csrbf/morph/openfoam.hpp): every encoding read as written
// and written back exactly, outputs refused, bad files named. OpenFOAM's own tools judge the
// results in tests/morph/test_openfoam.py.
#include "morph_test_helpers.hpp"
#include "csrbf/morph/openfoam.hpp"

#include <gtest/gtest.h>

#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
using csrbf::Vec3;
using namespace csrbf::morph;
using csrbf::test::bits;
using csrbf::test::BoxSpec;
using csrbf::test::error_of;
using csrbf::test::TempDir;

class Encodings : public ::testing::TestWithParam<std::pair<bool, bool>> {};

TEST_P(Encodings, ReadsTheBoxAsWritten) {
  TempDir dir;
  BoxSpec s;
  s.binary = GetParam().first;
  s.gzip = GetParam().second;
  const auto box = csrbf::test::write_box_case(dir.path / "case", s);
  const FoamCase c = read_openfoam(dir.path / "case");
  EXPECT_EQ(c.points_file.binary, s.binary);
  EXPECT_EQ(c.points_file.gzip, s.gzip);
  ASSERT_EQ(c.mesh.points.size(), box.points.size() / 3);
  for (std::size_t i = 0; i < c.mesh.points.size(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(c.mesh.points[i][k], box.points[3 * i + std::size_t(k)]);
  EXPECT_EQ(c.mesh.poly.cells, 24u);
  EXPECT_EQ(c.mesh.poly.faces(), box.faces.size());
  EXPECT_EQ(c.mesh.poly.internal_faces(), box.neighbour.size());
  ASSERT_EQ(c.mesh.patches.size(), 6u);
  EXPECT_EQ(c.mesh.patches[0].name, "xmin");
  EXPECT_EQ(c.mesh.patches[0].points.size(), 4u * 3u);  // (ny + 1)(nz + 1)
  EXPECT_EQ(c.mesh.patches[5].name, "zmax");
  EXPECT_EQ(c.mesh.patches[5].points.size(), 5u * 4u);
  // Unchanged points give back the file byte for byte; the polyMesh folder itself reads the same.
  EXPECT_EQ(foam_points_bytes(c, c.mesh.points), c.points_file.text);
  EXPECT_EQ(read_openfoam(dir.path / "case" / "constant" / "polyMesh").mesh.points, c.mesh.points);
}

TEST_P(Encodings, MovedPointsReadBackExactlyAndTheRestIsKept) {
  TempDir dir;
  BoxSpec s;
  s.binary = GetParam().first;
  s.gzip = GetParam().second;
  csrbf::test::write_box_case(dir.path / "case", s);
  const FoamCase c = read_openfoam(dir.path / "case");
  std::vector<Vec3> moved = c.mesh.points;
  for (std::size_t i = 0; i < moved.size(); i += 3) moved[i] += Vec3(1.0 / 3.0, -1e-7 * double(i), std::numbers::pi);
  write_openfoam_copy(c, moved, dir.path / "out");
  const FoamCase back = read_openfoam(dir.path / "out");
  ASSERT_EQ(back.mesh.points.size(), moved.size());
  for (std::size_t i = 0; i < moved.size(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(bits(back.mesh.points[i][k]), bits(moved[i][k])) << i;
  EXPECT_EQ(back.points_file.gzip, s.gzip);
  EXPECT_EQ(back.points_file.binary, s.binary);
  // Every other file is a byte-for-byte copy, and nothing else is left beside the output.
  for (const auto& e : fs::recursive_directory_iterator(dir.path / "case")) {
    if (!e.is_regular_file() || e.path().filename().string().rfind("points", 0) == 0) continue;
    const auto rel = fs::relative(e.path(), dir.path / "case");
    EXPECT_EQ(csrbf::test::read_text(dir.path / "out" / rel), csrbf::test::read_text(e.path())) << rel;
  }
  EXPECT_EQ(csrbf::test::files_in(dir.path), 2u);
  // The header and the footer of the points file are kept.
  const std::string& t = back.points_file.text;
  EXPECT_EQ(t.substr(0, back.points_file.body_begin), c.points_file.text.substr(0, c.points_file.body_begin));
  EXPECT_NE(t.find("// end"), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Morph, Encodings,
                         ::testing::Values(std::pair{false, false}, std::pair{true, false}, std::pair{false, true},
                                           std::pair{true, true}),
                         [](const auto& info) {
                           return std::string(info.param.first ? "Binary" : "Ascii") +
                                  (info.param.second ? "Gzip" : "");
                         });

TEST(OpenFoam, InPlaceRewritesThePointsAlone) {
  TempDir dir;
  csrbf::test::write_box_case(dir.path / "case", {});
  const FoamCase c = read_openfoam(dir.path / "case");
  const std::string faces = csrbf::test::read_text(c.poly_mesh / "faces");
  std::vector<Vec3> moved = c.mesh.points;
  moved[0] = Vec3(-0.25, 0.125, 1e-300);
  write_openfoam_in_place(c, moved);
  EXPECT_EQ(read_openfoam(dir.path / "case").mesh.points, moved);
  EXPECT_EQ(csrbf::test::read_text(c.poly_mesh / "faces"), faces);
  EXPECT_EQ(csrbf::test::files_in(c.poly_mesh), 5u);
}

TEST(OpenFoam, RefusesOutputsThatExistOrLieInsideTheCase) {
  TempDir dir;
  csrbf::test::write_box_case(dir.path / "case", {});
  const FoamCase c = read_openfoam(dir.path / "case");
  fs::create_directories(dir.path / "empty");
  EXPECT_NE(error_of([&] { write_openfoam_copy(c, c.mesh.points, dir.path / "empty"); }).find("it exists"),
            std::string::npos);
  EXPECT_TRUE(fs::is_empty(dir.path / "empty"));
  EXPECT_NE(
      error_of([&] { write_openfoam_copy(c, c.mesh.points, dir.path / "case" / "copy"); }).find("inside the case"),
      std::string::npos);
  EXPECT_FALSE(fs::exists(dir.path / "case" / "copy"));
  EXPECT_NE(error_of([&] { write_openfoam_copy(c, c.mesh.points, dir.path / "no" / "such"); }), "");
  // A case named through a link is copied from the folder it links to (the link itself was copied
  // onto the new folder: "Invalid argument"); the case is left as it was.
  fs::create_directory_symlink("case", dir.path / "link");
  const FoamCase linked = read_openfoam(dir.path / "link");
  std::vector<Vec3> moved = c.mesh.points;
  moved[1] = Vec3(0.5, 0.25, 0.125);
  write_openfoam_copy(linked, moved, dir.path / "from-link");
  EXPECT_EQ(read_openfoam(dir.path / "from-link").mesh.points, moved);
  EXPECT_FALSE(fs::is_symlink(dir.path / "from-link"));
  EXPECT_EQ(read_openfoam(dir.path / "case").mesh.points, c.mesh.points);
}

TEST(OpenFoam, BadFilesAreClearErrorsNamingTheFile) {
  TempDir dir;
  const auto poly = dir.path / "case" / "constant" / "polyMesh";
  const auto fresh = [&](BoxSpec s = {}) {
    fs::remove_all(dir.path / "case");
    csrbf::test::write_box_case(dir.path / "case", s);
  };
  const auto read_error = [&] { return error_of([&] { read_openfoam(dir.path / "case"); }); };
  const auto edit = [&](const char* file, const std::string& from, const std::string& to) {
    std::string t = csrbf::test::read_text(poly / file);
    const auto at = t.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    t.replace(at, from.size(), to);
    csrbf::test::write_text(poly / file, t);
  };

  fresh();
  fs::remove(poly / "owner");
  EXPECT_NE(read_error().find("no 'owner' or 'owner.gz'"), std::string::npos);

  fresh();
  edit("points", "60\n(", "6000000000\n(");  // a count that lies: refused before anything is allocated
  EXPECT_NE(read_error().find("cannot fit in the"), std::string::npos) << read_error();

  fresh();
  edit("points", "60\n(", "61\n(");  // one more than there are
  EXPECT_NE(read_error().find("points:"), std::string::npos);
  EXPECT_NE(read_error().find("expected '('"), std::string::npos) << read_error();

  fresh();
  edit("points", "60\n(", "59\n(");  // one fewer
  EXPECT_NE(read_error().find("more points than the count"), std::string::npos) << read_error();

  fresh();
  edit("faces", "4(1 6 26 21)", "4(1 6 26 600)");  // a label past the points
  EXPECT_NE(read_error().find("uses point 600, but there are 60 points"), std::string::npos) << read_error();

  // The four files are parsed at once; with several broken, the error is the one a serial read
  // meets first (points, faces, owner, neighbour), whatever the threads' timing: it named owner or
  // points by chance before.
  fresh();
  edit("points", "60\n(", "59\n(");
  edit("faces", "4(1 6 26 21)", "4(1 6 26 600)");
  edit("owner", "(", "(x");
  for (int i = 0; i < 10; ++i) EXPECT_NE(read_error().find("more points than the count"), std::string::npos);
  fresh();
  edit("faces", "4(1 6 26 21)", "4(1 6 26 600)");
  edit("owner", "(", "(x");
  for (int i = 0; i < 10; ++i) EXPECT_NE(read_error().find("uses point 600"), std::string::npos) << read_error();

  fresh();
  edit("points", "(0 0 0)", "(0 nan 0)");
  EXPECT_NE(read_error().find("is not finite"), std::string::npos) << read_error();

  fresh();
  edit("boundary", "nFaces 6;", "nFaces 7;");  // xmin then overlaps xmax
  EXPECT_NE(read_error().find("patch 'xmax': startFace 52, expected 53"), std::string::npos) << read_error();
  fresh();
  edit("boundary", "startFace 52;", "startFace 5200;");
  EXPECT_NE(read_error().find("patch 'xmax': startFace 5200 + nFaces 6 passes the 98 faces"), std::string::npos)
      << read_error();

  fresh();
  edit("owner", "format      ascii", "format      binary");  // a header that lies about the format
  EXPECT_NE(read_error().find("owner"), std::string::npos) << read_error();

  fresh();
  edit("points", "FoamFile", "/* never closed FoamFile");
  EXPECT_NE(read_error().find("never ends"), std::string::npos) << read_error();

  // Binary: truncated data, and a header that claims more than the file holds.
  BoxSpec b;
  b.binary = true;
  fresh(b);
  {
    std::string t = csrbf::test::read_text(poly / "points");
    csrbf::test::write_text(poly / "points", t.substr(0, t.size() - 200));
  }
  EXPECT_NE(read_error().find("truncated"), std::string::npos) << read_error();
  fresh(b);
  edit("owner", "\n(", "0\n(");  // 78 owners become 780
  EXPECT_NE(read_error().find("owner"), std::string::npos) << read_error();

  // gzip: corrupt and truncated streams.
  BoxSpec g;
  g.gzip = true;
  fresh(g);
  {
    std::string t = csrbf::test::read_text(poly / "points.gz");
    csrbf::test::write_text(poly / "points.gz", t.substr(0, t.size() / 2));
  }
  EXPECT_NE(read_error().find("truncated gzip"), std::string::npos) << read_error();
  fresh(g);
  {
    std::string t = csrbf::test::read_text(poly / "faces.gz");
    for (std::size_t i = 20; i < 60; ++i) t[i] = char(t[i] ^ 0x5a);
    csrbf::test::write_text(poly / "faces.gz", t);
  }
  EXPECT_NE(read_error().find("faces.gz"), std::string::npos) << read_error();

  EXPECT_NE(error_of([&] { read_openfoam(dir.path / "nowhere"); }).find("not a folder"), std::string::npos);
  fs::create_directories(dir.path / "plain");
  EXPECT_NE(error_of([&] { read_openfoam(dir.path / "plain"); }).find("not an OpenFOAM case"), std::string::npos);
}
