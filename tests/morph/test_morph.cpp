// csrbf::morph: the OpenFOAM reader and writer, the motion file, the morph and its quality measures.
// OpenFOAM's own tools judge the results in tests/morph/test_openfoam.py.
#include "box_case.hpp"
#include "cgns_box.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "csrbf/morph/quality.hpp"
#include "csrbf/morph/volume_file.hpp"
#include "io/test_helpers.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <bit>
#include <sys/stat.h>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

namespace fs = std::filesystem;
using csrbf::Vec3;
using csrbf::io::FileError;
using namespace csrbf::morph;
using csrbf::test::BoxSpec;
using csrbf::test::TempDir;

namespace {

/// The message of the FileError f throws ("" if it throws none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

Motion motion_from(const TempDir& dir, const std::string& json) {
  csrbf::test::write_text(dir / "motion.json", json);
  return read_motion(dir / "motion.json");
}

std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

}  // namespace

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

// Quality: closed forms on boxes.
TEST(Quality, UnitCellsHaveTheirVolumeAndNoNonOrthogonality) {
  const auto box = csrbf::test::make_box({});
  TempDir dir;
  csrbf::test::write_box_case(dir.path / "case", {});
  const FoamCase c = read_openfoam(dir.path / "case");
  const PolyQuality q = poly_quality(c.mesh.poly, c.mesh.points);
  EXPECT_EQ(q.cells, 24u);
  EXPECT_NEAR(q.min_volume, 0.125, 1e-15);
  EXPECT_NEAR(q.total_volume, 24 * 0.125, 1e-13);
  EXPECT_NEAR(q.max_non_orthogonality, 0.0, 1e-6);
  EXPECT_NEAR(q.max_skewness, 0.0, 1e-12);
  EXPECT_EQ(q.inverted_cells, 0u);
  EXPECT_EQ(q.bad_pyramids, 0u);
  // The cell determinant of a cube is (internal faces along x)(along y)(along z) / 8: 1 x 1 x 1 at a
  // corner of the 4 x 3 x 2 box; the mean is (6/4)(4/3)(2/2) / 8.
  EXPECT_NEAR(q.min_determinant, 0.125, 1e-15);
  EXPECT_NEAR(q.mean_determinant, 0.25, 1e-15);
  // A uniform scaling changes no determinant (faces are scaled by their mean).
  std::vector<Vec3> big = c.mesh.points;
  for (Vec3& p : big) p *= 7.0;
  EXPECT_NEAR(poly_quality(c.mesh.poly, big).min_determinant, 0.125, 1e-14);
  (void)box;
}

TEST(Quality, ShearGivesItsAngleAsNonOrthogonality) {
  for (const double shear : {0.1, 0.5, 1.0}) {
    TempDir dir;
    BoxSpec s;
    s.warp = [shear](int, int, int, double& x, double& y, double&) { x += shear * y; };
    csrbf::test::write_box_case(dir.path / "case", s);
    const FoamCase c = read_openfoam(dir.path / "case");
    const PolyQuality q = poly_quality(c.mesh.poly, c.mesh.points);
    EXPECT_NEAR(q.max_non_orthogonality, std::atan(shear) * 180 / std::numbers::pi, 1e-9) << shear;
    EXPECT_NEAR(q.min_volume, 0.125, 1e-14);  // a shear keeps volumes
    EXPECT_EQ(q.inverted_cells, 0u);
  }
}

TEST(Quality, APointPushedThroughItsCellInvertsIt) {
  TempDir dir;
  BoxSpec s;
  s.nx = s.ny = s.nz = 3;
  csrbf::test::write_box_case(dir.path / "case", s);
  const FoamCase c = read_openfoam(dir.path / "case");
  std::vector<Vec3> p = c.mesh.points;
  p[1 + 4 * (1 + 4 * 1)] += Vec3(0.9, 0.9, 0.9);  // interior point (1,1,1) past (2,2,2)'s cell
  const PolyQuality q = poly_quality(c.mesh.poly, p);
  EXPECT_GT(q.inverted_cells, 0u);
  EXPECT_GT(q.bad_pyramids, 0u);
}

// Motion files.
TEST(Motion, ReadsEveryKindAndRefusesBadValuesByPath) {
  TempDir dir;
  csrbf::test::write_text(dir / "d.txt", "# id dx dy dz\n3 0.1 0 0\n7 0 0.2 0 # trailing comment\n");
  const Motion m = motion_from(dir, R"({"radius": 2, "kernel": "c4", "polynomial": "linear", "patches": {
      "a": "fixed", "b": {"translate": [1, 2, 3]}, "c": {"rotate": {"axis": [0, 0, 2], "degrees": 90, "origin": [1, 0, 0]}},
      "d": {"displacements": "d.txt"}}})");
  EXPECT_EQ(*m.radius, 2.0);
  EXPECT_EQ(*m.kernel, csrbf::Kernel::C4);
  EXPECT_EQ(*m.polynomial, csrbf::Polynomial::Linear);
  ASSERT_EQ(m.patches.size(), 4u);
  EXPECT_EQ(m.patches[0].kind, PatchMotion::Kind::Fixed);
  EXPECT_EQ(m.patches[1].displacement(Vec3(5, 5, 5)), Vec3(1, 2, 3));
  // 90 degrees about z through (1, 0, 0): (2, 0, 0) goes to (1, 1, 0).
  EXPECT_NEAR((m.patches[2].displacement(Vec3(2, 0, 0)) - Vec3(-1, 1, 0)).norm(), 0.0, 1e-15);
  ASSERT_EQ(m.patches[3].given.size(), 2u);
  EXPECT_EQ(m.patches[3].given[1].point, 7u);
  EXPECT_EQ(m.patches[3].given[1].line, 3u);

  const auto err = [&](const std::string& json) { return error_of([&] { motion_from(dir, json); }); };
  EXPECT_NE(err(R"({"patches": {"w": {"rotate": {"axis": [0, 0, 0], "degrees": 5}}}})").find("patches.w.rotate.axis"),
            std::string::npos);
  EXPECT_NE(err(R"({"patches": {"w": "moving"}})").find("patches.w"), std::string::npos);
  EXPECT_NE(err(R"({"patches": {"w": {"translate": [0, 1]}}})").find("patches.w.translate"), std::string::npos);
  EXPECT_NE(err(R"({"patches": {}})").find("patches"), std::string::npos);
  EXPECT_NE(err(R"({"radius": -1, "patches": {"w": "fixed"}})").find("radius"), std::string::npos);
  EXPECT_NE(err(R"({"kernel": "c3", "patches": {"w": "fixed"}})").find("kernel"), std::string::npos);
  EXPECT_NE(err(R"({"patches": {"w": "fixed"}, "extra": 1})").find("extra"), std::string::npos);
  csrbf::test::write_text(dir / "bad.txt", "3 0.1 0\n");
  EXPECT_NE(err(R"({"patches": {"w": {"displacements": "bad.txt"}}})").find("bad.txt:1"), std::string::npos);
  csrbf::test::write_text(dir / "bad.txt", "3 0.1 0 inf\n");
  EXPECT_NE(err(R"({"patches": {"w": {"displacements": "bad.txt"}}})").find("not a finite number"), std::string::npos);
  EXPECT_NE(err(R"({"patches": {"w": {"displacements": "missing.txt"}}})").find("missing.txt"), std::string::npos);
}

class BoxMorph : public ::testing::Test {
 protected:
  void SetUp() override {
    BoxSpec s;
    s.nx = s.ny = s.nz = 6;
    s.h = 1.0 / 6;
    csrbf::test::write_box_case(dir.path / "case", s);
    c = read_openfoam(dir.path / "case");
  }
  TempDir dir;
  FoamCase c;
};

