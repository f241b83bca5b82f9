// Helpers shared by the csrbf::morph tests (tests/morph/test_*.cpp, one executable: test_morph).
#pragma once

#include "box_case.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/motion.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <string>

namespace csrbf::test {

/// The message of the FileError f throws ("" if it throws none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const csrbf::io::FileError& e) {
    return e.what();
  }
  return "";
}

/// The motion of `json`, written to motion.json in dir and read back.
inline csrbf::morph::Motion motion_from(const TempDir& dir, const std::string& json) {
  write_text(dir / "motion.json", json);
  return csrbf::morph::read_motion(dir / "motion.json");
}

/// The bits of v: compares coordinates bit for bit (-0 and 0 differ).
inline std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

}  // namespace csrbf::test

/// A 6^3 box case of side 1 in a fresh folder, read back as c.
class BoxMorph : public ::testing::Test {
 protected:
  void SetUp() override {
    csrbf::test::BoxSpec s;
    s.nx = s.ny = s.nz = 6;
    s.h = 1.0 / 6;
    csrbf::test::write_box_case(dir.path / "case", s);
    c = csrbf::morph::read_openfoam(dir.path / "case");
  }
  csrbf::test::TempDir dir;
  csrbf::morph::FoamCase c;
};
