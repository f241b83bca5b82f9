// The name tables (csrbf/names.hpp): one table per option enum, any case, the aliases.
#include "csrbf/names.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

using namespace csrbf;

TEST(Names, OneTablePerEnum) {
  for (const auto& e : NameTable<Kernel>::entries) {
    EXPECT_EQ(parse_name<Kernel>(e.name), e.value);
    EXPECT_EQ(parse_name<Kernel>(e.alias), e.value);
    EXPECT_EQ(kernel_name(e.value), e.name);
  }
  EXPECT_EQ(parse_kernel("PSI31"), Kernel::C2);
  EXPECT_EQ(parse_ordering("Reverse-Cuthill-McKee"), Ordering::ReverseCuthillMcKee);
  EXPECT_EQ(ordering_name(Ordering::BreadthFirst), "breadth-first");
  EXPECT_EQ(parse_solver("CG"), Solver::Cg);
  EXPECT_FALSE(parse_name<Polynomial>("").has_value());  // an empty alias matches nothing
  EXPECT_FALSE(parse_name<Polynomial>("quadratic").has_value());
  EXPECT_EQ(names<Polynomial>(), (std::vector<std::string>{"none", "constant", "linear"}));
  EXPECT_EQ(names_text<Kernel>(), "'c0', 'c2', 'c4' or 'c6'");
  EXPECT_EQ(names_text<Solver>("\""), "\"auto\", \"envelope\", \"eigen\", \"cholmod\" or \"cg\"");
  EXPECT_EQ(table_index(Polynomial::Linear), 2u);
}
