// A box of hexahedra written as CGNS by the tests' own writer (cgnslib, independent of csrbf's
// reader): one unstructured zone; boundary conditions "bottom" (z = 0, a PointList of vertices)
// and "top" (z = max, an ElementRange of QUAD_4 faces at FaceCenter, in family "lid"). The zone
// and the hexahedra are named Zone1 and GridElements, the only names python3-meshio's reader reads.
#pragma once

#include <cgnslib.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace csrbf::test {

/// tets: each hexahedron split into 6 positive tetrahedra (python3-meshio's CGNS reader reads only those).
inline void write_cgns_box(const std::string& path, int n = 4, double h = 0.25, bool single = false,
                           bool tets = false) {
  int fn = 0, base = 0, zone = 0, section = 0, bc = 0, coord = 0;
  const auto ok = [](int r) {
    if (r != CG_OK) throw std::runtime_error(std::string("cgns: ") + cg_get_error());
  };
  ok(cg_open(path.c_str(), CG_MODE_WRITE, &fn));
  ok(cg_base_write(fn, "Base", 3, 3, &base));
  const int np = (n + 1) * (n + 1) * (n + 1);
  const auto P = [n](int i, int j, int k) { return 1 + i + (n + 1) * (j + (n + 1) * k); };
  cgsize_t size[3] = {np, (tets ? 6 : 1) * n * n * n, 0};
  ok(cg_zone_write(fn, base, "Zone1", size, CGNS_ENUMV(Unstructured), &zone));
  std::vector<double> x(static_cast<std::size_t>(np)), y(x.size()), z(x.size());
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const std::size_t p = std::size_t(P(i, j, k) - 1);
        x[p] = i * h;
        y[p] = j * h;
        z[p] = k * h;
      }
  const char* names[3] = {"CoordinateX", "CoordinateY", "CoordinateZ"};
  const std::vector<double>* data[3] = {&x, &y, &z};
  for (int c = 0; c < 3; ++c) {
    if (single) {
      std::vector<float> f(data[c]->begin(), data[c]->end());
      ok(cg_coord_write(fn, base, zone, CGNS_ENUMV(RealSingle), names[c], f.data(), &coord));
    } else {
      ok(cg_coord_write(fn, base, zone, CGNS_ENUMV(RealDouble), names[c], data[c]->data(), &coord));
    }
  }
  std::vector<cgsize_t> hexes;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (const int v : {P(i, j, k), P(i + 1, j, k), P(i + 1, j + 1, k), P(i, j + 1, k), P(i, j, k + 1),
                            P(i + 1, j, k + 1), P(i + 1, j + 1, k + 1), P(i, j + 1, k + 1)})
          hexes.push_back(v);
  cgsize_t cells = n * n * n;
  if (tets) {
    std::vector<cgsize_t> t;
    static const int kuhn[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
    for (std::size_t c = 0; c < hexes.size(); c += 8)
      for (const auto& k : kuhn) {
        cgsize_t v[4] = {hexes[c + std::size_t(k[0])], hexes[c + std::size_t(k[1])], hexes[c + std::size_t(k[2])],
                         hexes[c + std::size_t(k[3])]};
        const auto at = [&](int i, const std::vector<double>& a) { return a[std::size_t(v[i] - 1)]; };
        double e[3][3];
        for (int i = 0; i < 3; ++i) {
          e[i][0] = at(i + 1, x) - at(0, x);
          e[i][1] = at(i + 1, y) - at(0, y);
          e[i][2] = at(i + 1, z) - at(0, z);
        }
        const double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                           e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                           e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
        if (det < 0) std::swap(v[1], v[2]);
        t.insert(t.end(), v, v + 4);
      }
    hexes = t;
    cells = 6 * n * n * n;
    ok(cg_section_write(fn, base, zone, "GridElements", CGNS_ENUMV(TETRA_4), 1, cells, 0, hexes.data(), &section));
  } else {
    ok(cg_section_write(fn, base, zone, "GridElements", CGNS_ENUMV(HEXA_8), 1, cells, 0, hexes.data(), &section));
  }
  std::vector<cgsize_t> lid;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      for (const int v : {P(i, j, n), P(i + 1, j, n), P(i + 1, j + 1, n), P(i, j + 1, n)}) lid.push_back(v);
  const cgsize_t first = cells + 1, last = cells + n * n;
  ok(cg_section_write(fn, base, zone, "Lid", CGNS_ENUMV(QUAD_4), first, last, 0, lid.data(), &section));
  std::vector<cgsize_t> bottom;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) bottom.push_back(P(i, j, 0));
  ok(cg_boco_write(fn, base, zone, "bottom", CGNS_ENUMV(BCWall), CGNS_ENUMV(PointList), cgsize_t(bottom.size()),
                   bottom.data(), &bc));
  const cgsize_t range[2] = {first, last};
  ok(cg_boco_write(fn, base, zone, "top", CGNS_ENUMV(BCWall), CGNS_ENUMV(PointRange), 2, range, &bc));
  ok(cg_boco_gridlocation_write(fn, base, zone, bc, CGNS_ENUMV(FaceCenter)));
  int family = 0;
  ok(cg_family_write(fn, base, "lid", &family));
  ok(cg_goto(fn, base, "Zone_t", zone, "ZoneBC_t", 1, "BC_t", bc, "end"));
  ok(cg_famname_write("lid"));
  ok(cg_close(fn));
}

}  // namespace csrbf::test
