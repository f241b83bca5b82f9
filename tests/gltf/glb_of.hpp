// A whole glb of a JSON chunk and a binary chunk, for the csrbf::gltf tests' hand-written files.
#pragma once

#include "csrbf/gltf/glb.hpp"

#include <string>
#include <vector>

namespace csrbf::test {

inline std::vector<unsigned char> glb_of(const std::string& json, const std::vector<unsigned char>& bin) {
  std::vector<unsigned char> glb = gltf::glb_head(json, bin.size(), "test");
  glb.insert(glb.end(), bin.begin(), bin.end());
  return glb;
}

}  // namespace csrbf::test
