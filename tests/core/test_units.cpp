// Units and numbers as csrbf writes them (csrbf/units.hpp): the GiB, the durations' clock, and the
// three ways a number is written, checked against printf's %g and read back exactly.
#include "csrbf/units.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>

using namespace csrbf;

TEST(Units, AGibIsTwoToTheThirtyBytes) {
  EXPECT_EQ(kGiB, std::ldexp(1.0, 30));
  EXPECT_EQ(kGiB, 1024.0 * 1024.0 * 1024.0);
}

TEST(Units, SecondsSinceCountsOnTheSteadyClock) {
  // The clock never goes back: a point two seconds ago is at least two seconds ago.
  EXPECT_GE(seconds_since(Clock::now() - std::chrono::seconds(2)), 2.0);
  EXPECT_GE(seconds_since(Clock::now()), 0.0);
}

TEST(Units, SignificantDigitsAsPrintfWritesThem) {
  EXPECT_EQ(format_significant(0.3, 3), "0.3");
  EXPECT_EQ(format_significant(1.5e7, 3), "1.5e+07");
  EXPECT_EQ(format_significant(123456.0, 3), "1.23e+05");
  EXPECT_EQ(format_significant(2.0 / 3.0, 2), "0.67");
  EXPECT_EQ(format_significant(-0.000125, 2), "-0.00013");
  EXPECT_EQ(format_significant(42.0, 6), "42");
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> exponent(-12, 12);
  for (int i = 0; i < 200; ++i) {
    const double v = std::pow(10.0, exponent(rng));
    for (const int digits : {1, 3, 6, 10}) {
      char want[64];
      std::snprintf(want, sizeof want, "%.*g", digits, v);
      EXPECT_EQ(format_significant(v, digits), want) << v << " to " << digits << " digits";
    }
  }
}

TEST(Units, GibWithItsUnit) {
  EXPECT_EQ(format_gib(0.25 * kGiB), "0.25 GiB");
  EXPECT_EQ(format_gib(4 * kGiB), "4 GiB");
  EXPECT_EQ(format_gib(1.5 * kGiB, 2), "1.5 GiB");
  EXPECT_EQ(format_gib(123456789.0), "0.115 GiB");  // 0.11498 GiB
  EXPECT_EQ(format_gib(123456789.0, 1), "0.1 GiB");
  EXPECT_EQ(format_gib(0.0), "0 GiB");
}

TEST(Units, ShortestTextReadsBackExactly) {
  EXPECT_EQ(format_shortest(0.1), "0.1");
  EXPECT_EQ(format_shortest(1e300), "1e+300");
  EXPECT_EQ(format_shortest(-2.5), "-2.5");
  EXPECT_EQ(format_shortest(3.0), "3");
  EXPECT_EQ(format_shortest(0.1 + 0.2), "0.30000000000000004");
  const double smallest = std::numeric_limits<double>::denorm_min();
  EXPECT_EQ(format_shortest(smallest), "5e-324");
  EXPECT_EQ(std::strtod(format_shortest(smallest).c_str(), nullptr), smallest);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> mantissa(-1, 1);
  std::uniform_int_distribution<int> exponent(-300, 300);
  for (int i = 0; i < 1000; ++i) {
    const double v = std::ldexp(mantissa(rng), exponent(rng));
    const std::string text = format_shortest(v);
    EXPECT_EQ(std::strtod(text.c_str(), nullptr), v) << text;
    // Never longer than printf's 17 digits, which always read back.
    char seventeen[64];
    std::snprintf(seventeen, sizeof seventeen, "%.17g", v);
    EXPECT_LE(text.size(), std::string(seventeen).size()) << text << " against " << seventeen;
  }
}
