#include "csrbf/io/memory.hpp"

#include "csrbf/io/error.hpp"

#include <cmath>
#include <cstdio>
#include <unistd.h>

namespace csrbf::io {

double resident_bytes() noexcept {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long long size = 0, resident = 0;
  const int got = std::fscanf(f, "%llu %llu", &size, &resident);
  std::fclose(f);
  return got == 2 ? double(resident) * double(::sysconf(_SC_PAGESIZE)) : 0.0;
}

double memory_left(double limit_bytes, const std::string& option) {
  const double held = resident_bytes(), left = limit_bytes - held;
  if (left < limit_bytes / 20) {
    char text[300];
    std::snprintf(text, sizeof text,
                  "%s %.3g GiB is too small: csrbf already holds %.3g GiB (the program, its libraries and what it "
                  "read), which leaves less than the twentieth of it that the work needs at least; give %s %.2g or "
                  "more",
                  option.c_str(), limit_bytes / double(1ull << 30), held / double(1ull << 30), option.c_str(),
                  std::ceil(100 * 1.25 * held / double(1ull << 30)) / 100);
    throw FileError(text);
  }
  return left;
}

std::string memory_share(double limit_bytes, double left, const std::string& option) {
  char text[200];
  std::snprintf(text, sizeof text,
                " (%s %.3g GiB: csrbf and what it read hold %.3g GiB of it, leaving %.3g GiB for the fit)",
                option.c_str(), limit_bytes / double(1ull << 30), (limit_bytes - left) / double(1ull << 30),
                left / double(1ull << 30));
  return text;
}

}  // namespace csrbf::io