TEST_F(BoxMorph, PatchesResolveWithTheirRules) {
  // zmin moves, xmin is fixed: their shared edge moves.
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.01]}, "xmin": "fixed"}})");
  const Prescribed p = prescribe(c.mesh, m);
  EXPECT_EQ(p.points.size(), 49u + 49u - 7u);
  EXPECT_EQ(p.moving(), 49u);
  for (std::size_t i = 0; i < p.points.size(); ++i)
    if (c.mesh.points[p.points[i]].z() == 0) {
      EXPECT_FALSE(p.fixed[i]) << p.points[i];
    }

  // Issue 31, point 7: a patch moved by 0 and a rotation's points on its axis do not count as moving.
  const Motion still = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0]}, "xmin": "fixed"}})");
  EXPECT_EQ(prescribe(c.mesh, still).moving(), 0u);
  const Motion turn = motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [0, 0, 1], "degrees": 5,
                                                                 "origin": [0, 0, 0]}}}})");
  EXPECT_EQ(prescribe(c.mesh, turn).moving(), 48u);  // the corner at the origin stays

  // Two moving patches that disagree at their shared edge.
  const std::string e = error_of([&] {
    prescribe(
        c.mesh,
        motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.01]}, "xmin": {"translate": [0.01, 0, 0]}}})"));
  });
  EXPECT_NE(e.find("patch 'xmin'"), std::string::npos) << e;
  EXPECT_NE(e.find("patch 'zmin'"), std::string::npos) << e;
  EXPECT_NE(e.find("point 0 "), std::string::npos) << e;
  // Agreeing ones are fine.
  EXPECT_EQ(
      prescribe(c.mesh,
                motion_from(
                    dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.01]}, "xmin": {"translate": [0, 0, 0.01]}}})"))
          .moving(),
      91u);

  EXPECT_NE(error_of([&] {
              prescribe(c.mesh, motion_from(dir, R"({"patches": {"wing": "fixed"}})"));
            }).find("its patches: xmin, xmax"),
            std::string::npos);
}

TEST_F(BoxMorph, DisplacementFilesAreCheckedAgainstThePatch) {
  const Patch& zmin = *c.mesh.patch("zmin");
  std::string all;
  for (const auto p : zmin.points) all += std::to_string(p) + " 0 0 0.01\n";
  csrbf::test::write_text(dir / "z.txt", all);
  const std::string json = R"({"patches": {"zmin": {"displacements": "z.txt"}}})";
  EXPECT_EQ(prescribe(c.mesh, motion_from(dir, json)).moving(), 49u);
  const auto err = [&](const std::string& text) {
    csrbf::test::write_text(dir / "z.txt", text);
    return error_of([&] { prescribe(c.mesh, motion_from(dir, json)); });
  };
  EXPECT_NE(err(all + "343 0 0 0\n").find("out of range: the mesh has 343 points"), std::string::npos);
  EXPECT_NE(err(all + "342 0 0 0\n").find("z.txt:50: point 342 is not on patch 'zmin'"), std::string::npos);
  EXPECT_NE(err(all + "0 0 0 0\n").find("given twice (also on line 1)"), std::string::npos);
  EXPECT_NE(err("0 0 0 0.01\n").find("48 of the 49 points of patch 'zmin' have no displacement"), std::string::npos);
}

TEST_F(BoxMorph, InteriorPointsFollowTheDenseInterpolantAndBoundariesLandExactly) {
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "xmin": "fixed", "xmax": "free",
                                                    "ymin": "free", "ymax": "free"}})");
  MorphOptions o;
  o.fit.radius = 0.6;
  const MorphResult r = morph(c.mesh, m, o);
  const Prescribed p = prescribe(c.mesh, m);
  // The controls: every moving point, and every staying one within R of a moving one (exact
  // locality), by brute force.
  std::vector<std::uint32_t> fitted;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    bool keep = p.displacements[i] != Vec3::Zero();
    for (std::size_t j = 0; j < p.points.size() && !keep; ++j)
      keep = p.displacements[j] != Vec3::Zero() &&
             (c.mesh.points[p.points[i]] - c.mesh.points[p.points[j]]).norm() < o.fit.radius;
    if (keep) fitted.push_back(std::uint32_t(i));
  }
  EXPECT_LT(fitted.size(), p.points.size());  // zmax, 1 from zmin, is left out
  EXPECT_EQ(r.report.far_fixed, p.points.size() - fitted.size());
  EXPECT_EQ(r.report.reach, 1.2);
  // The dense solve of the whole system: A alpha = d over the controls (C2, no polynomial).
  const std::size_t n = fitted.size();
  Eigen::MatrixXd A(n, n);
  Eigen::MatrixXd d(n, 3);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j)
      A(Eigen::Index(i), Eigen::Index(j)) = csrbf::wendland(
          csrbf::Kernel::C2, (c.mesh.points[p.points[fitted[i]]] - c.mesh.points[p.points[fitted[j]]]).norm() / 0.6);
    d.row(Eigen::Index(i)) = p.displacements[fitted[i]].transpose();
  }
  const Eigen::MatrixXd alpha = A.llt().solve(d);
  std::vector<char> prescribed(c.mesh.points.size(), 0);
  for (const auto q : p.points) prescribed[q] = 1;
  const double scale = r.report.max_displacement;
  EXPECT_GT(scale, 0.02);
  std::size_t moved = 0;
  for (std::size_t q = 0; q < c.mesh.points.size(); ++q) {
    if (prescribed[q]) continue;
    Vec3 want = c.mesh.points[q];
    for (std::size_t j = 0; j < n; ++j)
      want += alpha.row(Eigen::Index(j)).transpose() *
              csrbf::wendland(csrbf::Kernel::C2, (c.mesh.points[q] - c.mesh.points[p.points[fitted[j]]]).norm() / 0.6);
    EXPECT_NEAR((r.points[q] - want).norm(), 0.0, 1e-10 * scale) << q;
    moved += r.points[q] != c.mesh.points[q];
  }
  EXPECT_GT(moved, 50u);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t q = p.points[i];
    if (p.fixed[i]) {
      for (int k = 0; k < 3; ++k) EXPECT_EQ(bits(r.points[q][k]), bits(c.mesh.points[q][k]));
    } else {
      EXPECT_NEAR((r.points[q] - (c.mesh.points[q] + p.displacements[i])).norm(), 0.0, 1e-15);
    }
  }
  EXPECT_LT(r.report.max_boundary_error, 1e-12);
  EXPECT_EQ(r.report.controls, n);
  // The phase scales the whole motion.
  o.phase = 0.5;
  const MorphResult half = morph(c.mesh, m, o);
  for (std::size_t q = 0; q < c.mesh.points.size(); ++q)
    EXPECT_NEAR((half.points[q] - c.mesh.points[q] - 0.5 * (r.points[q] - c.mesh.points[q])).norm(), 0.0, 1e-14);
}

/// A 12^3 box case of side 1, written into dir and read back.
static FoamCase box12(const TempDir& dir) {
  BoxSpec spec;
  spec.nx = spec.ny = spec.nz = 12;
  spec.h = 1.0 / 12;
  csrbf::test::write_box_case(dir.path / "case", spec);
  return read_openfoam(dir.path / "case");
}

