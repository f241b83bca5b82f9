#include "csrbf/io/controls.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <sstream>

using namespace csrbf;
using csrbf::io::FileError;

namespace {
io::Controls parse(const std::string& text) {
  std::istringstream in(text);
  return io::parse_controls(in, "c.txt");
}
std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const FileError& e) {
    return e.what();
  }
  return "no error";
}
}  // namespace

TEST(Controls, ParsesCommentsAndBlankLines) {
  const auto c = parse("# header\n\n0 0 0  1 0 0\n  1 2 3 4 5 6   # trailing comment\n\t\n-1e-3 +2 3.5e2 0 0 0\n");
  ASSERT_EQ(c.sources.size(), 3u);
  EXPECT_EQ(c.sources[1], Vec3(1, 2, 3));
  EXPECT_EQ(c.destinations[1], Vec3(4, 5, 6));
  EXPECT_EQ(c.sources[2], Vec3(-1e-3, 2, 350));
  EXPECT_EQ(c.lines, (std::vector<int>{3, 4, 6}));
  EXPECT_TRUE(c.warnings.empty());
}

TEST(Controls, MalformedLinesNameFileLineAndText) {
  std::string e = error_of("0 0 0 1 1 1\n0 0 1 2 2\n");
  EXPECT_NE(e.find("c.txt:2:"), std::string::npos) << e;
  EXPECT_NE(e.find("0 0 1 2 2"), std::string::npos) << e;
  e = error_of("0 0 0 1 1 x1\n");
  EXPECT_NE(e.find("c.txt:1:"), std::string::npos) << e;
  EXPECT_NE(e.find("'x1'"), std::string::npos) << e;
  e = error_of("0 0 0 1 1 1 7\n");
  EXPECT_NE(e.find("7 fields"), std::string::npos) << e;
}

TEST(Controls, NonFiniteNumbersAreErrors) {
  for (const char* bad : {"nan", "inf", "-inf", "NaN", "1e999"}) {
    const std::string e = error_of(std::string("0 0 0\t1 ") + bad + " 1\n");
    EXPECT_NE(e.find("c.txt:1:"), std::string::npos) << e;
    EXPECT_NE(e.find(bad), std::string::npos) << e;
  }
}

TEST(Controls, EmptyFileIsAnError) {
  EXPECT_NE(error_of("").find("no control vectors"), std::string::npos);
  EXPECT_NE(error_of("# only comments\n\n").find("c.txt"), std::string::npos);
}

TEST(Controls, ExactDuplicatesAreMergedWithAWarning) {
  const auto c = parse("0 0 0 1 1 1\n2 2 2 2 2 2\n0 0 0 1 1 1\n-0 0 0 1 1 1\n");
  EXPECT_EQ(c.sources.size(), 2u);
  ASSERT_EQ(c.warnings.size(), 2u);
  EXPECT_NE(c.warnings[0].find("c.txt:3:"), std::string::npos) << c.warnings[0];
  EXPECT_NE(c.warnings[0].find("line 1"), std::string::npos) << c.warnings[0];
}

TEST(Controls, ConflictingDuplicatesNameBothLines) {
  const std::string e = error_of("# x\n0 0 0 1 1 1\n5 5 5 5 5 5\n0 0 0 1 1 2\n");
  EXPECT_NE(e.find("c.txt:4:"), std::string::npos) << e;
  EXPECT_NE(e.find("line 2"), std::string::npos) << e;
}

TEST(Controls, ReadAndWriteFiles) {
  test::TempDir dir;
  EXPECT_THROW(io::read_controls(dir / "missing.txt"), FileError);
  EXPECT_THROW(io::read_controls(dir.path), FileError);
  const std::vector<Vec3> s{Vec3(0.1, 0.2, 1.0 / 3.0)}, d{Vec3(1e-17, -2, 3)};
  io::write_controls(dir / "c.txt", s, d);
  const auto c = io::read_controls(dir / "c.txt");
  EXPECT_EQ(c.sources[0], s[0]);  // shortest round-trip formatting keeps every bit
  EXPECT_EQ(c.destinations[0], d[0]);
}
