#include "csrbf/kernels.hpp"

#include "csrbf/names.hpp"

namespace csrbf {

std::string_view kernel_name(Kernel k) noexcept { return name_of(k); }
std::optional<Kernel> parse_kernel(std::string_view name) noexcept { return parse_name<Kernel>(name); }

int kernel_smoothness(Kernel k) noexcept {
  switch (k) {
    case Kernel::C0:
      return 0;
    case Kernel::C2:
      return 2;
    case Kernel::C4:
      return 4;
    case Kernel::C6:
      return 6;
  }
  return 0;
}

}  // namespace csrbf