// Issue 31, point 1: exact locality as a contract. With polynomial none, a point 2R or farther from
// every moving control keeps its coordinates bit for bit, for every kernel, with or without greedy:
// staying controls carried coefficients of 1e-16 and moved the whole connected mesh (a flow
// solver's residuals jumped 63x on such a mesh). Measured on a 12^3 box, zmin moving, R = 0.3.
TEST(ExactLocality, PointsTwoRadiiFromEveryMovingOneKeepTheirBits) {
  TempDir dir;
  const FoamCase c = box12(dir);
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 4, "origin": [0.5, 0.5, 0]}},
                             "zmax": "fixed", "xmin": "fixed", "xmax": "fixed", "ymin": "fixed", "ymax": "fixed"}})");
  const Prescribed p = prescribe(c.mesh, m);
  std::vector<Vec3> moving;
  for (std::size_t i = 0; i < p.points.size(); ++i)
    if (p.displacements[i] != Vec3::Zero()) moving.push_back(c.mesh.points[p.points[i]]);
  const double radius = 0.3;
  for (const auto kernel : {csrbf::Kernel::C0, csrbf::Kernel::C2, csrbf::Kernel::C4, csrbf::Kernel::C6})
    for (const int variant : {0, 1, 2}) {  // plain, greedy, two levels
      const double greedy = variant == 1 ? 1e-3 : 0.0;
      SCOPED_TRACE(std::string(csrbf::kernel_name(kernel)) + (variant == 1   ? " greedy"
                                                              : variant == 2 ? " two levels"
                                                                             : ""));
      MorphOptions o;
      o.fit.radius = radius;
      o.fit.kernel = kernel;
      o.greedy = greedy;
      o.levels = variant == 2 ? 2 : 1;
      const MorphResult r = morph(c.mesh, m, o);
      EXPECT_EQ(r.report.levels, o.levels);
      EXPECT_EQ(r.report.reach, 2 * radius);
      std::size_t far = 0, near_moved = 0;
      for (std::size_t q = 0; q < c.mesh.points.size(); ++q) {
        double nearest = std::numeric_limits<double>::infinity();
        for (const Vec3& s : moving) nearest = std::min(nearest, (c.mesh.points[q] - s).norm());
        if (nearest >= 2 * radius) {
          ++far;
          for (int k = 0; k < 3; ++k) EXPECT_EQ(bits(r.points[q][k]), bits(c.mesh.points[q][k])) << q;
        } else if (nearest < radius) {
          near_moved += r.points[q] != c.mesh.points[q];
        }
      }
      EXPECT_GT(far, 700u);         // z >= 0.6: 6 of 13 layers of 169 points
      EXPECT_GT(near_moved, 300u);  // the field itself is there
    }
  // A polynomial moves the whole space: no reach.
  MorphOptions linear;
  linear.fit.radius = radius;
  linear.fit.polynomial = csrbf::Polynomial::Linear;
  EXPECT_TRUE(std::isinf(morph(c.mesh, m, linear).report.reach));
}

// A far point's -0 stays -0 (bit for bit, as the reach promises) where a slip patch brings the
// correction's branch and the placement of slip points in (the attacker's finding: -0 came back 0).
TEST(ExactLocality, NegativeZeroStaysNegativeZeroWithSlipPatches) {
  TempDir dir;
  FoamCase c = box12(dir);
  std::vector<std::uint32_t> signed_zero;
  for (const auto p : c.mesh.patch("ymin")->points)
    if (c.mesh.points[p].z() >= 0.75 && c.mesh.points[p].x() > 0 && c.mesh.points[p].x() < 1) {
      c.mesh.points[p].y() = -0.0;
      signed_zero.push_back(p);
    }
  ASSERT_GT(signed_zero.size(), 10u);
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0.02, 0.01, 0.03]}, "zmax": "fixed",
                                          "xmin": "fixed", "xmax": "fixed", "ymin": "slip", "ymax": "slip"}})");
  for (const int levels : {1, 2}) {
    MorphOptions o;
    o.fit.radius = 0.3;
    o.levels = levels;
    const MorphResult r = morph(c.mesh, m, o);
    for (const auto p : signed_zero) EXPECT_TRUE(std::signbit(r.points[p].y())) << p << " levels " << levels;
  }
}

// Two levels (MorphOptions::levels): a coarse fit at R of the controls no two of which are closer
// than R / 4 (taken in the controls' order), then a fit at the fine radius of what it leaves at
// every control. Checked against the two dense solves, done here by brute force, on a 12^3 box.
TEST(TwoLevels, AreTheSumOfTwoDenseSolvesAndExactAtTheControls) {
  TempDir dir;
  const FoamCase c = box12(dir);
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 4, "origin": [0.5, 0.5, 0]}},
                             "zmax": "fixed", "xmin": "fixed", "xmax": "free", "ymin": "free", "ymax": "free"}})");
  const double R = 0.6;
  MorphOptions o;
  o.fit.radius = R;
  o.levels = 2;
  const MorphResult r = morph(c.mesh, m, o);
  const Prescribed p = prescribe(c.mesh, m);
  // The controls: moving, and staying within R of a moving one, in the prescribed points' order.
  std::vector<Vec3> x, d;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    bool keep = p.displacements[i] != Vec3::Zero();
    for (std::size_t j = 0; j < p.points.size() && !keep; ++j)
      keep = p.displacements[j] != Vec3::Zero() && (c.mesh.points[p.points[i]] - c.mesh.points[p.points[j]]).norm() < R;
    if (!keep) continue;
    x.push_back(c.mesh.points[p.points[i]]);
    d.push_back(p.displacements[i]);
  }
  // The coarse controls, first come first taken, by brute force.
  EXPECT_DOUBLE_EQ(r.report.coarse_spacing, R / 4);
  std::vector<std::size_t> coarse;
  for (std::size_t i = 0; i < x.size(); ++i) {
    bool free = true;
    for (const std::size_t j : coarse) free = free && (x[i] - x[j]).norm() >= R / 4;
    if (free) coarse.push_back(i);
  }
  EXPECT_EQ(r.report.levels, 2);
  EXPECT_EQ(r.report.coarse_controls, coarse.size());
  EXPECT_GT(coarse.size(), 20u);
  EXPECT_LT(coarse.size(), x.size() / 3);  // 70 of 261
  // The fine radius: 1.75 x the boundary's spacing, here the grid's 1/12.
  const double Rf = r.report.fine_radius;
  EXPECT_NEAR(Rf, 1.75 / 12, 1e-12);
  EXPECT_EQ(r.report.reach, 2 * R);
  const auto dense = [](const std::vector<Vec3>& at, const Eigen::MatrixXd& rhs, double radius) {
    const auto n = Eigen::Index(at.size());
    Eigen::MatrixXd A(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < n; ++j)
        A(i, j) = csrbf::wendland(csrbf::Kernel::C2, (at[std::size_t(i)] - at[std::size_t(j)]).norm() / radius);
    return Eigen::MatrixXd(A.llt().solve(rhs));
  };
  const auto sum = [](const std::vector<Vec3>& at, const Eigen::MatrixXd& alpha, double radius, const Vec3& q) {
    Vec3 v = Vec3::Zero();
    for (std::size_t j = 0; j < at.size(); ++j)
      v += alpha.row(Eigen::Index(j)).transpose() * csrbf::wendland(csrbf::Kernel::C2, (q - at[j]).norm() / radius);
    return v;
  };
  std::vector<Vec3> xc;
  Eigen::MatrixXd dc(Eigen::Index(coarse.size()), 3);
  for (std::size_t k = 0; k < coarse.size(); ++k) {
    xc.push_back(x[coarse[k]]);
    dc.row(Eigen::Index(k)) = d[coarse[k]].transpose();
  }
  const Eigen::MatrixXd ac = dense(xc, dc, R);
  Eigen::MatrixXd left(Eigen::Index(x.size()), 3);
  for (std::size_t i = 0; i < x.size(); ++i) left.row(Eigen::Index(i)) = (d[i] - sum(xc, ac, R, x[i])).transpose();
  EXPECT_GT(left.cwiseAbs().maxCoeff(), 1e-4);  // the coarse level alone misses the controls
  const Eigen::MatrixXd af = dense(x, left, Rf);
  std::vector<char> prescribed(c.mesh.points.size(), 0);
  for (const auto q : p.points) prescribed[q] = 1;
  const double scale = r.report.max_displacement;
  std::size_t compared = 0;
  for (std::size_t q = 0; q < c.mesh.points.size(); ++q) {
    if (prescribed[q]) continue;
    const Vec3 want = c.mesh.points[q] + sum(xc, ac, R, c.mesh.points[q]) + sum(x, af, Rf, c.mesh.points[q]);
    EXPECT_NEAR((r.points[q] - want).norm(), 0.0, 1e-10 * scale) << q;
    ++compared;
  }
  EXPECT_GT(compared, 1000u);
  // Exact at the controls before their exact placement, as one level is.
  EXPECT_LT(r.report.max_boundary_error, 1e-12 * scale);
  EXPECT_EQ(r.report.controls, x.size());
  // Auto: this fit is far below a second, one level.
  o.levels = 0;
  const MorphResult a = morph(c.mesh, m, o);
  EXPECT_EQ(a.report.levels, 1);
  EXPECT_GT(a.report.seconds_plain_predicted, 0.0);
  EXPECT_LT(a.report.seconds_plain_predicted, 1.0);
  // Two levels and what excludes them.
  o.levels = 3;
  EXPECT_THROW(morph(c.mesh, m, o), csrbf::InvalidInput);
  o.levels = 2;
  o.greedy = 1e-3;
  EXPECT_THROW(morph(c.mesh, m, o), csrbf::InvalidInput);
  o.greedy = 0;
  o.fit.polynomial = csrbf::Polynomial::Linear;
  EXPECT_THROW(morph(c.mesh, m, o), csrbf::InvalidInput);
}

