// The csrbf program end to end, as a user runs it.
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdio>
#include <sys/wait.h>

namespace fs = std::filesystem;
using csrbf::test::read_text;
using csrbf::test::TempDir;
using csrbf::test::write_text;

namespace {

using CliRun = csrbf::test::ShellRun;

CliRun run(const std::string& args) { return csrbf::test::run_shell(std::string(CSRBF_CLI) + " " + args); }

const std::string kExamples = std::string(CSRBF_SOURCE_DIR) + "/examples/";

std::vector<std::string> v_lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);)
    if (l.rfind("v ", 0) == 0) out.push_back(l);
  return out;
}

}  // namespace

TEST(Cli, DeformsTheBundledFishKeepingVertexOrder) {
  TempDir dir;
  const auto out = (dir / "fish.obj").string();
  const CliRun r =
      run("deform --mesh " + kExamples + "fish.obj --controls " + kExamples + "fish.controls --radius 0.3 -o " + out);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("977 vertices"), std::string::npos) << r.out;
  const std::string in_text = read_text(kExamples + "fish.obj"), out_text = read_text(out);
  const auto vin = v_lines(in_text), vout = v_lines(out_text);
  ASSERT_EQ(vin.size(), vout.size());
  // Faces and comments identical, line for line.
  std::istringstream a(in_text), b(out_text);
  std::string la, lb;
  std::size_t moved = 0, i = 0;
  while (std::getline(a, la) && std::getline(b, lb)) {
    if (la.rfind("v ", 0) != 0) {
      EXPECT_EQ(la, lb);
      continue;
    }
    double x0, y0, z0, x1, y1, z1;
    ASSERT_EQ(std::sscanf(la.c_str(), "v %lf %lf %lf", &x0, &y0, &z0), 3);
    ASSERT_EQ(std::sscanf(lb.c_str(), "v %lf %lf %lf", &x1, &y1, &z1), 3);
    const double d = std::abs(x1 - x0) + std::abs(y1 - y0) + std::abs(z1 - z0);
    EXPECT_LT(d, 0.3) << "vertex " << i;  // each vertex stays near itself: order kept
    moved += d > 0;
    ++i;
  }
  EXPECT_GT(moved, 100u);
  // The controls' sources land on their destinations: tail control 1 of fish.controls.
  std::istringstream c(read_text(kExamples + "fish.controls"));
  std::string line;
  int checked = 0;
  while (std::getline(c, line) && checked < 5) {
    if (line.empty() || line[0] == '#') continue;
    double s[3], d[3];
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf %lf %lf %lf %lf %lf", &s[0], &s[1], &s[2], &d[0], &d[1], &d[2]), 6);
    for (std::size_t k = 0; k < vin.size(); ++k) {
      double x, y, z;
      std::sscanf(vin[k].c_str(), "v %lf %lf %lf", &x, &y, &z);
      if (std::abs(x - s[0]) + std::abs(y - s[1]) + std::abs(z - s[2]) < 1e-9) {
        std::sscanf(vout[k].c_str(), "v %lf %lf %lf", &x, &y, &z);
        EXPECT_NEAR(x, d[0], 1e-9);
        EXPECT_NEAR(y, d[1], 1e-9);
        EXPECT_NEAR(z, d[2], 1e-9);
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 5);
}

TEST(Cli, PhaseZeroLeavesTheMeshAndHalfPhaseHalves) {
  TempDir dir;
  write_text(dir / "p.xyz", "0 0 0\n0.1 0 0\n5 5 5\n");
  write_text(dir / "c.txt", "0 0 0 0 0 1\n");
  CliRun r = run("deform --mesh " + (dir / "p.xyz").string() + " --controls " + (dir / "c.txt").string() +
                 " -r 1 --kernel c0 --phase 0.5 -o " + (dir / "o.xyz").string());
  ASSERT_EQ(r.code, 0) << r.out;
  // phi_c0(0.1) = 0.81; alpha = 1; phase 0.5
  EXPECT_EQ(read_text(dir / "o.xyz"), "0 0 0.5\n0.1 0 0.405\n5 5 5\n");
  r = run("deform --mesh " + (dir / "p.xyz").string() + " --controls " + (dir / "c.txt").string() +
          " -r 1 --phase 0 -o " + (dir / "z.xyz").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(read_text(dir / "z.xyz"), read_text(dir / "p.xyz"));
}

TEST(Cli, InfoPrintsStatsAndJson) {
  CliRun r = run("info --controls " + kExamples + "fish.controls --radius 0.3");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("controls           92"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("dense 33856"), std::string::npos) << r.out;
  r = run("info --controls " + kExamples + "fish.controls --radius 0.3 --kernel c0 --polynomial linear --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("\"controls\": 92"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"kernel\": \"c0\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"envelope_bytes\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"breadth_first\""), std::string::npos) << r.out;
}

// Issue 32, point 2: cost before work, without a fit.
TEST(Cli, InfoEstimatesAndSuggestsARadius) {
  CliRun r = run("info --controls " + kExamples + "fish.controls --radius 0.3 --estimate");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("neighbours         34.30 per control, at most 51"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("auto starts with   envelope"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("bandwidth"), std::string::npos) << r.out;  // no fit ran
  r = run("info --controls " + kExamples + "fish.controls --neighbours 10 --estimate --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_NEAR(j["estimate"]["mean_neighbors"].get<double>(), 10.0, 1.0) << r.out;
  EXPECT_EQ(j["estimate"]["solvers"].size(), 3u);
  // The radius it names gives those neighbours in the fit itself.
  r = run("info --controls " + kExamples + "fish.controls --json --radius " +
          std::to_string(j["radius"].get<double>()));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NEAR(nlohmann::json::parse(r.out)["mean_neighbors"].get<double>(), 10.0, 1.0);
  EXPECT_EQ(run("info --controls " + kExamples + "fish.controls").code, 2);
  EXPECT_EQ(run("info --controls " + kExamples + "fish.controls --neighbours 500").code, 2);
  EXPECT_EQ(run("info --controls " + kExamples + "fish.controls --neighbours 5 --radius 0.3").code, 2);
  EXPECT_EQ(run("info --controls " + kExamples + "fish.controls --neighbours -5").code, 2);
}

TEST(Cli, HelpAndUsageErrors) {
  for (const char* cmd : {"--help", "deform --help", "info --help"}) {
    const CliRun r = run(cmd);
    EXPECT_EQ(r.code, 0) << cmd;
    EXPECT_NE(r.out.find("--"), std::string::npos);
  }
  const std::string base = "info --controls " + kExamples + "fish.controls ";
  for (const char* bad : {"--radius 0", "--radius -1", "--radius abc", "--radius nan", "--radius inf",
                          "--radius 0.3 --kernel c3", "--radius 0.3 --polynomial cubic"}) {
    const CliRun r = run(base + bad);
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.out;
  }
  EXPECT_NE(run(base + "--radius abc").out.find("abc"), std::string::npos);
  EXPECT_EQ(run("").code, 2);
  EXPECT_EQ(run("frobnicate").code, 2);
  EXPECT_EQ(run("deform --controls x").code, 2);
  EXPECT_EQ(run("deform --mesh a.obj --controls c --radius 1 --phase 1.5 -o b.obj").code, 2);
}

TEST(Cli, BadDataFailsWithoutTouchingTheOutput) {
  TempDir dir;
  const std::string mesh = kExamples + "fish.obj";
  const std::string out = (dir / "out.obj").string();
  write_text(out, "precious");
  struct Case {
    std::string controls_text, args, expect;
  };
  const std::vector<Case> cases{
      {"0 0 0 1 1 1\n0 0 0 2 2 2\n", "-r 0.3", "line 1"},
      {"0 0 0 1 1 nan\n", "-r 0.3", "c.txt:1:"},
      {"0 0 0 1 1\n", "-r 0.3", "c.txt:1:"},
      {"# empty\n", "-r 0.3", "no control vectors"},
      {"0 0 0 0 0 0\n1 0 0 1 0 0\n0 1 0 0 1 0\n", "-r 0.3 --polynomial linear", "constant"},
      {"0 0 0 0 0 0\n1 0 0 1 0 0\n0 1 0 0 1 0\n1 1 0 1 1 0\n", "-r 0.3 --polynomial linear", "coplanar"},
  };
  for (const auto& c : cases) {
    write_text(dir / "c.txt", c.controls_text);
    const CliRun r =
        run("deform --mesh " + mesh + " --controls " + (dir / "c.txt").string() + " " + c.args + " -o " + out);
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(c.expect), std::string::npos) << r.out;
    EXPECT_EQ(read_text(out), "precious");
  }
  write_text(dir / "c.txt", "0 0 0 1 1 1\n");
  write_text(dir / "bad.obj", "v 0 0 0\nv 1 1\n");
  const std::string ok_controls = " --controls " + (dir / "c.txt").string() + " -r 0.3 -o ";
  CliRun r = run("deform --mesh " + (dir / "bad.obj").string() + ok_controls + out);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("bad.obj:2:"), std::string::npos) << r.out;
  r = run("deform --mesh " + (dir / "missing.obj").string() + ok_controls + out);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("missing.obj"), std::string::npos) << r.out;
  r = run("deform --mesh " + mesh + ok_controls + (dir / "no/such/out.obj").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("does not exist"), std::string::npos) << r.out;
  r = run("deform --mesh " + mesh + " --controls " + (dir / "nothere.txt").string() + " -r 0.3 -o " + out);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("nothere.txt"), std::string::npos) << r.out;
  EXPECT_EQ(read_text(out), "precious");
  EXPECT_EQ(csrbf::test::files_in(dir.path), 3u);  // out.obj, c.txt, bad.obj: no temporaries left
}

