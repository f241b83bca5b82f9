// The exceptions of csrbf (csrbf/errors.hpp): one hierarchy under csrbf::Error, one usage error,
// messages made printable.
#include "csrbf/errors.hpp"
#include "csrbf/space_map.hpp"

#include <gtest/gtest.h>

#include "test_points.hpp"

#include <cmath>
#include <limits>
#include <random>
#include <string>

using namespace csrbf;

TEST(Errors, OneHierarchy) {
  // Every csrbf exception is a csrbf::Error; a resource limit is not bad input.
  const ResourceLimit limit("too big");
  EXPECT_EQ(dynamic_cast<const InvalidInput*>(static_cast<const Error*>(&limit)), nullptr);
  const IllConditioned ill("close");
  EXPECT_NE(dynamic_cast<const InvalidInput*>(static_cast<const Error*>(&ill)), nullptr);
  const NotPositiveDefinite npd(3, -1.0);
  EXPECT_NE(dynamic_cast<const Error*>(&npd), nullptr);
  EXPECT_EQ(npd.row(), 3u);
  // The memory limit raises ResourceLimit from a fit.
  std::mt19937 rng(303);
  const auto s = test::random_points(2000, rng);
  FitOptions o{0.9, Kernel::C2, Polynomial::None};
  o.memory_limit_bytes = 1e6;
  EXPECT_THROW(SpaceMap::fit(s, s, o), ResourceLimit);
}

TEST(Errors, OneUsageErrorIsBadInput) {
  // The programs exit 2 on a UsageError and 1 on any other Error; a usage error is bad input too.
  const UsageError usage("--radius: give a number");
  EXPECT_NE(dynamic_cast<const InvalidInput*>(static_cast<const Error*>(&usage)), nullptr);
  EXPECT_STREQ(usage.what(), "--radius: give a number");
  EXPECT_THROW(throw UsageError("x"), InvalidInput);
  EXPECT_THROW(throw DuplicateSource(1, 4, "same"), InvalidInput);
  EXPECT_THROW(throw DegeneratePolynomial("coplanar"), InvalidInput);
}

TEST(Errors, MessagesArePrintable) {
  // A name from a file cannot drive the terminal, forge a line or end the message early: every
  // control character becomes a JSON-style escape; backslashes and UTF-8 pass unchanged.
  const std::string esc(1, '\x1b'), nul(1, '\0'), del(1, '\x7f');
  EXPECT_EQ(printable("a" + esc + "[2J"), "a\\u001b[2J");
  EXPECT_EQ(printable("x" + nul + "y"), "x\\u0000y");
  EXPECT_EQ(printable("line\nnext"), "line\\u000anext");
  EXPECT_EQ(printable("line\nnext", true), "line\nnext");
  EXPECT_EQ(printable("del" + del), "del\\u007f");
  EXPECT_EQ(printable("a\\b"), "a\\b");
  EXPECT_EQ(printable("caf\xc3\xa9"), "caf\xc3\xa9");
  const InvalidInput e("name " + esc + "]0;title" + std::string(1, '\a') + " here");
  EXPECT_EQ(std::string(e.what()), "name \\u001b]0;title\\u0007 here");
  // Idempotent: a message printed again through printable() is the same text.
  EXPECT_EQ(printable(e.what()), std::string(e.what()));
}

TEST(Errors, FactorisationFailuresCarryTheirRow) {
  const NotPositiveDefinite at(7, -2.5);
  EXPECT_EQ(at.row(), 7u);
  EXPECT_EQ(at.pivot(), -2.5);
  const NotPositiveDefinite unknown("CHOLMOD: not positive definite");
  EXPECT_EQ(unknown.row(), std::numeric_limits<std::size_t>::max());
  EXPECT_TRUE(std::isnan(unknown.pivot()));
  const DuplicateSource dup(2, 9, "sources 2 and 9 coincide");
  EXPECT_EQ(dup.first(), 2u);
  EXPECT_EQ(dup.second(), 9u);
}

TEST(Errors, PhaseIsCheckedByName) {
  check_phase(0.0);
  check_phase(-1e6);
  check_phase(1e6);
  EXPECT_THROW(check_phase(std::nan("")), InvalidInput);
  EXPECT_THROW(check_phase(1e6 * 1.000001), InvalidInput);
  EXPECT_THROW(check_phase(std::numeric_limits<double>::infinity()), InvalidInput);
}
