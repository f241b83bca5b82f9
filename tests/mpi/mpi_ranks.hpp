// The rank of this process and the number of ranks of test_mpi's run, set by its main
// (tests/mpi/test_mpi.cpp) before any test runs.
#pragma once

namespace csrbf::test {
extern int g_rank, g_size;
}  // namespace csrbf::test
