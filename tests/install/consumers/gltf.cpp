// csrbf::gltf alone, as an engine or a content pipeline takes it: a one-triangle glb built in memory
// with the package's glb writer, played back by GltfRuntime; then a scene built in code (a square
// pulled at a corner by one deformation) exported by the package's exporter, with CSRBF_deformation,
// and played back: the corner at weight 1 is where the control put it. Configured with VTK, MPI and
// assimp disabled (test_install.sh), and ldd-checked there for their libraries.
#include <csrbf/gltf/export.hpp>
#include <csrbf/gltf/glb.hpp>
#include <csrbf/gltf/runtime.hpp>

#include <cmath>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

namespace {

bool plays_a_triangle() {
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::string doc =
      R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],)"
      R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",)"
      R"("min":[0,0,0],"max":[1,1,0]}],"meshes":[{"name":"tri","primitives":[{"attributes":{"POSITION":0}}]}]})";
  std::vector<unsigned char> glb = csrbf::gltf::glb_head(doc, sizeof xyz, "consumer");
  const std::size_t at = glb.size();
  glb.resize(at + sizeof xyz);
  std::memcpy(glb.data() + at, xyz, sizeof xyz);
  const csrbf::gltf::GltfRuntime runtime(glb);
  const auto rest = runtime.rest(runtime.mesh_named("tri"));
  return rest.size() == 3 && rest[1].x() == 1.0 && rest[2].y() == 1.0 && !runtime.compact(0);
}

bool exports_a_pulled_square() {
  using csrbf::Vec3;
  csrbf::anim::Scene scene;
  csrbf::anim::Object square;
  square.name = "square";
  square.rest = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  square.faces = csrbf::PolygonList{{0, 1, 2}, {0, 2, 3}};
  square.finalize();
  csrbf::anim::Part part;
  part.name = "all";
  part.vertices = {0, 1, 2, 3};
  csrbf::anim::Deformation pull;
  pull.name = "pull";
  csrbf::FitOptions fit;
  fit.radius = 0.8;
  const std::vector<Vec3> from = {Vec3(1, 1, 0)}, to = {Vec3(1, 1, 0.25)};
  pull.map = csrbf::SpaceMap::fit(from, to, fit);
  pull.schedule = csrbf::anim::PhaseTrack({{0.0, 0.0}, {1.0, 1.0}}, csrbf::anim::PhaseEasing::Linear);
  part.deformations.push_back(std::move(pull));
  square.parts.push_back(std::move(part));
  scene.objects.push_back(std::move(square));
  csrbf::gltf::GltfOptions options;
  options.compact = csrbf::gltf::Compact::WithFallback;
  csrbf::gltf::GltfReport report;
  const std::vector<unsigned char> glb = csrbf::gltf::gltf_binary(scene, options, report);
  const csrbf::gltf::GltfRuntime runtime(glb);
  const std::size_t mesh = runtime.mesh_named("square");
  std::vector<Vec3> positions, normals;
  const std::vector<double> weights = {1.0};
  runtime.deform(mesh, weights, positions, normals);
  bool corner = false, still = true;
  for (std::size_t v = 0; v < positions.size(); ++v) {
    const Vec3 r = runtime.rest(mesh)[v];
    if ((r - Vec3(1, 1, 0)).norm() < 1e-12)
      corner = std::abs(positions[v].z() - 0.25) < 1e-6;
    else if ((r - Vec3(0, 0, 0)).norm() < 1e-12)
      still = positions[v] == r;  // farther than R from the control: its bits kept
  }
  return runtime.compact(mesh) && report.targets == 1 && corner && still;
}

}  // namespace

int main() {
  const bool ok = plays_a_triangle() && exports_a_pulled_square();
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
