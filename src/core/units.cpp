// Numbers as csrbf writes them (units.hpp).
#include "csrbf/units.hpp"

#include <charconv>
#include <sstream>

namespace csrbf {

std::string format_significant(double v, int digits) {
  std::ostringstream os;
  os.precision(digits);
  os << v;
  return os.str();
}

std::string format_gib(double bytes, int digits) { return format_significant(bytes / kGiB, digits) + " GiB"; }

std::string format_shortest(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace csrbf
