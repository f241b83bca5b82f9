// A volume mesh as the morph sees it (csrbf/morph/volume_mesh.hpp): standard cells by their corners,
// polyhedral faces with owners and neighbours, patches found by name, and the box case as the
// OpenFOAM reader fills them (points, faces, cells and sorted boundary patches).
#include "morph_test_helpers.hpp"
#include "csrbf/morph/volume_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

using csrbf::Vec3;
using namespace csrbf::morph;

TEST(VolumeMesh, CellsAreListedByTheirCorners) {
  CellTopology cells;
  EXPECT_EQ(cells.size(), 0u);
  EXPECT_EQ(cells.start, std::vector<std::uint64_t>{0});
  const std::vector<std::uint32_t> tetra{0, 1, 2, 3}, wedge{1, 2, 3, 4, 5, 6};
  cells.add(10, tetra);  // VTK_TETRA
  cells.add(13, wedge);  // VTK_WEDGE
  EXPECT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells.type, (std::vector<std::uint8_t>{10, 13}));
  EXPECT_EQ(cells.start, (std::vector<std::uint64_t>{0, 4, 10}));
  EXPECT_EQ(cells.points, (std::vector<std::uint32_t>{0, 1, 2, 3, 1, 2, 3, 4, 5, 6}));
}

TEST(VolumeMesh, FacesCountOwnersAndInternalFacesByNeighbours) {
  PolyTopology poly;
  EXPECT_EQ(poly.faces(), 0u);
  poly.owner = {0, 0, 1};
  poly.neighbour = {1};
  EXPECT_EQ(poly.faces(), 3u);
  EXPECT_EQ(poly.internal_faces(), 1u);
}

TEST(VolumeMesh, PatchesAreFoundByName) {
  VolumeMesh mesh;
  EXPECT_EQ(mesh.patch("wall"), nullptr);
  mesh.patches.push_back({"inlet", "patch", {0, 1}, {}, 0, 0, true});
  mesh.patches.push_back({"wall", "wall", {2}, {"walls"}, 0, 0, true});
  ASSERT_NE(mesh.patch("wall"), nullptr);
  EXPECT_EQ(mesh.patch("wall"), &mesh.patches[1]);
  EXPECT_EQ(mesh.patch("inlet")->points, (std::vector<std::uint32_t>{0, 1}));
  EXPECT_EQ(mesh.patch("walls"), nullptr);  // a group is no patch name
  EXPECT_EQ(mesh.patch("Wall"), nullptr);
}

TEST_F(BoxMorph, TheReaderFillsTheBoxsTopology) {
  const VolumeMesh& m = c.mesh;
  // 6^3 hexahedra: 7^3 points; 3 x 6 x 6 x 7 faces, of which 3 x 6 x 6 x 5 are internal.
  EXPECT_EQ(m.points.size(), 343u);
  EXPECT_TRUE(m.point_ids.empty());
  EXPECT_EQ(m.poly.cells, 216u);
  EXPECT_EQ(m.poly.faces(), 756u);
  EXPECT_EQ(m.poly.internal_faces(), 540u);
  EXPECT_EQ(m.poly.face_start.size(), m.poly.faces() + 1);
  EXPECT_EQ(m.poly.face_points.size(), 4 * m.poly.faces());
  EXPECT_EQ(m.cells.size(), 0u);  // OpenFOAM's cells are polyhedral
  ASSERT_EQ(m.patches.size(), 6u);
  std::uint64_t next_face = m.poly.internal_faces();
  for (const Patch& p : m.patches) {
    SCOPED_TRACE(p.name);
    EXPECT_TRUE(p.boundary);
    EXPECT_EQ(p.points.size(), 49u);
    EXPECT_TRUE(std::is_sorted(p.points.begin(), p.points.end()));
    EXPECT_EQ(std::adjacent_find(p.points.begin(), p.points.end()), p.points.end());
    EXPECT_EQ(p.face_begin, next_face);  // the boundary faces follow the internal ones, patch by patch
    EXPECT_EQ(p.face_end - p.face_begin, 36u);
    next_face = p.face_end;
  }
  EXPECT_EQ(next_face, m.poly.faces());
  // Each patch holds the points of its side of the unit box.
  for (const std::uint32_t i : m.patch("xmin")->points) EXPECT_EQ(m.points[i].x(), 0.0);
  for (const std::uint32_t i : m.patch("zmax")->points) EXPECT_NEAR(m.points[i].z(), 1.0, 1e-12);
}