// Auto's R with two levels (issue 31, a new user's finding): where one level would pass the memory
// budget and two levels fit it, R is kept and two levels are taken, where before R was cut to what
// one level could hold (and the smaller R inverted cells on windAroundBuildings).
TEST(TwoLevels, AutoRadiusIsKeptWhereTwoLevelsFitTheMemory) {
  TempDir dir;
  const FoamCase c = box12(dir);
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.05]}, "zmax": "fixed",
                                          "xmin": "fixed", "xmax": "fixed", "ymin": "fixed", "ymax": "fixed"}})");
  const auto run = [&](double limit_bytes, int levels) {
    MorphOptions o;
    o.radius_auto = true;
    o.fit.memory_limit_bytes = limit_bytes;
    o.levels = levels;
    return morph(c.mesh, m, o);
  };
  const MorphResult free = run(4e9, 0);
  EXPECT_NEAR(free.report.radius, 1.0, 1e-12);  // 20 x 0.05
  EXPECT_EQ(free.report.levels, 1);
  EXPECT_NE(free.report.levels_why.find("auto: one level"), std::string::npos) << free.report.levels_why;
  // Half of one level's predicted memory: one level cannot hold R = 1, two levels can.
  const double one = free.report.predicted.bytes;
  const MorphResult two = run(one, 0);
  EXPECT_NEAR(two.report.radius, 1.0, 1e-12);
  EXPECT_NE(two.report.radius_why.find("in two levels"), std::string::npos) << two.report.radius_why;
  EXPECT_EQ(two.report.levels, 2);
  EXPECT_NE(two.report.levels_why.find("memory budget"), std::string::npos) << two.report.levels_why;
  EXPECT_LT(two.report.max_boundary_error, 1e-12);
  // Asked for one level: R shrinks to what one level holds, as before.
  const MorphResult cut = run(one, 1);
  EXPECT_LT(cut.report.radius, 1.0);
  EXPECT_EQ(cut.report.levels, 1);
  EXPECT_EQ(cut.report.levels_why, "asked for");
}

TEST_F(BoxMorph, GreedyUsesFewerControlsWithinItsTolerance) {
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "xmin": "fixed", "xmax": "fixed"}})");
  MorphOptions o;
  o.fit.radius = 0.8;
  o.greedy = 0.05;
  // Unbounded: a loaded machine (the sanitizer pass) must not stop greedy by its time budget.
  o.greedy_budget = std::numeric_limits<double>::infinity();
  const MorphResult r = morph(c.mesh, m, o);
  const Prescribed p = prescribe(c.mesh, m);
  EXPECT_LT(r.report.controls, p.points.size());
  EXPECT_GE(r.report.greedy_rounds, 2u);
  EXPECT_LE(r.report.max_boundary_error, 0.05 * r.report.max_displacement);
  for (std::size_t i = 0; i < p.points.size(); ++i)
    EXPECT_NEAR((r.points[p.points[i]] - (c.mesh.points[p.points[i]] + p.displacements[i])).norm(), 0.0, 1e-15);
  // A tighter tolerance takes more controls.
  o.greedy = 1e-3;
  const MorphResult tight = morph(c.mesh, m, o);
  EXPECT_GT(tight.report.controls, r.report.controls);
  EXPECT_LE(tight.report.max_boundary_error, 1e-3 * r.report.max_displacement);
}

TEST_F(BoxMorph, TheLargestSafePhaseInvertsNothing) {
  // zmin pushed up by more than a cell layer: the first layer inverts.
  const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, 0.4]}, "zmax": "fixed"}})");
  MorphOptions o;
  o.fit.radius = 0.3;
  const MorphResult r = morph(c.mesh, m, o);
  const PolyQuality after = poly_quality(c.mesh.poly, r.points);
  ASSERT_GT(after.inverted_cells, 0u);
  const double s = largest_safe_phase(c.mesh, r.points, 1.0, 0);
  EXPECT_GT(s, 0.1);
  EXPECT_LT(s, 1.0);
  const auto at = [&](double t) {
    std::vector<Vec3> p(r.points.size());
    for (std::size_t i = 0; i < p.size(); ++i) p[i] = c.mesh.points[i] + t * (r.points[i] - c.mesh.points[i]);
    return poly_quality(c.mesh.poly, p).inverted_cells;
  };
  EXPECT_EQ(at(s), 0u);
  EXPECT_GT(at(s + 2e-4), 0u);
}

TEST_F(BoxMorph, ThePatchesOfAnEmptyPatchAreRefused) {
  TempDir d2;
  BoxSpec s;
  s.empty_patch = true;
  csrbf::test::write_box_case(d2.path / "case", s);
  const FoamCase e = read_openfoam(d2.path / "case");
  EXPECT_NE(error_of([&] {
              prescribe(e.mesh, motion_from(dir, R"({"patches": {"nothing": "fixed"}})"));
            }).find("has no points"),
            std::string::npos);
}

// CGNS, written by the tests' own cgnslib writer and read back through cgnslib.
TEST(Cgns, ReadsZonesBoundaryConditionsAndFamilies) {
  TempDir dir;
  csrbf::test::write_cgns_box((dir / "box.cgns").string());
  const auto f = open_volume(dir / "box.cgns");
  const VolumeMesh& m = f->mesh();
  EXPECT_EQ(f->format(), "cgns");
  EXPECT_EQ(m.points.size(), 125u);
  EXPECT_EQ(m.cells.size(), 64u + 16u);
  ASSERT_NE(m.patch("bottom"), nullptr);
  ASSERT_NE(m.patch("top"), nullptr);
  ASSERT_NE(m.patch("lid"), nullptr);  // the family of "top"
  EXPECT_EQ(m.patch("bottom")->points.size(), 25u);
  EXPECT_EQ(m.patch("top")->points, m.patch("lid")->points);
  for (const auto p : m.patch("top")->points) EXPECT_EQ(m.points[p].z(), 1.0);
  const MeshQuality q = mesh_quality(m, m.points);
  ASSERT_TRUE(q.cells.has_value());
  EXPECT_EQ(q.cells->hexahedra, 64u);
  EXPECT_NEAR(q.cells->min_scaled_jacobian, 1.0, 1e-12);
  EXPECT_EQ(q.inverted_cells(), 0u);
}

TEST(Cgns, WritesTheCoordinatesInTheirOwnTypeAndNothingElse) {
  for (const bool single : {false, true}) {
    TempDir dir;
    csrbf::test::write_cgns_box((dir / "box.cgns").string(), 4, 0.25, single);
    const auto f = open_volume(dir / "box.cgns");
    EXPECT_EQ(f->encoding(), single ? "single" : "double");
    const Motion m =
        motion_from(dir, R"({"radius": 0.6, "patches": {"bottom": {"translate": [0, 0, 0.05]}, "lid": "fixed"}})");
    MorphOptions o;
    o.fit.radius = 0.6;
    const MorphResult r = morph(f->mesh(), m, o);
    f->write_copy(r.points, dir / "out.cgns");
    EXPECT_THROW(f->write_copy(r.points, dir / "out.cgns"), FileError);  // never replaced
    // Read back through cgnslib directly.
    int fn = 0;
    ASSERT_EQ(cg_open((dir / "out.cgns").c_str(), CG_MODE_READ, &fn), CG_OK);
    CGNS_ENUMT(DataType_t) type;
    char name[64];
    ASSERT_EQ(cg_coord_info(fn, 1, 1, 1, &type, name), CG_OK);
    EXPECT_EQ(type, single ? CGNS_ENUMV(RealSingle) : CGNS_ENUMV(RealDouble));
    std::vector<double> z(125);
    cgsize_t lo = 1, hi = 125;
    ASSERT_EQ(cg_coord_read(fn, 1, 1, "CoordinateZ", CGNS_ENUMV(RealDouble), &lo, &hi, z.data()), CG_OK);
    for (std::size_t i = 0; i < 125; ++i) EXPECT_EQ(z[i], single ? double(float(r.points[i].z())) : r.points[i].z());
    int nbocos = 0, nsections = 0;
    cg_nbocos(fn, 1, 1, &nbocos);
    cg_nsections(fn, 1, 1, &nsections);
    EXPECT_EQ(nbocos, 2);
    EXPECT_EQ(nsections, 2);
    cg_close(fn);
    const auto back = open_volume(dir / "out.cgns");
    EXPECT_EQ(back->mesh().patch("lid")->points, f->mesh().patch("lid")->points);
    for (const auto p : f->mesh().patch("bottom")->points) EXPECT_NEAR(back->mesh().points[p].z(), 0.05, 1e-7);
  }
}

