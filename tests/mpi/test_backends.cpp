// csrbf/mpi/backends.hpp under mpirun (test_mpi: 1, 2, 3 and 4 ranks): rank 0's scatter backend
// fits and evaluates as the serial SpaceMap while the other ranks serve it; a decomposed backend's
// members are collective (largest, sum, gather in rank order, a failure agreed by all); decomposed
// cases and .pvtu files are found, and broken ones named; usage errors exit 2.
#include "csrbf/io/error.hpp"
#include "csrbf/mpi/backends.hpp"
#include "csrbf/mpi/runtime.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/space_map.hpp"

#include <gtest/gtest.h>

#include "io/test_helpers.hpp"
#include "core/test_points.hpp"
#include "mpi_ranks.hpp"

#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

using namespace csrbf;
using namespace csrbf::mpi;
namespace fs = std::filesystem;

namespace {

using csrbf::test::g_rank;
using csrbf::test::g_size;
using csrbf::test::seeded_points;

/// The message of the io::FileError f throws ("" if it throws none).
template <class F>
std::string file_error_of(F&& f) {
  try {
    f();
  } catch (const io::FileError& e) {
    return e.what();
  }
  return "";
}

TEST(MpiBackends, UsageErrorsExitTwoAndEverythingElseOne) {
  const auto code = [](auto e) { return exit_code_of(std::make_exception_ptr(e)); };
  EXPECT_EQ(code(morph::JobError("give an output")), 2);
  EXPECT_EQ(code(Failure("agreed", 1, 2)), 2);  // an agreed failure keeps its code
  EXPECT_EQ(code(Failure("agreed", 1, 1)), 1);
  EXPECT_EQ(code(InvalidInput("not finite")), 1);
  EXPECT_EQ(code(io::FileError("mesh: no such file")), 1);
  EXPECT_EQ(code(std::runtime_error("other")), 1);
}

TEST(MpiBackends, ScatteredFitEqualsTheSerialOne) {
  const std::vector<Vec3> s = seeded_points(800, 61), x = seeded_points(3000, 67);
  std::vector<Vec3> d(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) d[i] = s[i] + Vec3(0.05 * std::sin(3 * s[i].y()), 0.02 * s[i].x(), 0.01);
  const FitOptions o{0.25, Kernel::C2, Polynomial::Linear};
  if (g_rank != 0) {
    EXPECT_EQ(serve(MPI_COMM_WORLD), 0);  // until rank 0 finishes with 0
    return;
  }
  ScatterBackend b(MPI_COMM_WORLD, DistributedSolver::Auto, x);
  EXPECT_FALSE(b.keeps_mappings());
  EXPECT_FALSE(b.part());
  const auto mapping = b.fit(s, d, o, {});
  std::vector<Vec3> out(x.size()), want(x.size());
  mapping->apply(x, out, 0.7);
  SpaceMap::fit(s, d, o).apply(x, want, 0.7);
  double err = 0;
  for (std::size_t i = 0; i < x.size(); ++i) err = std::max(err, (out[i] - want[i]).norm());
  EXPECT_LT(err, 1e-10 * 0.06);
  EXPECT_EQ(mapping->stats().controls, s.size());
  EXPECT_EQ(b.stats().controls, s.size());
  EXPECT_EQ(b.stats().ranks, std::size_t(g_size));
  // Every rank's share of the controls, in rank order, adds up to all of them.
  const std::vector<RankStats> ranks = b.rank_stats();
  ASSERT_EQ(ranks.size(), std::size_t(g_size));
  std::size_t owned = 0;
  for (std::size_t r = 0; r < ranks.size(); ++r) {
    EXPECT_EQ(ranks[r].rank, int(r));
    owned += ranks[r].controls_owned;
  }
  EXPECT_EQ(owned, s.size());
  // A later fit replaces the ranks' mapping: the earlier one refuses to evaluate.
  const auto later = b.fit(s, s, o, {});
  try {
    mapping->apply(x, out, 1.0);
    ADD_FAILURE() << "a replaced mapping evaluated";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "csrbf::mpi: a mapping used after a later fit replaced it");
  }
  later->displacements(x, out);
  for (std::size_t i = 0; i < x.size(); ++i) ASSERT_LT(out[i].norm(), 1e-12);  // sources to themselves
  b.finish(0);
  b.finish(1);  // idempotent: the workers already stopped with 0
}