TEST(Cli, ExactDuplicateControlsWarnAndSucceed) {
  TempDir dir;
  write_text(dir / "c.txt", "0.5 0.5 0.5 0.5 0.6 0.5\n0.5 0.5 0.5 0.5 0.6 0.5\n");
  const CliRun r = run("deform --mesh " + kExamples + "fish.obj --controls " + (dir / "c.txt").string() +
                       " -r 0.3 -o " + (dir / "o.ply").string());
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("c.txt:2:"), std::string::npos) << r.out;
}

TEST(Cli, BenchPrintsJsonRowsWithMedians) {
  CliRun r = run("bench --scenario ball --json --seconds 0.01");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("\"scenario\":\"ball\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"vertices\":386"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"recompute_us\":"), std::string::npos) << r.out;
  r = run("bench --scenario fish --json --seconds 0.01");
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* key : {"\"controls\":92", "\"vertices\":977", "\"fit_us\":", "\"eval_us\":", "\"playback_us\":",
                          "\"memcpy_us\":", "\"threads\":1", "\"radius\":0.3"})
    EXPECT_NE(r.out.find(key), std::string::npos) << key << "\n" << r.out;
  r = run("bench --scenario nope");
  EXPECT_EQ(r.code, 2) << r.out;
}

TEST(Cli, ReadsADeformationFile) {
  TempDir dir;
  // The same deformation as a deformation JSON (referring to the controls) and as options.
  write_text(dir / "fish.json", R"({"format": "csrbf-deformation", "version": 1, "kernel": "c4", "radius": 0.3,
                                    "polynomial": "constant", "controls": ")" +
                                    kExamples + R"(fish.controls"})");
  const CliRun a = run("deform --mesh " + kExamples + "fish.obj --deformation " + (dir / "fish.json").string() +
                       " -o " + (dir / "a.obj").string());
  ASSERT_EQ(a.code, 0) << a.out;
  const CliRun b = run("deform --mesh " + kExamples + "fish.obj --controls " + kExamples +
                       "fish.controls --radius 0.3 --kernel c4 --polynomial constant -o " + (dir / "b.obj").string());
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_EQ(read_text(dir / "a.obj"), read_text(dir / "b.obj"));
  // Both ways at once, or neither, is a usage error.
  EXPECT_EQ(run("info --deformation " + (dir / "fish.json").string() + " --radius 0.3").code, 2);
  EXPECT_EQ(run("info").code, 2);
  // Inline sources with a duplicate: the message names the JSON entries.
  write_text(dir / "dup.json",
             R"({"radius": 0.3, "sources": [[0,0,0],[1,0,0],[0,0,0]], "destinations": [[0,0,0],[1,0,0],[0,0,1]]})");
  const CliRun d = run("info --deformation " + (dir / "dup.json").string());
  EXPECT_EQ(d.code, 1);
  EXPECT_NE(d.out.find("dup.json: sources[2]: source is the same as on sources[0]"), std::string::npos) << d.out;
}