TEST(Cgns, BrokenFilesAreErrorsNamingThem) {
  TempDir dir;
  csrbf::test::write_cgns_box((dir / "box.cgns").string());
  const std::string bytes = csrbf::test::read_text(dir / "box.cgns");
  csrbf::test::write_text(dir / "cut.cgns", bytes.substr(0, bytes.size() / 3));
  EXPECT_NE(error_of([&] { open_volume(dir / "cut.cgns"); }).find("cut.cgns"), std::string::npos);
  csrbf::test::write_text(dir / "text.cgns", "not a cgns file\n");
  EXPECT_NE(error_of([&] { open_volume(dir / "text.cgns"); }).find("text.cgns"), std::string::npos);
  EXPECT_NE(error_of([&] { open_volume(dir / "missing.cgns"); }).find("missing.cgns"), std::string::npos);
  EXPECT_NE(error_of([&] { open_volume(dir / "mesh.stl"); }).find("mesh.stl"), std::string::npos);
}

TEST(Cells, PrismsAndPyramidsAreMeasuredAndOrientedEitherWay) {
  // A unit prism and pyramid in VTK's corner order, then mirrored as another convention would
  // store them: both read as valid; pushing the apex through the base inverts the pyramid.
  std::vector<Vec3> p{{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 1},      {1, 0, 1},
                      {2, 0, 0}, {3, 0, 0}, {3, 1, 0}, {2, 1, 0}, {2.5, 0.5, 0.7}};
  for (const bool mirrored : {false, true}) {
    CellTopology t;
    const std::uint32_t wedge[] = {0, 1, 2, 3, 4, 5}, wedge_m[] = {0, 2, 1, 3, 5, 4};
    const std::uint32_t pyr[] = {6, 7, 8, 9, 10}, pyr_m[] = {6, 9, 8, 7, 10};
    t.add(13, mirrored ? wedge_m : wedge);
    t.add(14, mirrored ? pyr_m : pyr);
    orient_cells(t, p);
    const CellQuality q = cell_quality(t, p, p);
    EXPECT_EQ(q.prisms, 1u);
    EXPECT_EQ(q.pyramids, 1u);
    EXPECT_EQ(q.inverted_cells, 0u) << mirrored;
    EXPECT_GT(q.min_scaled_jacobian, 0.5);
    std::vector<Vec3> pushed = p;
    pushed[10].z() = -0.7;
    EXPECT_EQ(cell_quality(t, pushed, p).inverted_cells, 1u);
  }
}

