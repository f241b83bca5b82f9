#include "csrbf/io/memory.hpp"

#include "csrbf/io/error.hpp"
#include "csrbf/units.hpp"

#include <cmath>
#include <cstdio>
#include <unistd.h>

namespace csrbf::io {

namespace {
/// Field 0 (the address space) or 1 (resident) of /proc/self/statm, in bytes; 0 where unknown.
double statm_bytes(int field) noexcept {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long long size = 0, resident = 0;
  const int got = std::fscanf(f, "%llu %llu", &size, &resident);
  std::fclose(f);
  return got == 2 ? double(field == 0 ? size : resident) * double(::sysconf(_SC_PAGESIZE)) : 0.0;
}
}  // namespace

double resident_bytes() noexcept { return statm_bytes(1); }

double address_space_bytes() noexcept { return statm_bytes(0); }

double memory_left(double limit_bytes, const std::string& option) {
  const double held = resident_bytes(), left = limit_bytes - held;
  if (left < limit_bytes / 20) {
    char text[300];
    std::snprintf(text, sizeof text,
                  "%s %.3g GiB is too small: csrbf already holds %.3g GiB (the program, its libraries and what it "
                  "read), which leaves less than the 5 %% of it that the work needs at least; give %s %.2g or more",
                  option.c_str(), limit_bytes / kGiB, held / kGiB, option.c_str(),
                  std::ceil(100 * 1.25 * held / kGiB) / 100);
    throw FileError(text);
  }
  return left;
}

std::string memory_share(double limit_bytes, double left, const std::string& option) {
  char text[200];
  std::snprintf(text, sizeof text,
                " (%s %.3g GiB: csrbf and what it read hold %.3g GiB of it, leaving %.3g GiB for the fit)",
                option.c_str(), limit_bytes / kGiB, (limit_bytes - left) / kGiB, left / kGiB);
  return text;
}

}  // namespace csrbf::io
