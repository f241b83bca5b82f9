// The deformation file (csrbf/io/deformation.hpp): one CSRBF space mapping as JSON, written and read
// back exactly, its active area, and bad files refused by their JSON path.
#include "csrbf/io/deformation.hpp"
#include "test_helpers.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

using csrbf::Vec3;
using csrbf::io::FileError;
using csrbf::test::TempDir;
using csrbf::test::write_text;

TEST(DeformationFile, WritesAndReadsBackExactly) {
  TempDir dir;
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 0.1 + 0.2;  // not representable in short decimal: shortest round-trip text
  spec.options.kernel = csrbf::Kernel::C4;
  spec.options.polynomial = csrbf::Polynomial::Linear;
  spec.sources = {Vec3(0, 0, 0), Vec3(1.0 / 3, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  spec.destinations = {Vec3(0, 0, 0.1), Vec3(1.0 / 3, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1e-17)};
  csrbf::io::write_deformation(dir / "d.json", spec);
  const auto back = csrbf::io::read_deformation(dir / "d.json");
  EXPECT_EQ(back.options.radius, spec.options.radius);
  EXPECT_EQ(back.options.kernel, spec.options.kernel);
  EXPECT_EQ(back.options.polynomial, spec.options.polynomial);
  EXPECT_EQ(back.sources, spec.sources);
  EXPECT_EQ(back.destinations, spec.destinations);
  // Bad files name the path; a failed write leaves the old file.
  write_text(dir / "bad.json", R"({"radius": 0.3, "sources": [[0,0,0]], "destinations": [[0,0,0],[1,1,1]]})");
  try {
    csrbf::io::read_deformation(dir / "bad.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json: destinations: has 2 points but sources has 1"), std::string::npos)
        << e.what();
  }
  write_text(dir / "bad.json", R"({"radius": 0.3, "controls": "x.controls", "sources": [[0,0,0]]})");
  EXPECT_THROW(csrbf::io::read_deformation(dir / "bad.json"), FileError);
  const std::string before = csrbf::test::read_text(dir / "d.json");
  spec.destinations.pop_back();
  EXPECT_THROW(csrbf::io::write_deformation(dir / "d.json", spec), FileError);
  EXPECT_EQ(csrbf::test::read_text(dir / "d.json"), before);
}

TEST(DeformationFile, ActiveAreaRoundTripsAndLimitsTheVerticesMoved) {
  TempDir dir;
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 2.0;
  spec.sources = {Vec3(0.5, 0.5, 0)};
  spec.destinations = {Vec3(0.5, 0.5, 0.2)};
  spec.area = csrbf::io::ActiveArea{6, {1, 2}, std::nullopt};
  csrbf::io::write_deformation(dir / "d.json", spec);
  const auto back = csrbf::io::read_deformation(dir / "d.json");
  ASSERT_TRUE(back.area.has_value());
  EXPECT_EQ(*back.area, *spec.area);
  // Applied to 6 points: only 1 and 2 move, by the map; the others stay bit for bit.
  std::vector<Vec3> pts = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0), Vec3(2, 0, 0), Vec3(2, 1, 0)};
  const auto rest = pts;
  const auto map = back.fit();
  csrbf::io::check_active_area(*back.area, pts, "d.json", "the points");
  csrbf::io::apply_deformation(map, back.area, pts, 0.5);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i == 1 || i == 2) {
      std::vector<Vec3> one = {rest[i]};
      map.apply(one, one, 0.5);
      EXPECT_EQ(pts[i], one[0]) << i;
      EXPECT_NE(pts[i], rest[i]) << i;
    } else {
      EXPECT_EQ(pts[i], rest[i]) << i;
    }
  }
  // A mesh of another vertex count is refused, naming both counts.
  std::vector<Vec3> five(rest.begin(), rest.begin() + 5);
  try {
    csrbf::io::check_active_area(*back.area, five, "d.json", "five.obj");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "d.json: active_area: the deformation was picked on a mesh of 6 vertices, five.obj has 5"),
              std::string::npos)
        << e.what();
  }
  // The same count in another vertex order (an STL round trip, a re-export) is refused by the bounds.
  const auto bounded = csrbf::io::ActiveArea::of(rest, {1, 2});
  ASSERT_TRUE(bounded.bounds.has_value());
  EXPECT_EQ((*bounded.bounds)[0], Vec3(1, 0, 0));
  EXPECT_EQ((*bounded.bounds)[1], Vec3(1, 1, 0));
  auto reordered = rest;
  std::swap(reordered[1], reordered[4]);
  EXPECT_NO_THROW(csrbf::io::check_active_area(bounded, rest, "d.json", "quad.obj"));
  try {
    csrbf::io::check_active_area(bounded, reordered, "d.json", "quad.stl");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(
        std::string(e.what()).find("d.json: active_area: its vertices of quad.stl are not where they were picked"),
        std::string::npos)
        << e.what();
  }
  spec.area = bounded;
  csrbf::io::write_deformation(dir / "b.json", spec);
  EXPECT_EQ(csrbf::io::read_deformation(dir / "b.json").area, bounded);
  // Rounding through a float format (glTF, 6e-8 relative) is not a reorder.
  auto rounded = rest;
  for (auto& p : rounded) p = p.cast<float>().cast<double>() + Vec3::Constant(1e-8);
  EXPECT_NO_THROW(csrbf::io::check_active_area(bounded, rounded, "d.json", "quad.glb"));
  // Bad areas name the JSON path and the value.
  const std::string head = R"({"radius": 1, "sources": [[0,0,0]], "destinations": [[0,0,1]], "active_area": )";
  const std::pair<std::string, std::string> bad[] = {
      {R"({"vertex_count": 4, "vertices": [1, 1]})",
       "active_area.vertices[1]: vertices must be sorted and unique (1 follows 1)"},
      {R"({"vertex_count": 4, "vertices": [4]})", "active_area.vertices[0]: vertex 4 is not below vertex_count 4"},
      {R"({"vertex_count": 0, "vertices": [0]})", "active_area.vertex_count: expected a vertex count from 1"},
      {R"({"vertex_count": 4, "vertices": []})", "active_area.vertices: an active area needs at least one vertex"},
      {R"({"vertex_count": 4, "vertices": [-1]})", "active_area.vertices[0]: expected an integer >= 0"},
      {R"({"vertex_count": 4, "vertices": [0], "extra": 1})",
       "active_area.extra: unknown key 'extra' (allowed here: vertex_count, vertices, bounds)"},
      {R"({"vertex_count": 4, "vertices": [0], "bounds": [[1, 0, 0], [0, 0, 0]]})",
       "active_area.bounds: the first corner must not exceed the second"},
      {R"({"vertex_count": 4, "vertices": [0], "bounds": [[0, 0, 0]]})",
       "active_area.bounds: expected [[xmin, ymin, zmin], [xmax, ymax, zmax]]"},
  };
  for (const auto& [area, message] : bad) {
    write_text(dir / "bad.json", head + area + "}");
    try {
      csrbf::io::read_deformation(dir / "bad.json");
      ADD_FAILURE() << area;
    } catch (const FileError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

TEST(DeformationFile, NumbersTooLargeForADoubleAreAnError) {
  // Found by fuzz_deformation: nlohmann reports this as out_of_range, not as a parse error.
  TempDir dir;
  write_text(dir / "big.json", R"({"radius": 1111E1111, "sources": [[0,0,0]], "destinations": [[0,0,0]]})");
  try {
    csrbf::io::read_deformation(dir / "big.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("number overflow"), std::string::npos) << e.what();
  }
  EXPECT_THROW(csrbf::io::read_deformation_text("[1E400]", "t.json", dir.path), FileError);
}

TEST(DeformationFile, NestingAndMessagesAreBounded) {
  TempDir dir;
  // 70 000 levels: refused while parsing (the error path once recursed and overflowed the stack).
  write_text(dir / "deep.json",
             "{\"radius\": 1, \"sources\": " + std::string(70000, '[') + std::string(70000, ']') + "}");
  try {
    csrbf::io::read_deformation(dir / "deep.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("deep.json: JSON nested deeper than 64 levels"), std::string::npos)
        << e.what();
  }
  // 64 levels are fine for the parser (the value is then the wrong type, named by its path).
  write_text(dir / "d64.json", "{\"radius\": " + std::string(63, '[') + std::string(63, ']') + "}");
  try {
    csrbf::io::read_deformation(dir / "d64.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("radius: expected a number, got an array of 1 elements"), std::string::npos)
        << e.what();
  }
  // A long string of multi-byte characters is cut inside a character: still a clean message
  // (fuzz_deformation found it throwing nlohmann's type_error from the message).
  std::string accents;
  for (int i = 0; i < 40; ++i) accents += "\xC3\xA9";
  write_text(dir / "utf8.json", "{\"radius\": \"" + accents + "\"}");
  try {
    csrbf::io::read_deformation(dir / "utf8.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("radius: expected a number, got \"\xC3\xA9"), std::string::npos) << e.what();
    EXPECT_LT(std::string(e.what()).size(), 200u);
  }
}
