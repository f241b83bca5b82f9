// Where a morph fits and evaluates (csrbf/morph/backend.hpp): the default backend is SpaceMap in
// this process, whose collective members are those of one process alone, and a job's backend
// decides which mesh is opened and where the moved points go.
#include "morph_test_helpers.hpp"
#include "core/test_points.hpp"
#include "csrbf/morph/backend.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/space_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

using csrbf::Vec3;
using namespace csrbf::morph;
using csrbf::test::motion_from;
using csrbf::test::seeded_points;

namespace {

/// Opens the case under another name and keeps the moved points instead of writing them.
class RecordingBackend : public MorphBackend {
 public:
  explicit RecordingBackend(std::filesystem::path real) : real_(std::move(real)) {}
  std::filesystem::path mesh_path(const std::filesystem::path& mesh) override {
    asked = mesh;
    return real_;
  }
  void write_copy(const VolumeFile&, std::span<const Vec3> points, const std::filesystem::path& out) override {
    written.assign(points.begin(), points.end());
    written_to = out;
  }
  std::filesystem::path asked, written_to;
  std::vector<Vec3> written;

 private:
  std::filesystem::path real_;
};

}  // namespace

TEST(MorphBackend, TheLocalBackendIsOneProcessAlone) {
  MorphBackend& b = local_backend();
  EXPECT_EQ(&b, &local_backend());
  EXPECT_FALSE(b.part());
  EXPECT_TRUE(b.keeps_mappings());
  EXPECT_EQ(b.max(-2.5), -2.5);
  EXPECT_EQ(b.sum(7.25), 7.25);
  const std::vector<Vec3> points{Vec3(1, 2, 3), Vec3(-4, 5, 6)};
  EXPECT_EQ(b.gather(points), points);
  std::vector<double> values{3, -1, 2};
  b.max(values);
  EXPECT_EQ(values, (std::vector<double>{3, -1, 2}));
  EXPECT_EQ(b.mesh_path("case/constant"), std::filesystem::path("case/constant"));
}

TEST(MorphBackend, AgreeRethrowsWhatCaughtCaught) {
  MorphBackend& b = local_backend();
  EXPECT_EQ(caught([] {}), nullptr);
  EXPECT_NO_THROW(b.agree(caught([] {})));
  const std::exception_ptr e = caught([] { throw std::out_of_range("patch 7"); });
  ASSERT_NE(e, nullptr);
  try {
    b.agree(e);
    FAIL() << "agree swallowed the failure";
  } catch (const std::out_of_range& x) {
    EXPECT_STREQ(x.what(), "patch 7");
  }
}

TEST(MorphBackend, TheLocalFitIsSpaceMaps) {
  const std::vector<Vec3> s = seeded_points(300, 3);
  std::vector<Vec3> d(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) d[i] = s[i] + Vec3(0.05 * std::sin(3 * s[i].y()), 0.02 * s[i].x(), 0);
  const csrbf::FitOptions o{0.3, csrbf::Kernel::C2, csrbf::Polynomial::Linear};
  const auto mapping = local_backend().fit(s, d, o, {});
  const csrbf::SpaceMap map = csrbf::SpaceMap::fit(s, d, o);
  const std::vector<Vec3> x = seeded_points(500, 4);
  std::vector<Vec3> out(x.size()), want(x.size()), disp(x.size()), want_disp(x.size());
  mapping->apply(x, out, 0.5);
  map.apply(x, want, 0.5);
  mapping->displacements(x, disp);
  map.displacements(x.front().data(), want_disp.front().data(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    ASSERT_EQ(out[i], want[i]);
    ASSERT_EQ(disp[i], want_disp[i]);
    ASSERT_NEAR((out[i] - (x[i] + 0.5 * disp[i])).norm(), 0.0, 1e-15);  // in + phase d(in)
  }
  EXPECT_EQ(mapping->stats().controls, s.size());
  EXPECT_EQ(mapping->stats().neighbor_pairs, map.stats().neighbor_pairs);
}

TEST_F(BoxMorph, AJobsBackendOpensAndWritesTheMesh) {
  motion_from(dir, R"({"radius": 0.5, "patches": {"zmax": {"translate": [0, 0, 0.05]}, "zmin": "fixed"}})");
  RecordingBackend b(dir.path / "case");
  MorphJob job;
  job.mesh = dir / "elsewhere";  // not there: the backend opens the case instead
  job.motion = dir / "motion.json";
  job.out = dir / "moved";
  job.backend = &b;
  const MorphOutcome o = run_job(job);
  EXPECT_EQ(b.asked, dir / "elsewhere");
  EXPECT_TRUE(o.written);
  EXPECT_EQ(b.written_to, dir / "moved");
  EXPECT_FALSE(std::filesystem::exists(dir / "moved"));  // the backend wrote nothing
  ASSERT_EQ(b.written.size(), c.mesh.points.size());
  EXPECT_EQ(b.written, o.result.points);
}
