// What a long morph tells its user (csrbf/morph/progress.hpp): a ProgressPhase begins and ends its
// phase on a Progress, or does nothing without one, and run_job's phases come in order, each ended.
#include "morph_test_helpers.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/morph/progress.hpp"
#include "csrbf/units.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

using namespace csrbf::morph;
using csrbf::test::motion_from;

namespace {

/// Every call, as text: "note ...", "begin fit 10 2", "advance 3", "end".
class Recorder : public Progress {
 public:
  void note(const std::string& line) override { calls.push_back("note " + line); }
  void begin(const std::string& phase, double total, double seconds) override {
    calls.push_back("begin " + phase + " " + csrbf::format_shortest(total) + " " + csrbf::format_shortest(seconds));
    phases.push_back(phase);
  }
  void advance(double done) override { calls.push_back("advance " + csrbf::format_shortest(done)); }
  void end() override { calls.push_back("end"); }
  std::vector<std::string> calls, phases;
};

}  // namespace

TEST(Progress, APhaseBeginsAndEndsWithItsScope) {
  Recorder r;
  {
    ProgressPhase fit(&r, "fit", 10, 2.5);
    fit.advance(3);
    fit.advance(10);
  }
  { const ProgressPhase read(&r, "read"); }
  EXPECT_EQ(r.calls,
            (std::vector<std::string>{"begin fit 10 2.5", "advance 3", "advance 10", "end", "begin read 0 0", "end"}));
  // Without a Progress nothing is told, and nothing fails.
  ProgressPhase none(nullptr, "fit", 10, 1);
  none.advance(5);
  // The base class hears everything and says nothing.
  Progress quiet;
  quiet.note("radius 0.5");
  quiet.begin("fit");
  quiet.advance(1);
  quiet.end();
}

TEST_F(BoxMorph, ARunJobsPhasesComeInOrderEachEnded) {
  motion_from(dir, R"({"radius": 0.5, "patches": {"zmax": {"translate": [0, 0, 0.05]}, "zmin": "fixed"}})");
  Recorder r;
  MorphJob job;
  job.mesh = dir / "case";
  job.motion = dir / "motion.json";
  job.out = dir / "moved";
  job.progress = &r;
  ASSERT_TRUE(run_job(job).written);
  ASSERT_FALSE(r.phases.empty());
  EXPECT_EQ(r.phases.front(), "read");
  EXPECT_EQ(r.phases.back(), "write");
  for (const char* phase : {"fit", "evaluate", "quality"})
    EXPECT_NE(std::find(r.phases.begin(), r.phases.end(), phase), r.phases.end()) << phase;
  // Phases do not nest: each begin is followed by its end before the next begins.
  int open = 0;
  for (const std::string& call : r.calls) {
    if (call.rfind("begin ", 0) == 0) {
      EXPECT_EQ(open, 0) << call;
      ++open;
    } else if (call == "end") {
      --open;
      EXPECT_EQ(open, 0);
    } else if (call.rfind("advance ", 0) == 0) {
      EXPECT_EQ(open, 1) << call;
    }
  }
  EXPECT_EQ(open, 0);
}
