// csrbf/mpi/distributed.hpp under mpirun (test_mpi: tests/CMakeLists.txt runs it with 1, 2, 3 and
// 4 ranks): the distributed fit and evaluation equal the serial SpaceMap to 1e-10 of the largest
// displacement, for every kernel and polynomial and both solvers; controls whose support crosses
// every partition boundary; a rank with no points and one with no controls; shared controls owned
// once; a failure on one rank is a failure on all.
#include "csrbf/mpi/distributed.hpp"
#include "csrbf/mpi/runtime.hpp"
#include "csrbf/space_map.hpp"

#include <gtest/gtest.h>

#include "core/test_points.hpp"
#include "mpi_ranks.hpp"

#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace csrbf;
using namespace csrbf::mpi;

namespace {

using csrbf::test::g_rank;
using csrbf::test::g_size;
using csrbf::test::seeded_points;

std::vector<Vec3> moved(const std::vector<Vec3>& s) {
  std::vector<Vec3> d(s.size());
  for (std::size_t i = 0; i < s.size(); ++i)
    d[i] = s[i] + Vec3(0.05 * std::sin(3 * s[i].y()), 0.03 * s[i].x() - 0.01, 0.02 * std::cos(2 * s[i].z()));
  return d;
}

/// This rank's share of a set, by a partition every rank computes alike.
template <class T>
std::vector<T> share(const std::vector<T>& all, const std::vector<int>& part, int rank) {
  std::vector<T> out;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (part[i] == rank) out.push_back(all[i]);
  return out;
}

struct Case {
  std::vector<Vec3> s, d, x;
  Partition part;
};

Case make_case(std::size_t n, std::size_t m, unsigned seed) {
  Case c;
  c.s = seeded_points(n, seed);
  c.d = moved(c.s);
  c.x = seeded_points(m, seed + 1, -0.05, 1.05);
  c.part = rcb_partition(c.x, c.s, g_size);
  return c;
}

/// The largest distance between the distributed and the serial result over this rank's points,
/// over all ranks, relative to the largest displacement.
double compare(const Case& c, const FitOptions& o, DistributedSolver solver, const std::vector<int>& point_part,
               const std::vector<int>& control_part, double phase = 0.8) {
  const auto s = share(c.s, control_part, g_rank), d = share(c.d, control_part, g_rank);
  const auto x = share(c.x, point_part, g_rank);
  DistributedMap map = DistributedMap::fit(MPI_COMM_WORLD, s, d, o, solver);
  std::vector<Vec3> out(x.size());
  map.apply(x, out, phase);
  const SpaceMap serial = SpaceMap::fit(c.s, c.d, o);
  std::vector<Vec3> want(x.size());
  serial.apply(x, want, phase);
  double err = 0, gmax = 0;
  for (std::size_t i = 0; i < x.size(); ++i) err = std::max(err, (out[i] - want[i]).norm());
  for (std::size_t i = 0; i < c.s.size(); ++i) gmax = std::max(gmax, (c.d[i] - c.s[i]).norm());
  double all = 0;
  MPI_Allreduce(&err, &all, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return all / gmax;
}

TEST(Distributed, EqualsTheSerialFitForEveryKernelPolynomialAndSolver) {
  const Case c = make_case(2500, 20000, 19);
  for (const Kernel k : {Kernel::C0, Kernel::C2, Kernel::C4, Kernel::C6})
    for (const Polynomial p : {Polynomial::None, Polynomial::Constant, Polynomial::Linear})
      for (const DistributedSolver s : {DistributedSolver::Mumps, DistributedSolver::Cg}) {
        FitOptions o;
        o.radius = 0.2;
        o.kernel = k;
        o.polynomial = p;
        SCOPED_TRACE(std::string(kernel_name(k)) + " " + std::string(polynomial_name(p)) + " " +
                     distributed_solver_name(s));
        EXPECT_LT(compare(c, o, s, c.part.point_part, c.part.control_part), 1e-10);
      }
}

// One rank's CG is the serial fit's own (the core's, with its incomplete Cholesky), not PETSc's
// KSP: the same steps as SpaceMap::fit with the CG solver, and the same coefficients. Points on a
// plane, where CG needs its preconditioner (plain CG did not converge in 3000 steps).
// (On several ranks PETSc's additive Schwarz with ICC did not converge on these planar points in
// 3000 steps: noted in the issue.)
TEST(Distributed, OneRanksCgIsTheSerialFitsOwn) {
  {
    const Case c = make_case(1500, 10, 31);
    FitOptions o;
    o.radius = 0.2;
    const DistributedMap map = DistributedMap::fit(MPI_COMM_WORLD, share(c.s, c.part.control_part, g_rank),
                                                   share(c.d, c.part.control_part, g_rank), o, DistributedSolver::Cg);
    EXPECT_EQ(map.stats().core_cg, g_size == 1);
  }
  if (g_size != 1) return;
  std::vector<Vec3> s = seeded_points(3000, 29), d;
  for (Vec3& x : s) x.z() = 0;
  d = moved(s);
  FitOptions o;
  o.radius = 0.1;
  DistributedMap map = DistributedMap::fit(MPI_COMM_SELF, s, d, o, DistributedSolver::Cg);
  EXPECT_TRUE(map.stats().core_cg);
  FitOptions serial_options = o;
  serial_options.solver = Solver::Cg;
  const SpaceMap serial = SpaceMap::fit(s, d, serial_options);
  EXPECT_EQ(map.stats().iterations, serial.stats().iterations);
  std::vector<Vec3> out(s.size()), want(s.size());
  map.apply(s, out, 1.0);
  serial.apply(s, want, 1.0);
  double err = 0;
  for (std::size_t i = 0; i < s.size(); ++i) err = std::max(err, (out[i] - want[i]).norm());
  EXPECT_LT(err, 1e-9);
}

TEST(Distributed, SupportsCrossingEveryPartitionBoundary) {
  // R = 0.7 of the cube: every control's support reaches every part.
  const Case c = make_case(600, 5000, 23);
  FitOptions o;
  o.radius = 0.7;
  o.polynomial = Polynomial::Linear;
  EXPECT_LT(compare(c, o, DistributedSolver::Auto, c.part.point_part, c.part.control_part), 1e-10);
}

TEST(Distributed, ARankWithNoPointsAndARankWithNoControls) {
  const Case c = make_case(1500, 8000, 29);
  // The last rank has no points, rank 0 no controls (with one rank: both, on rank 0's own sets).
  std::vector<int> pp = c.part.point_part, cp = c.part.control_part;
  if (g_size > 1) {
    for (int& r : pp)
      if (r == g_size - 1) r = 0;
    for (int& r : cp)
      if (r == 0) r = 1;
  }
  FitOptions o;
  o.radius = 0.25;
  o.polynomial = Polynomial::Constant;
  EXPECT_LT(compare(c, o, DistributedSolver::Mumps, pp, cp), 1e-10);
  EXPECT_LT(compare(c, o, DistributedSolver::Cg, pp, cp), 1e-10);
}

TEST(Distributed, SharedControlsAreOwnedOnceAndMustAgree) {
  const Case c = make_case(1200, 6000, 31);
  // Every rank also holds the controls of its neighbour rank (rank + 1): duplicates, bit for bit.
  std::vector<Vec3> s = share(c.s, c.part.control_part, g_rank), d = share(c.d, c.part.control_part, g_rank);
  if (g_size > 1) {
    const int next = (g_rank + 1) % g_size;
    const auto s2 = share(c.s, c.part.control_part, next), d2 = share(c.d, c.part.control_part, next);
    s.insert(s.end(), s2.begin(), s2.end());
    d.insert(d.end(), d2.begin(), d2.end());
  }
  FitOptions o;
  o.radius = 0.25;
  DistributedMap map = DistributedMap::fit(MPI_COMM_WORLD, s, d, o, DistributedSolver::Auto, {}, true);
  EXPECT_EQ(map.stats().controls, c.s.size());
  const auto x = share(c.x, c.part.point_part, g_rank);
  std::vector<Vec3> out(x.size()), want(x.size());
  map.apply(x, out);
  SpaceMap::fit(c.s, c.d, o).apply(x, want);
  for (std::size_t i = 0; i < x.size(); ++i) ASSERT_LT((out[i] - want[i]).norm(), 1e-10);
  if (g_size > 1) {
    // The same point moved two ways on two ranks: an error on every rank, naming both.
    std::vector<Vec3> bad = d;
    for (std::size_t i = bad.size() / 2; i < bad.size(); ++i) bad[i] += Vec3(0.01, 0, 0);
    try {
      DistributedMap::fit(MPI_COMM_WORLD, s, bad, o, DistributedSolver::Auto, {}, true);
      ADD_FAILURE() << "no error";
    } catch (const Failure& f) {
      EXPECT_NE(std::string(f.what()).find("moved differently"), std::string::npos) << f.what();
    }
    // Without dedupe the duplicates are an error naming the controls.
    try {
      DistributedMap::fit(MPI_COMM_WORLD, s, d, o, DistributedSolver::Auto, {}, false);
      ADD_FAILURE() << "no error";
    } catch (const Failure& f) {
      EXPECT_NE(std::string(f.what()).find("same source"), std::string::npos) << f.what();
    }
  }
}

TEST(Distributed, AFailureOnOneRankIsAFailureOnAll) {
  const Case c = make_case(500, 100, 37);
  auto s = share(c.s, c.part.control_part, g_rank), d = share(c.d, c.part.control_part, g_rank);
  const int bad = g_size - 1;
  if (g_rank == bad && !s.empty()) s[0].x() = std::nan("");
  if (g_rank == bad && s.empty()) {
    s.push_back(Vec3(std::nan(""), 0, 0));
    d.push_back(Vec3::Zero());
  }
  FitOptions o;
  o.radius = 0.3;
  try {
    DistributedMap::fit(MPI_COMM_WORLD, s, d, o);
    ADD_FAILURE() << "no error";
  } catch (const Failure& f) {
    EXPECT_EQ(f.rank(), bad);
    EXPECT_EQ(f.exit_code(), 1);
    EXPECT_NE(std::string(f.what()).find("not finite"), std::string::npos) << f.what();
  }
  // A radius that is no number: the same error on every rank, from every rank's own check.
  o.radius = -1;
  EXPECT_THROW(DistributedMap::fit(MPI_COMM_WORLD, share(c.s, c.part.control_part, g_rank),
                                   share(c.d, c.part.control_part, g_rank), o),
               Failure);
  // No controls anywhere.
  o.radius = 0.3;
  EXPECT_THROW(DistributedMap::fit(MPI_COMM_WORLD, {}, {}, o), Failure);
}

TEST(Partition, RcbBalancesPointsAndControls) {
  const auto x = seeded_points(10000, 41), s = seeded_points(500, 43);
  for (const int parts : {1, 2, 3, 4, 7}) {
    const Partition p = rcb_partition(x, s, parts);
    std::vector<int> np(std::size_t(parts), 0), nc(std::size_t(parts), 0);
    for (const int r : p.point_part) ++np[std::size_t(r)];
    for (const int r : p.control_part) ++nc[std::size_t(r)];
    for (int r = 0; r < parts; ++r) {
      // Each part within 5% of its even share of the total weight (points + controls weighted).
      const double w = np[std::size_t(r)] + nc[std::size_t(r)] * (10000.0 / 500.0);
      EXPECT_NEAR(w / (20000.0 / parts), 1.0, 0.05) << parts << " parts, part " << r;
    }
  }
}

TEST(Partition, EveryPointAndControlLiesInItsPartsRegion) {
  const auto x = seeded_points(5000, 47), s = seeded_points(400, 53);
  for (const int parts : {1, 2, 3, 5}) {
    const Partition p = rcb_partition(x, s, parts);
    ASSERT_EQ(p.point_part.size(), x.size());
    ASSERT_EQ(p.control_part.size(), s.size());
    for (std::size_t i = 0; i < x.size(); ++i) ASSERT_EQ(p.part_of(x[i]), p.point_part[i]) << parts << " parts";
    for (std::size_t i = 0; i < s.size(); ++i) ASSERT_EQ(p.part_of(s[i]), p.control_part[i]) << parts << " parts";
    // A point outside every box still has a part, by the same cuts.
    const int far = p.part_of(Vec3(10, 10, 10));
    EXPECT_GE(far, 0);
    EXPECT_LT(far, parts);
  }
  EXPECT_EQ(Partition{}.part_of(Vec3(1, 2, 3)), 0);  // no cuts: one part
}

TEST(Distributed, SolverNamesAndTheSerialOnes) {
  for (const auto s : {DistributedSolver::Auto, DistributedSolver::Mumps, DistributedSolver::Cg})
    EXPECT_EQ(parse_distributed_solver(distributed_solver_name(s)), s);
  EXPECT_EQ(distributed_solver_name(DistributedSolver::Mumps), "mumps");
  // The serial direct solvers have no distributed form: MUMPS stands for them.
  for (const char* direct : {"envelope", "eigen", "cholmod"})
    EXPECT_EQ(parse_distributed_solver(direct), DistributedSolver::Mumps) << direct;
  EXPECT_EQ(parse_distributed_solver("cg"), DistributedSolver::Cg);
  EXPECT_FALSE(parse_distributed_solver("petsc").has_value());
  EXPECT_FALSE(parse_distributed_solver("").has_value());
}

}  // namespace
