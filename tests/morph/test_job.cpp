// A whole morph as `csrbf morph` runs it (csrbf/morph/job.hpp): a job's contradictions are usage
// errors named before anything is read, its options take precedence over the motion file's, and
// run_job reads, morphs, measures and writes the box case unless the morph inverts cells.
#include "morph_test_helpers.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/morph/openfoam.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <type_traits>

using csrbf::Vec3;
using namespace csrbf::morph;
using csrbf::test::error_of;
using csrbf::test::motion_from;
using csrbf::test::TempDir;

namespace {

/// The message of the JobError f throws ("" if it throws none).
template <class F>
std::string usage_error_of(F&& f) {
  try {
    f();
  } catch (const JobError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MorphJob, ContradictionsAreUsageErrors) {
  static_assert(std::is_base_of_v<csrbf::UsageError, JobError>);  // exit status 2
  const auto check = [](auto change) {
    MorphJob job;
    job.in_place = true;
    change(job);
    return usage_error_of([&] { check_job(job); });
  };
  EXPECT_EQ(check([](MorphJob&) {}), "");
  EXPECT_EQ(check([](MorphJob& j) { j.in_place = false; }), "give an output (a new case folder or file) or in place");
  EXPECT_EQ(check([](MorphJob& j) { j.out = "out"; }), "give an output or in place, not both");
  EXPECT_EQ(check([](MorphJob& j) { j.in_place = false, j.write = false; }), "");  // measure only
  EXPECT_EQ(check([](MorphJob& j) { j.radius = 0.0; }), "the radius must be a finite number > 0, got 0");
  EXPECT_EQ(check([](MorphJob& j) { j.radius = std::numeric_limits<double>::infinity(); }),
            "the radius must be a finite number > 0, got inf");
  EXPECT_EQ(check([](MorphJob& j) { j.phase = 1.5; }), "the phase must be in [0, 1], got 1.5");
  EXPECT_EQ(check([](MorphJob& j) { j.greedy = 0.0; }), "the greedy tolerance must be in (0, 1], got 0");
  EXPECT_EQ(check([](MorphJob& j) { j.greedy_budget = -1; }), "the greedy budget must be in [0, 1e6], got -1");
  EXPECT_EQ(check([](MorphJob& j) { j.levels = 3; }), "levels must be auto (0), 1 or 2, got 3");
  EXPECT_EQ(check([](MorphJob& j) { j.levels = 2, j.greedy = 0.1; }),
            "two levels and greedy exclude each other (greedy chooses its own controls): give one");
  EXPECT_EQ(check([](MorphJob& j) { j.memory_limit_bytes = 0; }), "the memory limit must be > 0");
}

TEST(MorphJob, OutputsAreNewFilesInTheInputsFormat) {
  TempDir dir;
  csrbf::test::write_text(dir / "exists.vtu", "");
  MorphJob job;
  job.mesh = dir / "mesh.vtu";
  job.out = dir / "exists.vtu";
  EXPECT_EQ(error_of([&] { check_job(job); }),
            "cannot write '" + job.out.string() +
                "': it exists (csrbf morph writes a new case folder or file; --in-place rewrites the input)");
  job.out = dir / "missing" / "out.vtu";
  EXPECT_EQ(error_of([&] { check_job(job); }),
            "cannot write '" + job.out.string() + "': folder '" + (dir / "missing").string() + "' does not exist");
  job.out = dir / "out.msh";
  EXPECT_EQ(
      usage_error_of([&] { check_job(job); }),
      "output " + job.out.string() + ": the output is written in the input's format, so it needs the extension '.vtu'");
  job.out = dir / "OUT.VTU";  // the extension in any case
  EXPECT_NO_THROW(check_job(job));
}

TEST(MorphJob, TheJobsOptionsOverTheMotionsOverTheDefaults) {
  TempDir dir;
  const Motion given = motion_from(dir, R"({"radius": 0.3, "kernel": "c4", "polynomial": "linear",
                                            "patches": {"zmin": "fixed"}})");
  const Motion bare = motion_from(dir, R"({"patches": {"zmin": "fixed"}})");
  MorphJob job;
  MorphOptions o = morph_options(job, given);
  EXPECT_EQ(o.fit.radius, 0.3);
  EXPECT_FALSE(o.radius_auto);
  EXPECT_EQ(o.fit.kernel, csrbf::Kernel::C4);
  EXPECT_EQ(o.fit.polynomial, csrbf::Polynomial::Linear);
  o = morph_options(job, bare);
  EXPECT_TRUE(o.radius_auto);  // no radius anywhere
  EXPECT_EQ(o.fit.kernel, csrbf::Kernel::C2);
  EXPECT_EQ(o.fit.polynomial, csrbf::Polynomial::None);
  job.radius = 0.7;
  job.kernel = csrbf::Kernel::C0;
  job.polynomial = csrbf::Polynomial::Constant;
  job.phase = 0.25;
  job.greedy = 0.01;
  job.memory_limit_bytes = 1e9;
  o = morph_options(job, given);
  EXPECT_EQ(o.fit.radius, 0.7);
  EXPECT_EQ(o.fit.kernel, csrbf::Kernel::C0);
  EXPECT_EQ(o.fit.polynomial, csrbf::Polynomial::Constant);
  EXPECT_EQ(o.phase, 0.25);
  EXPECT_EQ(o.greedy, 0.01);
  EXPECT_EQ(o.fit.memory_limit_bytes, 1e9);
  job.radius.reset();
  job.radius_auto = true;  // `--radius auto` over the motion's 0.3
  EXPECT_TRUE(morph_options(job, given).radius_auto);
  // Two levels need polynomial none; the message says where the polynomial came from.
  MorphJob two;
  two.levels = 2;
  EXPECT_EQ(usage_error_of([&] { morph_options(two, given); }),
            "two levels need polynomial none (a polynomial moves the whole space; its fit is one level), got linear "
            "(\"polynomial\" in " +
                given.file + ")");
  two.polynomial = csrbf::Polynomial::Constant;
  EXPECT_EQ(usage_error_of([&] { morph_options(two, given); }),
            "two levels need polynomial none (a polynomial moves the whole space; its fit is one level), got "
            "constant (--polynomial)");
}

TEST_F(BoxMorph, RunJobMeasuresAndWritesTheMovedCase) {
  motion_from(dir, R"({"radius": 0.5, "patches": {"zmax": {"translate": [0, 0, 0.05]}, "zmin": "fixed"}})");
  MorphJob job;
  job.mesh = dir / "case";
  job.motion = dir / "motion.json";
  job.write = false;
  const MorphOutcome measured = run_job(job);
  EXPECT_FALSE(measured.written);
  EXPECT_EQ(measured.output, "");
  EXPECT_EQ(measured.format, "openfoam");
  EXPECT_EQ(measured.points, 343u);
  EXPECT_EQ(measured.cells, 216u);
  EXPECT_EQ(measured.patches, 6u);
  EXPECT_FALSE(measured.inverts);
  EXPECT_EQ(measured.options.fit.radius, 0.5);
  EXPECT_EQ(measured.result.points.size(), 343u);
  const std::string json = outcome_json(measured);
  EXPECT_NE(json.find("\"written\": false"), std::string::npos) << json;
  EXPECT_NE(json.find("\"points\": 343"), std::string::npos) << json;
  EXPECT_NE(json.find("\"radius\": 0.5"), std::string::npos) << json;

  job.write = true;
  job.out = dir / "moved";
  const MorphOutcome written = run_job(job);
  EXPECT_TRUE(written.written);
  EXPECT_EQ(written.output, job.out.string());
  const FoamCase back = read_openfoam(job.out);
  ASSERT_EQ(back.mesh.points.size(), written.result.points.size());
  for (std::size_t i = 0; i < back.mesh.points.size(); ++i) ASSERT_EQ(back.mesh.points[i], written.result.points[i]);
  // zmax (z = 1) moved up by 0.05, zmin (z = 0) stayed.
  for (std::size_t i = 0; i < c.mesh.points.size(); ++i) {
    if (c.mesh.points[i].z() == 1.0) {
      EXPECT_NEAR(back.mesh.points[i].z(), 1.05, 1e-12);
    } else if (c.mesh.points[i].z() == 0.0) {
      EXPECT_EQ(back.mesh.points[i], c.mesh.points[i]);
    }
  }
}

TEST_F(BoxMorph, ACaseThatWouldInvertIsNotWrittenUnlessForced) {
  // zmin pushed up through its first layer of cells.
  motion_from(dir, R"({"radius": 0.3, "patches": {"zmin": {"translate": [0, 0, 0.4]}, "zmax": "fixed"}})");
  MorphJob job;
  job.mesh = dir / "case";
  job.motion = dir / "motion.json";
  job.out = dir / "moved";
  const MorphOutcome o = run_job(job);
  EXPECT_TRUE(o.inverts);
  EXPECT_FALSE(o.written);
  EXPECT_FALSE(std::filesystem::exists(job.out));
  EXPECT_GT(o.safe_phase, 0.1);
  EXPECT_LT(o.safe_phase, 1.0);
  EXPECT_GT(o.after.inverted_cells(), o.before.inverted_cells());
  EXPECT_NE(outcome_json(o).find("\"safe_phase\": "), std::string::npos);
  job.force = true;
  EXPECT_TRUE(run_job(job).written);
  EXPECT_TRUE(std::filesystem::exists(job.out));
}
