// Large arrays on transparent huge pages (types.hpp, UninitializedAllocator).
#include "csrbf/types.hpp"

#include <cstdlib>
#include <new>

#include <sys/mman.h>

namespace csrbf::detail {

void* allocate_huge(std::size_t bytes) {
  constexpr std::size_t page = std::size_t(2) << 20;
  const std::size_t rounded = (bytes + page - 1) / page * page;
  if (rounded < bytes) throw std::bad_alloc();
  void* p = std::aligned_alloc(page, rounded);
  if (!p) throw std::bad_alloc();
  // Advice only: where the kernel has no huge page to give (or THP is off), 4 KiB pages as before.
  madvise(p, rounded, MADV_HUGEPAGE);
  return p;
}

void free_huge(void* p) noexcept { std::free(p); }

}  // namespace csrbf::detail