TEST(MpiBackends, DecomposedMembersAreCollective) {
  Decomposition d;
  d.kind = Decomposition::Kind::OpenFoam;
  for (int r = 0; r < g_size; ++r) d.parts.push_back("case/processor" + std::to_string(r));
  DecomposedBackend b(MPI_COMM_WORLD, DistributedSolver::Auto, d);
  EXPECT_TRUE(b.part());
  EXPECT_FALSE(b.keeps_mappings());
  EXPECT_EQ(b.mesh_path("case"), fs::path("case/processor" + std::to_string(g_rank)));
  EXPECT_EQ(b.max(double(g_rank)), double(g_size - 1));
  EXPECT_EQ(b.sum(double(g_rank + 1)), double(g_size * (g_size + 1) / 2));
  std::vector<double> values{double(g_rank), -double(g_rank), 5};
  b.max(values);
  EXPECT_EQ(values, (std::vector<double>{double(g_size - 1), 0, 5}));
  // Rank r holds r + 1 points (r, k, 0): all of them, in rank order, on every rank.
  std::vector<Vec3> mine;
  for (int k = 0; k <= g_rank; ++k) mine.emplace_back(g_rank, k, 0);
  std::vector<Vec3> want;
  for (int r = 0; r < g_size; ++r)
    for (int k = 0; k <= r; ++k) want.emplace_back(r, k, 0);
  EXPECT_EQ(b.gather(mine), want);
  // No failure anywhere: nothing thrown. A usage error on the last rank: every rank throws it, exit 2.
  EXPECT_NO_THROW(b.agree(nullptr));
  const std::exception_ptr local =
      g_rank == g_size - 1 ? std::make_exception_ptr(morph::JobError("levels must be 1 or 2")) : nullptr;
  try {
    b.agree(local);
    ADD_FAILURE() << "no failure agreed";
  } catch (const Failure& f) {
    EXPECT_EQ(f.rank(), g_size - 1);
    EXPECT_EQ(f.exit_code(), 2);
    EXPECT_NE(std::string(f.what()).find("levels must be 1 or 2"), std::string::npos) << f.what();
  }
}

TEST(MpiBackends, DecomposedCasesAreFoundAndBrokenOnesNamed) {
  test::TempDir dir;  // one a rank
  fs::create_directories(dir / "single" / "constant");
  EXPECT_EQ(find_decomposition(dir / "single").kind, Decomposition::Kind::None);
  EXPECT_EQ(find_decomposition(dir / "mesh.vtu").kind, Decomposition::Kind::None);
  for (int p = 0; p < 3; ++p) fs::create_directories(dir / "case" / ("processor" + std::to_string(p)));
  const Decomposition foam = find_decomposition(dir / "case");
  EXPECT_EQ(foam.kind, Decomposition::Kind::OpenFoam);
  EXPECT_EQ(foam.root, dir / "case");
  EXPECT_EQ(foam.parts,
            (std::vector<fs::path>{dir / "case/processor0", dir / "case/processor1", dir / "case/processor2"}));
  fs::create_directories(dir / "case" / "system");
  test::write_text(dir / "case/system/decomposeParDict", "numberOfSubdomains 4;\nmethod scotch;\n");
  EXPECT_EQ(file_error_of([&] { find_decomposition(dir / "case"); }),
            (dir / "case/system/decomposeParDict").string() +
                ": numberOfSubdomains 4, but the case has 3 processor folders: a processor folder is missing, or the "
                "case was decomposed again differently");
  fs::remove(dir / "case/system/decomposeParDict");
  fs::remove(dir / "case/processor1");
  EXPECT_EQ(file_error_of([&] { find_decomposition(dir / "case"); }),
            (dir / "case/processor1").string() +
                ": missing, but the case has processor2 (a decomposed case has processor0 to processorN-1)");

  test::write_text(dir / "mesh.pvtu",
                   "<VTKFile type=\"PUnstructuredGrid\"><PUnstructuredGrid>\n<Piece Source=\"mesh/mesh_0.vtu\"/>\n"
                   "<Piece Source='mesh/mesh_1.vtu'/>\n</PUnstructuredGrid></VTKFile>\n");
  const Decomposition pieces = find_decomposition(dir / "mesh.pvtu");
  EXPECT_EQ(pieces.kind, Decomposition::Kind::Pvtu);
  EXPECT_EQ(pieces.parts, (std::vector<fs::path>{dir / "mesh/mesh_0.vtu", dir / "mesh/mesh_1.vtu"}));
  EXPECT_EQ(pieces.pvtu_text, test::read_text(dir / "mesh.pvtu"));
  const auto pvtu_error = [&](const std::string& text) {
    test::write_text(dir / "bad.pvtu", text);
    return file_error_of([&] { find_decomposition(dir / "bad.pvtu"); });
  };
  const std::string bad = (dir / "bad.pvtu").string();
  EXPECT_EQ(pvtu_error("<VTKFile></VTKFile>"), bad + ": no <Piece Source=...> entries");
  EXPECT_EQ(pvtu_error("<Piece Source=\"/etc/passwd\"/>"),
            bad + ": piece '/etc/passwd': a path relative to the .pvtu's folder");
  EXPECT_EQ(pvtu_error("<Piece Source=mesh_0.vtu/>"), bad + ": a <Piece> whose Source is not quoted");
  EXPECT_EQ(pvtu_error("<Piece NumberOfPoints=\"3\"/>"), bad + ": a <Piece> without a Source attribute");
}

}  // namespace
