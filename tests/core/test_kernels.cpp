#include "csrbf/kernels.hpp"

#include <gtest/gtest.h>

#include <cmath>

using csrbf::Kernel;

namespace {

double closed_form(Kernel k, double r) {
  if (r >= 1) return 0;
  switch (k) {
    case Kernel::C0:
      return std::pow(1 - r, 2);
    case Kernel::C2:
      return std::pow(1 - r, 4) * (4 * r + 1);
    case Kernel::C4:
      return std::pow(1 - r, 6) * (35 * r * r + 18 * r + 3);
    case Kernel::C6:
      return std::pow(1 - r, 8) * (32 * r * r * r + 25 * r * r + 8 * r + 1);
  }
  return NAN;
}

const Kernel kAll[] = {Kernel::C0, Kernel::C2, Kernel::C4, Kernel::C6};

}  // namespace

TEST(Kernels, ValuesMatchClosedFormsInDoubleAndFloat) {
  for (Kernel k : kAll)
    for (int i = 0; i <= 120; ++i) {
      const double r = i / 100.0;
      EXPECT_NEAR(csrbf::wendland(k, r), closed_form(k, r), 1e-14) << csrbf::kernel_name(k) << " r=" << r;
      EXPECT_NEAR(csrbf::wendland(k, float(r)), float(closed_form(k, r)), 3e-6f) << csrbf::kernel_name(k) << " r=" << r;
    }
}

TEST(Kernels, KnownValues) {
  EXPECT_DOUBLE_EQ(csrbf::wendland(Kernel::C0, 0.5), 0.25);
  EXPECT_DOUBLE_EQ(csrbf::wendland(Kernel::C2, 0.5), 0.0625 * 3.0);
  EXPECT_DOUBLE_EQ(csrbf::wendland(Kernel::C4, 0.0), 3.0);
  EXPECT_DOUBLE_EQ(csrbf::wendland(Kernel::C6, 0.0), 1.0);
  EXPECT_EQ(csrbf::wendland(Kernel::C2, 1.0), 0.0);
  EXPECT_EQ(csrbf::wendland(Kernel::C2, 7.0), 0.0);
  EXPECT_EQ(csrbf::wendland(Kernel::C0, std::nan("")), 0.0);
}

TEST(Kernels, DerivativesMatchFiniteDifferences) {
  for (Kernel k : kAll)
    for (int i = 1; i < 100; ++i) {
      const double r = i / 100.0, h = 1e-6;
      const double fd = (closed_form(k, r + h) - closed_form(k, r - h)) / (2 * h);
      EXPECT_NEAR(csrbf::wendland_derivative(k, r), fd, 1e-7) << csrbf::kernel_name(k) << " r=" << r;
      EXPECT_NEAR(csrbf::wendland_derivative(k, float(r)), float(fd), 2e-5f) << csrbf::kernel_name(k) << " r=" << r;
    }
}

TEST(Kernels, DerivativeClosedFormsAndEnds) {
  EXPECT_DOUBLE_EQ(csrbf::wendland_derivative(Kernel::C0, 0.25), -1.5);
  EXPECT_DOUBLE_EQ(csrbf::wendland_derivative(Kernel::C2, 0.5), -20 * 0.5 * 0.125);
  for (Kernel k : {Kernel::C2, Kernel::C4, Kernel::C6}) EXPECT_EQ(csrbf::wendland_derivative(k, 0.0), 0.0);
  for (Kernel k : kAll) {
    EXPECT_EQ(csrbf::wendland_derivative(k, 1.0), 0.0);
    EXPECT_EQ(csrbf::wendland_derivative(k, 2.0), 0.0);
    EXPECT_NEAR(csrbf::wendland_derivative(k, 1.0 - 1e-9), 0.0, 1e-8);  // continuous at the support's edge
  }
}

TEST(Kernels, Names) {
  for (Kernel k : kAll) EXPECT_EQ(csrbf::parse_kernel(csrbf::kernel_name(k)), k);
  EXPECT_EQ(csrbf::parse_kernel("PSI31"), Kernel::C2);
  EXPECT_FALSE(csrbf::parse_kernel("c3").has_value());
  EXPECT_EQ(csrbf::kernel_smoothness(Kernel::C6), 6);
}
