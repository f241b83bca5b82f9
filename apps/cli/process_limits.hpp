// Whether the process runs under an address-space limit (ulimit -v) or a tight process limit:
// there OpenBLAS's and libgomp's threads, started as the libraries load, cannot have their
// buffers, and the launcher keeps the heap unpadded. Shared by the launcher and the programs it
// runs (which may be run directly).
#pragma once

#include <sys/resource.h>

namespace csrbf::cli {

inline bool under_process_limits() noexcept {
  rlimit as{}, procs{};
  return (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) ||
         (::getrlimit(RLIMIT_NPROC, &procs) == 0 && procs.rlim_cur != RLIM_INFINITY && procs.rlim_cur < 4096);
}

}  // namespace csrbf::cli
