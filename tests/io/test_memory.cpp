// What the process holds (csrbf/io/memory.hpp): its resident and address-space sizes grow with
// what it touches, and --memory-limit's share and refusal messages add up.
#include "csrbf/io/error.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/units.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <sys/mman.h>

using namespace csrbf;

TEST(Memory, ResidentAndAddressSpaceGrowWithWhatIsTouched) {
  const double resident = io::resident_bytes(), space = io::address_space_bytes();
  EXPECT_GT(resident, 0.0);
  EXPECT_LE(resident, space);
  // Mapped here rather than allocated, so that no allocator (a sanitizer's) holds the pages already.
  constexpr std::size_t bytes = std::size_t(64) << 20;
  void* block = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(block, MAP_FAILED);
  EXPECT_GE(io::address_space_bytes() - space, double(bytes));
  EXPECT_LT(io::resident_bytes() - resident, 0.5 * double(bytes));  // reserved, not yet resident
  std::memset(block, 1, bytes);                                     // every page touched
  EXPECT_GE(io::resident_bytes() - resident, 0.9 * double(bytes));
  ::munmap(block, bytes);
}

TEST(Memory, WhatIsLeftOfALimitIsTheLimitLessWhatIsHeld) {
  const double limit = io::resident_bytes() + 2 * kGiB;
  const double left = io::memory_left(limit);
  // The process allocates nothing of note between the two readings (a few pages at most).
  EXPECT_NEAR(left, limit - io::resident_bytes(), 1 << 20);
  EXPECT_NEAR(left, 2 * kGiB, 1 << 20);
}

TEST(Memory, ALimitBelowWhatIsHeldIsRefusedNamingTheOption) {
  const double held = io::resident_bytes();
  for (const std::string option : {"--memory-limit", "memory_limit"}) {
    try {
      io::memory_left(held, option);  // nothing left for the work
      FAIL() << "a limit of what the process holds was accepted";
    } catch (const io::FileError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind(option + " ", 0), 0u) << m;
      EXPECT_NE(m.find(" GiB is too small: csrbf already holds "), std::string::npos) << m;
      EXPECT_NE(m.find("leaves less than the 5 % of it that the work needs at least; give " + option + " "),
                std::string::npos)
          << m;
    }
  }
  // A twentieth of the limit left is enough.
  EXPECT_NO_THROW(io::memory_left(held * 20.0 / 19.0 + (16 << 20)));
}

TEST(Memory, ShareOfTheLimitAddsUp) {
  EXPECT_EQ(io::memory_share(4 * kGiB, 1 * kGiB),
            " (--memory-limit 4 GiB: csrbf and what it read hold 3 GiB of it, leaving 1 GiB for the fit)");
  EXPECT_EQ(io::memory_share(0.5 * kGiB, 0.125 * kGiB, "memory_limit"),
            " (memory_limit 0.5 GiB: csrbf and what it read hold 0.375 GiB of it, leaving 0.125 GiB for the fit)");
  EXPECT_EQ(io::memory_share(1 * kGiB, kGiB / 3),
            " (--memory-limit 1 GiB: csrbf and what it read hold 0.667 GiB of it, leaving 0.333 GiB for the fit)");
}
