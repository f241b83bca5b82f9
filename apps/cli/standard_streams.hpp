// Standard input, output and error held open: a closed one would become the next file the
// program opens (a pipe to a child reader, which the child then overwrites with its own
// /dev/null, so that the parent reads nothing), so each closed one is opened on /dev/null. Shared
// by the launcher and the programs it runs (which may be run directly).
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>

namespace csrbf::cli {

inline void hold_standard_streams() noexcept {
  for (int fd = 0; fd <= 2; ++fd)
    if (::fcntl(fd, F_GETFD) == -1 && errno == EBADF) {
      const int null = ::open("/dev/null", O_RDWR);
      if (null >= 0 && null != fd) {
        ::dup2(null, fd);
        ::close(null);
      }
    }
}

}  // namespace csrbf::cli