TEST(Cli, CheckFoldsReportsTheFirstFold) {
  TempDir dir;
  // One control pushed 0.3 along +z with R = 0.5 (0.6 R): C2 folds from phase 1 / (0.6 * 135 / 64) = 0.79.
  write_text(dir / "push.controls", "0.5 0.5 0.9  0.5 0.5 1.2\n");
  const CliRun r = run("info --controls " + (dir / "push.controls").string() + " --radius 0.5 --mesh " + kExamples +
                       "face.obj --check-folds");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("FOLDS at the phase checked"), std::string::npos) << r.out;
  const CliRun j = run("info --controls " + (dir / "push.controls").string() + " --radius 0.5 --mesh " + kExamples +
                       "face.obj --check-folds --phase 0.5 --json");
  ASSERT_EQ(j.code, 0) << j.out;
  const auto json = nlohmann::json::parse(j.out);
  EXPECT_EQ(json["folds"]["folded"], 0);
  EXPECT_GT(json["folds"]["min_det"].get<double>(), 0.0);
  // The face's surface does not pass exactly through r = R/4 ahead of the push: the fold starts
  // at or after the closed form's 0.79.
  EXPECT_GE(json["folds"]["fold_free_phase"].get<double>(), 0.79);
  EXPECT_LT(json["folds"]["fold_free_phase"].get<double>(), 1.0);
  EXPECT_EQ(run("info --controls " + (dir / "push.controls").string() + " --radius 0.5 --check-folds").code, 2);
}
