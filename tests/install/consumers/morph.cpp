// csrbf::morph: a motion file and a small OpenFOAM-free mesh, morphed in memory. Without
// csrbf::morph_formats, a .vtk is refused with a message naming that target.
#include <csrbf/io/error.hpp>
#include <csrbf/morph/morph.hpp>
#include <csrbf/morph/volume_file.hpp>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

int main() {
  csrbf::morph::VolumeMesh mesh;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) mesh.points.emplace_back(0.5 * i, 0.5 * j, 0.5 * k);
  csrbf::morph::Patch bottom{"bottom", "wall", {}}, top{"top", "wall", {}};
  for (std::uint32_t p = 0; p < 9; ++p) bottom.points.push_back(p);
  for (std::uint32_t p = 18; p < 27; ++p) top.points.push_back(p);
  mesh.patches = {bottom, top};
  const auto path = std::filesystem::temp_directory_path() / "csrbf-consumer-motion.json";
  std::ofstream(path) << R"({"radius": 1.2, "patches": {"bottom": {"translate": [0, 0, 0.1]}, "top": "fixed"}})";
  const auto motion = csrbf::morph::read_motion(path);
  std::filesystem::remove(path);
  csrbf::morph::MorphOptions o;
  o.fit.radius = *motion.radius;
  const auto r = csrbf::morph::morph(mesh, motion, o);
  const double middle = r.points[13].z() - mesh.points[13].z();  // the centre point moved up, less than the bottom
  bool refused = false;
  try {
    csrbf::morph::open_volume("mesh.vtk");
  } catch (const csrbf::io::FileError& e) {
    refused = std::string(e.what()).find("csrbf::morph_formats") != std::string::npos;
  }
  const bool ok = r.points[0].z() == 0.1 && r.points[26] == mesh.points[26] && middle > 0 && middle < 0.1 && refused;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