// Gmsh: a two-tetrahedron mesh in msh 2.2, written here.
TEST(Gmsh, ReadsGroupsAndRefusesBrokenFiles) {
  TempDir dir;
  const std::string mesh =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 1 \"base\"\n3 2 \"solid\"\n$EndPhysicalNames\n"
      "$Nodes\n5\n10 0 0 0\n11 1 0 0\n12 0 1 0\n13 0 0 1\n14 0 0 -1\n$EndNodes\n"
      "$Elements\n3\n1 2 2 1 1 10 11 12\n2 4 2 2 2 10 11 12 13\n3 4 2 2 2 10 12 11 14\n$EndElements\n";
  csrbf::test::write_text(dir / "two.msh", mesh);
  const auto f = open_volume(dir / "two.msh");
  EXPECT_EQ(f->encoding(), "msh 2.2 ascii");
  const VolumeMesh& m = f->mesh();
  ASSERT_EQ(m.points.size(), 5u);
  EXPECT_EQ(m.point_ids, (std::vector<std::uint64_t>{10, 11, 12, 13, 14}));
  ASSERT_NE(m.patch("base"), nullptr);
  EXPECT_EQ(m.patch("base")->points, (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_EQ(m.patch("solid")->points.size(), 5u);
  const MeshQuality q = mesh_quality(m, m.points);
  EXPECT_EQ(q.cells->tetrahedra, 2u);
  EXPECT_EQ(q.inverted_cells(), 0u);
  // Moved and written: only the coordinates of $Nodes change.
  std::vector<Vec3> p = m.points;
  p[3] = Vec3(0.25, 0.125, 1.5);
  f->write_copy(p, dir / "out.msh");
  std::string want = mesh;
  want.replace(want.find("13 0 0 1"), 8, "13 0.25 0.125 1.5");
  EXPECT_EQ(csrbf::test::read_text(dir / "out.msh"), want);
  EXPECT_NE(error_of([&] { f->write_copy(p, dir / "out.vtu"); }), "");

  const auto broken = [&](const std::string& text) {
    csrbf::test::write_text(dir / "bad.msh", text);
    return error_of([&] { open_volume(dir / "bad.msh"); });
  };
  EXPECT_NE(broken("garbage\n").find("not a Gmsh mesh"), std::string::npos);
  EXPECT_NE(broken(mesh.substr(0, mesh.find("$Elements") + 12)).find("bad.msh"), std::string::npos);
  std::string lying = mesh;
  lying.replace(lying.find("$Nodes\n5"), 8, "$Nodes\n5000000");
  EXPECT_NE(broken(lying).find("a count that lies"), std::string::npos) << broken(lying);
  EXPECT_NE(broken("$MeshFormat\n3.0 0 8\n$EndMeshFormat\n").find("csrbf reads 2.2 and 4.1"), std::string::npos);
}

// Issue 30: legacy VTK files that crashed VTK's reader inside csrbf (a cell whose point count lies:
// "malloc(): invalid size", SIGSEGV), and cells VTK reads but drops or misreads. VTK now reads in a
// child process that checks every cell: each is an error naming the file, never a crash.
TEST(Hostile, VtkFilesThatCrashOrLoseCellsAreErrors) {
  TempDir dir;
  const auto grid = [](const std::string& cells, const std::string& types, int count = 2, int size = 10) {
    return "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n"
           "0 0 0 1 0 0 0 1 0 0 0 1 0 0 -1\nCELLS " +
           std::to_string(count) + " " + std::to_string(size) + "\n" + cells + "CELL_TYPES " + std::to_string(count) +
           "\n" + types + "POINT_DATA 5\nSCALARS s float 1\nLOOKUP_TABLE default\n1 2 3 4 5\n";
  };
  const std::vector<std::pair<std::string, std::string>> cases{
      // Found by fuzzing VTK's reader with the counts of a cell (each crashed it).
      {grid("4 0 1 2 3\n42 0 2 1 4\n", "10\n10\n"), ""},
      {grid("4 0 1 2 3\n99999999 0 2 1 4\n", "99999999\n10\n"), ""},
      // Read, but dropped or misread: a type VTK does not have, a tetrahedron of 3 points, a
      // polyhedron without its faces.
      {grid("4 0 1 2 3\n4 0 2 1 4\n", "10\n99\n"), "cell 1 has type 99, which is not a VTK cell type"},
      {grid("4 0 1 2 3\n3 0 2 1\n", "10\n10\n", 2, 9), "cell 1 of type 10 (vtkTetra) has 3 points; its type has 4"},
      {grid("4 0 1 2 3\n4 0 2 1 4\n", "10\n42\n"), "states 5 points and 2 cells, but VTK read 5 and 1"},
  };
  int k = 0;
  for (const auto& [text, message] : cases) {
    const fs::path f = dir / ("bad" + std::to_string(k++) + ".vtk");
    csrbf::test::write_text(f, text);
    const std::string e = error_of([&] { open_volume(f); });
    EXPECT_NE(e.find(f.string() + ": VTK"), std::string::npos) << f << ": " << e;
    if (!message.empty()) {
      EXPECT_NE(e.find(message), std::string::npos) << e;
    }
  }
  // A sound file still reads, with its point data, and is written back whole.
  csrbf::test::write_text(dir / "good.vtk", grid("4 0 1 2 3\n4 0 2 1 4\n", "10\n10\n"));
  const auto good = open_volume(dir / "good.vtk");
  EXPECT_EQ(good->mesh().points.size(), 5u);
  std::vector<Vec3> p = good->mesh().points;
  p[3].z() = 1.5;
  good->write_copy(p, dir / "out.vtk");
  const auto back = open_volume(dir / "out.vtk");
  EXPECT_EQ(back->mesh().points[3].z(), 1.5);
  EXPECT_NE(csrbf::test::read_text(dir / "out.vtk").find("SCALARS s float"), std::string::npos);
  // A write here starts VTK's TBB workers in this process; the next read forks a child that has
  // none of them. Its VTK used TBB's pool as copied and waited for ever (one full-suite run in
  // three hung here): the child's VTK runs sequentially. Ten writes and reads in turn.
  for (int i = 0; i < 10; ++i) {
    const fs::path out = dir / ("again" + std::to_string(i) + ".vtk");
    back->write_copy(p, out);
    EXPECT_EQ(open_volume(out)->mesh().points[3].z(), 1.5);
  }
}

// Issue 30: a .vtu whose NumberOfCells is below what its cell arrays hold lost the cells past it
// (VTK reads the stated count), with exit 0. Each layout of the types array is measured.
TEST(Hostile, AVtuThatStatesFewerCellsThanItHoldsIsAnError) {
  TempDir dir;
  const auto vtu = [](int cells, const std::string& types) {
    const bool zlib = types.find("eJz") != std::string::npos;
    return "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
           "header_type=\"UInt64\"" +
           std::string(zlib ? " compressor=\"vtkZLibDataCompressor\"" : "") +
           ">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"5\" NumberOfCells=\"" + std::to_string(cells) +
           "\">\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 "
           "0 1 0 0 -1</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" "
           "format=\"ascii\">0 1 2 3 0 2 1 4</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" "
           "format=\"ascii\">4 8</DataArray>\n" +
           types + "\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  };
  const std::string ascii = "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10 10</DataArray>";
  const std::string binary = "<DataArray type=\"UInt8\" Name=\"types\" format=\"binary\">AgAAAAAAAAA=Cgo=</DataArray>";
  // zlib: one block of 2 bytes, the header [1, 2, 2, 10] then the compressed bytes, each in base64.
  const std::string zlib =
      "<DataArray type=\"UInt8\" Name=\"types\" format=\"binary\">"
      "AQAAAAAAAAACAAAAAAAAAAIAAAAAAAAACgAAAAAAAAA=eJzj4gIAACAAFQ==</DataArray>";
  for (const auto& types : {ascii, binary, zlib}) {
    csrbf::test::write_text(dir / "good.vtu", vtu(2, types));
    const auto good = open_volume(dir / "good.vtu");
    EXPECT_EQ(good->mesh().cells.type.size(), 2u);
    csrbf::test::write_text(dir / "lies.vtu", vtu(1, types));
    const std::string e = error_of([&] { open_volume(dir / "lies.vtu"); });
    EXPECT_NE(e.find("lies.vtu: NumberOfCells says 1 cells, but its cell types array holds 2"), std::string::npos) << e;
  }
}

// Issue 30: a legacy .vtk whose data array is cut short was read with its missing values
// uninitialised (VTK warns to its output window and goes on), and written out as if read.
TEST(Hostile, ALegacyVtkDataArrayCutShortIsAnError) {
  TempDir dir;
  const std::string grid =
      "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n0 0 0 1 0 0 0 1 0 0 0 1 0 0 "
      "-1\nCELLS 2 10\n4 0 1 2 3\n4 0 2 1 4\nCELL_TYPES 2\n10\n10\n";
  const std::string whole = "POINT_DATA 5\nSCALARS s float 1\nLOOKUP_TABLE default\n1 2 3 4 5\n";
  csrbf::test::write_text(dir / "good.vtk", grid + whole);
  EXPECT_EQ(open_volume(dir / "good.vtk")->mesh().points.size(), 5u);
  for (const std::string& data : {std::string("POINT_DATA 5\nSCALARS s float 1\nLOOKUP_TABLE default\n1 2 3\n"),
                                  std::string("CELL_DATA 2\nSCALARS c int 1\nLOOKUP_TABLE default\n7\n"),
                                  std::string("POINT_DATA 5\nVECTORS v double\n1 2 3 4 5 6\n")}) {
    csrbf::test::write_text(dir / "short.vtk", grid + data);
    const std::string e = error_of([&] { open_volume(dir / "short.vtk"); });
    EXPECT_NE(e.find("short.vtk"), std::string::npos) << data << e;
    EXPECT_NE(e.find("Error reading ascii data"), std::string::npos) << data << e;
  }
}

// Found by an attacker's trial: each was a crash, a hang or a false success.
TEST(Hostile, LiesAndShortFilesAreErrorsNotCrashes) {
  TempDir dir;
  // Gmsh 2.2 whose node count is one short: Gmsh's library crashed on such files; it now reads in a
  // child process, so the crash is an error naming the file.
  const std::string mesh =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 1 \"base\"\n$EndPhysicalNames\n"
      "$Nodes\n4\n10 0 0 0\n11 1 0 0\n12 0 1 0\n13 0 0 1\n14 0 0 -1\n$EndNodes\n"
      "$Elements\n3\n1 2 2 1 1 10 11 12\n2 4 2 2 2 10 11 12 13\n3 4 2 2 2 10 12 11 14\n$EndElements\n";
  csrbf::test::write_text(dir / "short.msh", mesh);
  EXPECT_NE(error_of([&] { open_volume(dir / "short.msh"); }).find("short.msh"), std::string::npos);
  csrbf::test::write_text(dir / "cut.msh", mesh.substr(0, mesh.find("$EndElements")));
  EXPECT_NE(error_of([&] { open_volume(dir / "cut.msh"); }).find("no $EndElements"), std::string::npos);
  // VTK: a cell naming a point past the points.
  csrbf::test::write_text(
      dir / "bad.vtk",
      "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 "
      "1\nCELLS 1 5\n4 0 1 2 99999999\nCELL_TYPES 1\n10\n");
  EXPECT_NE(error_of([&] { open_volume(dir / "bad.vtk"); }).find("uses point 99999999, but there are 4 points"),
            std::string::npos)
      << error_of([&] { open_volume(dir / "bad.vtk"); });
  // A FIFO is not a mesh file (reading it would wait for ever).
  ASSERT_EQ(::mkfifo((dir / "pipe.msh").c_str(), 0600), 0);
  EXPECT_NE(error_of([&] { open_volume(dir / "pipe.msh"); }).find("not a regular file"), std::string::npos);
  // OpenFOAM: an owner label far past the faces would size every per-cell array.
  csrbf::test::write_box_case(dir.path / "case", {});
  const auto owner = dir.path / "case" / "constant" / "polyMesh" / "owner";
  std::string t = csrbf::test::read_text(owner);
  t.replace(t.find("\n(\n0\n") + 3, 1, "99999999");
  csrbf::test::write_text(owner, t);
  EXPECT_NE(error_of([&] { read_openfoam(dir.path / "case"); }).find("name cell 99999999"), std::string::npos)
      << error_of([&] { read_openfoam(dir.path / "case"); });
}

TEST_F(BoxMorph, AGreedyToleranceBelowTheSolvesAccuracyStillEnds) {
  const Motion m =
      motion_from(dir, R"({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "xmin": "free", "xmax": "free",
                                                    "ymin": "free", "ymax": "free"}})");
  MorphOptions o;
  o.fit.radius = 0.5;
  o.greedy = 1e-300;
  o.greedy_budget = std::numeric_limits<double>::infinity();  // it must end by itself
  const MorphResult r = morph(c.mesh, m, o);
  EXPECT_LE(r.report.controls, 98u);
  EXPECT_LT(r.report.max_boundary_error, 1e-10);
}

// Issue 31, point 2: patches the motion leaves unlisted slip where planar (they left their planes:
// the ground of windAroundBuildings), and entries name patches by regular expression.
TEST_F(BoxMorph, UnlistedPlanarPatchesSlipWithinTheirPlanes) {
  const std::string twist = R"("zmin": {"rotate": {"axis": [0, 0, 1], "degrees": 4, "origin": [0.5, 0.5, 0]}},
                               "zmax": "fixed")";
  const auto run = [&](const std::string& more) {
    const Motion m = motion_from(dir, "{\"patches\": {" + twist + more + "}}");
    MorphOptions o;
    o.fit.radius = 0.6;
    return morph(c.mesh, m, o);
  };
  const MorphResult slip = run("");
  const MorphResult free = run(R"j(, "[xy]m(in|ax)": "free")j");
  const double size = std::sqrt(3.0);
  // The sides' points off the twisted face: on their planes to 1e-12 of the size, yet moved along
  // them; left free, they leave their planes.
  double along = 0, off_free = 0;
  std::size_t checked = 0;
  for (const char* name : {"xmin", "xmax", "ymin", "ymax"}) {
    const Patch* patch = c.mesh.patch(name);
    ASSERT_NE(patch, nullptr);
    const int axis = name[0] == 'x' ? 0 : 1;
    const double plane = name[1 + 1] == 'i' ? 0.0 : 1.0;
    for (const auto p : patch->points) {
      if (c.mesh.points[p].z() == 0) continue;  // the twisted face's edge moves with it
      EXPECT_LE(std::abs(slip.points[p][axis] - plane), 1e-12 * size) << name << " point " << p;
      along = std::max(along, (slip.points[p] - c.mesh.points[p]).norm());
      off_free = std::max(off_free, std::abs(free.points[p][axis] - plane));
      ++checked;
    }
  }
  EXPECT_GT(checked, 100u);
  EXPECT_GT(along, 1e-3);
  EXPECT_GT(off_free, 1e-3);
  EXPECT_GT(slip.report.slip, 100u);
  // The report: every patch, its kind and why.
  std::map<std::string, std::pair<std::string, std::string>> kinds;
  for (const auto& p : slip.report.patches) kinds[p.name] = {p.kind, p.why};
  EXPECT_EQ(kinds["zmin"], std::make_pair(std::string("moving"), std::string("listed")));
  EXPECT_EQ(kinds["zmax"], std::make_pair(std::string("fixed"), std::string("listed")));
  EXPECT_EQ(kinds["xmin"], std::make_pair(std::string("slip"), std::string("planar")));
  for (const auto& p : free.report.patches)
    if (p.name != "zmin" && p.name != "zmax") {
      EXPECT_EQ(p.kind, "free") << p.name;
      EXPECT_EQ(p.why, "listed as '[xy]m(in|ax)'") << p.name;
    }
  // Exact locality holds with slip: points 2R from every moving one (here none: the box is small)
  // and a pattern that names nothing is an error that lists the patches.
  const std::string e = error_of([&] { run(R"(, "wall.*": "fixed")"); });
  EXPECT_NE(e.find("the mesh has no patch 'wall.*'; its patches: "), std::string::npos) << e;
}

