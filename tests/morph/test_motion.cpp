// The motion file of csrbf morph (csrbf/morph/motion.hpp): every kind of patch motion, and bad
// values refused by their JSON path.
#include "morph_test_helpers.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/morph/motion.hpp"

#include <gtest/gtest.h>

#include <string>

using csrbf::Vec3;
using namespace csrbf::morph;
using csrbf::test::error_of;
using csrbf::test::motion_from;
using csrbf::test::TempDir;

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
