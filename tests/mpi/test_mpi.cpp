// The main of test_mpi (tests/mpi/test_*.cpp), which tests/CMakeLists.txt runs under mpirun with 1,
// 2, 3 and 4 ranks: MPI and PETSc started once for every test (csrbf/mpi/runtime.hpp), one report
// (rank 0's), and a run that fails where any rank failed.
#include "csrbf/mpi/runtime.hpp"

#include <gtest/gtest.h>

#include "mpi_ranks.hpp"

namespace csrbf::test {
int g_rank = 0, g_size = 1;
}  // namespace csrbf::test

using csrbf::mpi::Runtime;
using csrbf::test::g_rank;
using csrbf::test::g_size;

int main(int argc, char** argv) {
  Runtime runtime(&argc, &argv);
  g_rank = runtime.rank();
  g_size = runtime.size();
  ::testing::InitGoogleTest(&argc, argv);
  if (g_rank != 0) {  // one report: rank 0's; the others' failures still fail the run (exit code)
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  const int rc = RUN_ALL_TESTS();
  int any = 0;
  MPI_Allreduce(&rc, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return any;
}
