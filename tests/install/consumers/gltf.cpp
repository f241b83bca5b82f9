// csrbf::gltf alone, as an engine takes it: a one-triangle glb built in memory with the package's
// glb writer, played back by GltfRuntime. Configured with VTK, MPI and assimp disabled
// (test_install.sh), and ldd-checked there for their libraries.
#include <csrbf/gltf/glb.hpp>
#include <csrbf/gltf/runtime.hpp>

#include <cstring>
#include <iostream>
#include <string>

int main() {
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
  const bool ok = rest.size() == 3 && rest[1].x() == 1.0 && rest[2].y() == 1.0 && !runtime.compact(0);
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
