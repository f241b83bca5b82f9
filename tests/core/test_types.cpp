// The core's value types (csrbf/types.hpp): the polygon list.
#include "csrbf/types.hpp"

#include <gtest/gtest.h>

using namespace csrbf;

TEST(Types, PolygonListHoldsFacesInTwoArrays) {
  PolygonList faces{{0, 1, 2}, {2, 1, 3, 4}};
  faces.push_back({4, 5, 6});
  ASSERT_EQ(faces.size(), 3u);
  EXPECT_EQ(faces[1].size(), 4u);
  EXPECT_EQ(faces[1][3], 4u);
  EXPECT_EQ(faces.indices().size(), 10u);
  std::size_t corners = 0;
  for (auto f : faces) corners += f.size();
  EXPECT_EQ(corners, 10u);
  faces[0][0] = 9;
  EXPECT_EQ(faces[0][0], 9u);
  faces.clear();
  EXPECT_TRUE(faces.empty());
}