// A QualityMeter's later measures recompute only the faces and cells of points that differ from
// the mesh's (now or at the last measure): each equals a whole measure of the same points (a
// fresh poly_quality) bit for bit, through a sequence that moves a corner, moves more, inverts a
// cell, moves back part of the way and returns to the mesh's own points.
TEST_F(BoxMorph, ALaterMeasureEqualsAWholeOne) {
  const auto same = [](const PolyQuality& a, const PolyQuality& b) {
    EXPECT_EQ(a.max_non_orthogonality, b.max_non_orthogonality);
    EXPECT_EQ(a.mean_non_orthogonality, b.mean_non_orthogonality);
    EXPECT_EQ(a.max_skewness, b.max_skewness);
    EXPECT_EQ(a.negative_volumes, b.negative_volumes);
    EXPECT_EQ(a.bad_pyramids, b.bad_pyramids);
    EXPECT_EQ(a.inverted_cells, b.inverted_cells);
    EXPECT_EQ(a.min_volume, b.min_volume);
    EXPECT_EQ(a.total_volume, b.total_volume);
    EXPECT_EQ(a.min_determinant, b.min_determinant);
    EXPECT_EQ(a.mean_determinant, b.mean_determinant);
  };
  const std::vector<Vec3>& own = c.mesh.points;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02);
  const auto moved = [&](double within, double scale) {  // points within a distance of the origin
    std::vector<Vec3> p = own;
    for (Vec3& x : p)
      if (x.norm() < within) x += scale * Vec3(jitter(rng), jitter(rng), jitter(rng));
    return p;
  };
  std::vector<Vec3> inverted = own;
  const std::size_t inner =
      std::size_t(std::min_element(own.begin(), own.end(),
                                   [](const Vec3& a, const Vec3& b) {
                                     return (a - Vec3(0.5, 0.5, 0.5)).norm() < (b - Vec3(0.5, 0.5, 0.5)).norm();
                                   }) -
                  own.begin());
  inverted[inner] += Vec3(0.4, 0.0, 0.0);  // through its neighbours' cells
  const std::vector<std::vector<Vec3>> sets{own, moved(0.3, 1.0), moved(0.8, 2.0), inverted, moved(0.2, 0.5), own};
  QualityMeter meter(c.mesh);
  for (std::size_t k = 0; k < sets.size(); ++k) {
    SCOPED_TRACE("point set " + std::to_string(k));
    const MeshQuality later = meter.measure(sets[k]);
    ASSERT_TRUE(later.poly);
    same(*later.poly, poly_quality(c.mesh.poly, sets[k]));
  }
  EXPECT_GT(meter.measure(inverted).inverted_cells(), 0u);
}

// Issue 31, point 7: the smallest cell volume ratio, after / before. Under an affine map x -> Ax
// every cell's volume is multiplied by det A: the closed form, for OpenFOAM's polyhedra (against
// the meter's first measure) and for every standard cell type (against the reference points).
TEST_F(BoxMorph, TheVolumeRatioIsTheDeterminantOfAnAffineMap) {
  Eigen::Matrix3d a;
  a << 1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 0.8;
  const double det = a.determinant();
  const auto mapped = [&](const std::vector<Vec3>& p, const Eigen::Matrix3d& m) {
    std::vector<Vec3> out(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) out[i] = m * p[i] + Vec3(0.3, -2, 5);
    return out;
  };
  QualityMeter meter(c.mesh);
  EXPECT_EQ(meter.measure(c.mesh.points).poly->min_volume_ratio, 1.0);
  EXPECT_NEAR(meter.measure(mapped(c.mesh.points, a)).poly->min_volume_ratio, det, 1e-12);
  // Squeezing the box's bottom layer to a fifth of its height: 0.2.
  std::vector<Vec3> squeezed = c.mesh.points;
  for (Vec3& p : squeezed) p.z() = p.z() < 1.0 / 6 + 1e-9 ? p.z() / 5 : p.z() - (1.0 / 6) * 4 / 5;
  EXPECT_NEAR(meter.measure(squeezed).poly->min_volume_ratio, 0.2, 1e-12);
  // A tetrahedron, a hexahedron, a prism, a pyramid; then a triangle and a quadrilateral alone.
  std::vector<Vec3> p{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1},  // tet
                      {2, 0, 0}, {3, 0, 0}, {3, 1, 0}, {2, 1, 0}, {2, 0, 1},      {3, 0, 1},
                      {3, 1, 1}, {2, 1, 1},                                                   // hex
                      {4, 0, 0}, {5, 0, 0}, {4, 1, 0}, {4, 0, 1}, {5, 0, 1},      {4, 1, 1},  // prism
                      {6, 0, 0}, {7, 0, 0}, {7, 1, 0}, {6, 1, 0}, {6.5, 0.5, 0.8}};           // pyramid
  CellTopology solid;
  const std::uint32_t tet[] = {0, 1, 2, 3}, hex[] = {4, 5, 6, 7, 8, 9, 10, 11}, prism[] = {12, 13, 14, 15, 16, 17},
                      pyramid[] = {18, 19, 20, 21, 22};
  solid.add(10, tet);
  solid.add(12, hex);
  solid.add(13, prism);
  solid.add(14, pyramid);
  EXPECT_EQ(cell_quality(solid, p, p).min_volume_ratio, 1.0);
  EXPECT_NEAR(cell_quality(solid, mapped(p, a), p).min_volume_ratio, det, 1e-12);
  // One cell crushed to a third: the smallest ratio is its.
  std::vector<Vec3> crushed = p;
  for (int k : {8, 9, 10, 11}) crushed[std::size_t(k)].z() = 1.0 / 3;
  EXPECT_NEAR(cell_quality(solid, crushed, p).min_volume_ratio, 1.0 / 3, 1e-12);
  // In-plane cells (a 2-D mesh): a map that keeps the plane z = 0 scales areas by its 2x2 block.
  CellTopology flat;
  const std::uint32_t tri[] = {0, 1, 2}, quad[] = {4, 5, 6, 7};
  flat.add(5, tri);
  flat.add(9, quad);
  Eigen::Matrix3d b = Eigen::Matrix3d::Identity();
  b.topLeftCorner<2, 2>() << 1.3, 0.4, -0.2, 0.7;
  EXPECT_NEAR(cell_quality(flat, mapped(p, b), p).min_volume_ratio, b.determinant(), 1e-12);
}

