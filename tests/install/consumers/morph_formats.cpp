// csrbf::morph_formats: linking the target registers the VTK, Gmsh and CGNS readers. A legacy .vtk
// of one tetrahedron, written here, is read back through open_volume.
#include <csrbf/morph/volume_file.hpp>

#include <filesystem>
#include <fstream>
#include <iostream>

int main() {
  const auto path = std::filesystem::temp_directory_path() / "csrbf-consumer-tet.vtk";
  std::ofstream(path) << "# vtk DataFile Version 3.0\ntet\nASCII\nDATASET UNSTRUCTURED_GRID\n"
                         "POINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
  const auto file = csrbf::morph::open_volume(path);
  std::filesystem::remove(path);
  const bool ok = file->format() == "vtk" && file->mesh().points.size() == 4 && file->mesh().points[3].z() == 1.0;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
