#include "csrbf/displacement_field.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace csrbf;

namespace {
template <class T>
void check_playback(double tol) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> s(60), d(60);
  for (std::size_t i = 0; i < s.size(); ++i) {
    s[i] = Vec3(u(rng), u(rng), u(rng));
    d[i] = s[i] + 0.05 * Vec3(u(rng), u(rng), u(rng));
  }
  const SpaceMap map = SpaceMap::fit(s, d, {0.3, Kernel::C2, Polynomial::None});
  std::vector<T> rest(3 * 5000);
  for (auto& x : rest) x = T(u(rng) * 1.2 - 0.1);
  DisplacementField<T> field(map, rest.data(), 5000);
  EXPECT_EQ(field.size(), 5000u);
  std::vector<T> a(rest.size()), b(rest.size());
  for (double t : {0.0, 0.3, 1.0}) {
    field.apply(t, a.data());
    map.apply(rest.data(), b.data(), 5000, t);
    for (std::size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(double(a[i]), double(b[i]), tol) << "t=" << t;
    if (t == 0.0) {
      for (std::size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], rest[i]);
    }
  }
  // New destinations, same sources: update the field.
  std::vector<Vec3> d2 = s;
  const SpaceMap map2 = map.with_destinations(d2);
  field.update(map2);
  field.apply(1.0, a.data());
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(double(a[i]), double(rest[i]), tol);
  const DisplacementField<T> copy = field.clone();
  EXPECT_EQ(copy.displacements().size(), field.displacements().size());
  EXPECT_THROW(field.apply(std::nan(""), a.data()), InvalidInput);
}
}  // namespace

TEST(DisplacementField, PlaybackEqualsApplyDouble) { check_playback<double>(1e-15); }
TEST(DisplacementField, PlaybackEqualsApplyFloat) { check_playback<float>(2e-7); }