// Issue 31, point 3: --radius auto.
TEST_F(BoxMorph, AutoRadiusFollowsTheDisplacementTheSpacingAndTheMemoryLimit) {
  const auto run = [&](double dz, double limit_bytes) {
    const Motion m = motion_from(dir, R"({"patches": {"zmin": {"translate": [0, 0, )" + std::to_string(dz) +
                                          R"j(]}, "zmax": "fixed", "[xy]m(in|ax)": "fixed"}})j");
    MorphOptions o;
    o.radius_auto = true;
    o.fit.memory_limit_bytes = limit_bytes;
    return morph(c.mesh, m, o);
  };
  // 20 x the largest displacement, where that is above 4 x the boundary's spacing (1/6).
  const MorphResult big = run(0.05, 4e9);
  EXPECT_NEAR(big.report.radius, 1.0, 1e-12);
  EXPECT_NE(big.report.radius_why.find("20 x the largest displacement 0.05"), std::string::npos)
      << big.report.radius_why;
  EXPECT_EQ(big.report.reach, 2 * big.report.radius);
  // A small motion: 4 x the spacing.
  const MorphResult small = run(0.002, 4e9);
  EXPECT_NEAR(small.report.radius, 4.0 / 6, 1e-12);
  EXPECT_NE(small.report.radius_why.find("4 x the boundary's spacing 0.1667"), std::string::npos)
      << small.report.radius_why;
  // The prediction: neighbours per control as the fit found them (every source counted, at most
  // 256 of them, or a sample), and per point against brute force over every point.
  for (const MorphResult* r : {&big, &small}) {
    const double R = r->report.radius;
    EXPECT_NEAR(r->report.predicted.neighbours_per_control, r->report.fit.mean_neighbors,
                0.05 * r->report.fit.mean_neighbors);
    std::vector<Vec3> moving, fitted;
    for (const auto p : c.mesh.patch("zmin")->points) moving.push_back(c.mesh.points[p]);
    fitted = moving;
    for (const Patch& patch : c.mesh.patches)
      for (const auto p : patch.points) {
        const Vec3& x = c.mesh.points[p];
        if (x.z() == 0) continue;
        bool near = false;
        for (const Vec3& m : moving) near |= (m - x).norm() < R;
        if (near && std::find(fitted.begin(), fitted.end(), x) == fitted.end()) fitted.push_back(x);
      }
    EXPECT_EQ(fitted.size(), r->report.controls);
    double terms = 0;
    for (const Vec3& x : c.mesh.points)
      for (const Vec3& s : fitted) terms += (s - x).norm() < R;
    EXPECT_NEAR(r->report.predicted.neighbours_per_point, terms / double(c.mesh.points.size()), 1e-12);
    EXPECT_GT(r->report.predicted.bytes, 0);
    EXPECT_GT(r->report.predicted.seconds_fit, 0);
  }
  // A memory limit that the displacement's R would pass: R shrinks until the prediction fits half
  // of it, and the report says so.
  const double at_one = big.report.predicted.bytes;
  const MorphResult capped = run(0.05, at_one);
  EXPECT_LT(capped.report.radius, 1.0);
  EXPECT_GT(capped.report.radius, 0.3);
  EXPECT_NE(capped.report.radius_why.find("above what --memory-limit leaves it"), std::string::npos)
      << capped.report.radius_why;
  EXPECT_LE(capped.report.predicted.bytes, 0.5 * at_one);
  // Nothing moves: no radius is needed, and none is chosen.
  const MorphResult still = run(0.0, 4e9);
  EXPECT_EQ(still.report.radius, 0.0);
  EXPECT_EQ(still.report.radius_why, "nothing moves");
  EXPECT_EQ(still.points, c.mesh.points);
}

// Issue 31, point 4: greedy never loses. Past its budget it stops and fits every control: the
// result is then the plain morph's, bit for bit, and the report says why.
TEST_F(BoxMorph, GreedyPastItsBudgetFitsEveryControl) {
  const Motion m =
      motion_from(dir, R"j({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "[xy]m(in|ax)": "fixed"}})j");
  MorphOptions plain;
  plain.fit.radius = 0.8;
  const MorphResult all = morph(c.mesh, m, plain);
  MorphOptions o = plain;
  o.greedy = 1e-3;
  o.greedy_budget = 0;  // no time at all: one round, then every control
  o.greedy_budget_floor = 0;
  const MorphResult stopped = morph(c.mesh, m, o);
  EXPECT_EQ(stopped.report.greedy_rounds, 1u);
  EXPECT_EQ(stopped.report.controls, all.report.controls);
  EXPECT_EQ(stopped.points, all.points);
  EXPECT_NE(stopped.report.greedy_stopped.find("every control is fitted instead"), std::string::npos)
      << stopped.report.greedy_stopped;
  EXPECT_NE(stopped.report.greedy_stopped.find("after 1 round ("), std::string::npos) << stopped.report.greedy_stopped;
  // Unbounded, it runs to its tolerance with fewer controls.
  o.greedy_budget = std::numeric_limits<double>::infinity();
  const MorphResult ran = morph(c.mesh, m, o);
  EXPECT_TRUE(ran.report.greedy_stopped.empty());
  EXPECT_LT(ran.report.controls, all.report.controls);
  EXPECT_LE(ran.report.max_boundary_error, 1e-3 * ran.report.max_displacement);

  // With slip sides a second fit corrects the slip points: once greedy stopped in the first fit,
  // the correction takes every control too, so the result is still the plain morph's.
  const Motion slip =
      motion_from(dir, R"j({"patches": {"zmin": {"rotate": {"axis": [1, 0, 0], "degrees": 3, "origin": [0.5, 0.5, 0]}},
                                                    "zmax": "fixed", "[xy]m(in|ax)": "slip"}})j");
  const MorphResult slip_all = morph(c.mesh, slip, plain);
  ASSERT_GT(slip_all.report.controls, all.report.controls);  // the two fits' controls: a correction ran
  o.greedy_budget = 0;
  const MorphResult slip_stopped = morph(c.mesh, slip, o);
  EXPECT_EQ(slip_stopped.report.greedy_rounds, 1u);
  EXPECT_EQ(slip_stopped.report.controls, slip_all.report.controls);
  EXPECT_EQ(slip_stopped.points, slip_all.points);
  EXPECT_NE(slip_stopped.report.greedy_stopped.find("(and in a slip correction's fit, if one follows)"),
            std::string::npos)
      << slip_stopped.report.greedy_stopped;
}
