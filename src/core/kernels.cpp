#include "csrbf/kernels.hpp"

#include <algorithm>
#include <cctype>
#include <string>

namespace csrbf {

std::string_view kernel_name(Kernel k) noexcept {
  switch (k) {
    case Kernel::C0: return "c0";
    case Kernel::C2: return "c2";
    case Kernel::C4: return "c4";
    case Kernel::C6: return "c6";
  }
  return "?";
}

std::optional<Kernel> parse_kernel(std::string_view name) noexcept {
  std::string s(name);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (s == "c0" || s == "psi20") return Kernel::C0;
  if (s == "c2" || s == "psi31") return Kernel::C2;
  if (s == "c4" || s == "psi42") return Kernel::C4;
  if (s == "c6" || s == "psi53") return Kernel::C6;
  return std::nullopt;
}

int kernel_smoothness(Kernel k) noexcept {
  switch (k) {
    case Kernel::C0: return 0;
    case Kernel::C2: return 2;
    case Kernel::C4: return 4;
    case Kernel::C6: return 6;
  }
  return 0;
}

}  // namespace csrbf
