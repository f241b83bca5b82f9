// The glb runtime (csrbf/gltf/runtime.hpp) on small files written here: what it refuses before the
// player would fail on it.
#include "csrbf/errors.hpp"
#include "csrbf/gltf/glb.hpp"
#include "csrbf/gltf/runtime.hpp"

#include <gtest/gtest.h>

#include "gltf/glb_of.hpp"

#include <cstring>
#include <string>
#include <vector>

using namespace csrbf;
using namespace csrbf::gltf;

namespace {

using test::glb_of;

/// A triangle with one morph target (36 + 36 bytes) and, where times is given, an animation of its
/// weight at those times (the values follow the times in the buffer).
std::vector<unsigned char> animated_triangle(const std::vector<float>& times) {
  std::vector<float> data = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  const std::size_t t0 = data.size() * 4;
  for (const float t : times) data.push_back(t);
  const std::size_t w0 = data.size() * 4;
  for (std::size_t i = 0; i < times.size(); ++i) data.push_back(float(i));
  std::vector<unsigned char> bin(data.size() * 4);
  std::memcpy(bin.data(), data.data(), bin.size());
  const std::string n = std::to_string(times.size()), tb = std::to_string(t0), wb = std::to_string(w0),
                    len = std::to_string(4 * times.size());
  const std::string json =
      R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":)" + std::to_string(bin.size()) +
      R"(}],"bufferViews":[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":36},)"
      R"({"buffer":0,"byteOffset":)" +
      tb + R"(,"byteLength":)" + len + R"(},{"buffer":0,"byteOffset":)" + wb + R"(,"byteLength":)" + len +
      R"(}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},)"
      R"({"bufferView":1,"componentType":5126,"count":3,"type":"VEC3"},)"
      R"({"bufferView":2,"componentType":5126,"count":)" +
      n + R"(,"type":"SCALAR"},{"bufferView":3,"componentType":5126,"count":)" + n +
      R"(,"type":"SCALAR"}],"meshes":[{"name":"tri","primitives":[{"attributes":{"POSITION":0},)"
      R"("targets":[{"POSITION":1}]}]}],"nodes":[{"mesh":0}],)"
      R"("animations":[{"channels":[{"sampler":0,"target":{"node":0,"path":"weights"}}],)"
      R"("samplers":[{"input":2,"output":3}]}]})";
  return glb_of(json, bin);
}

std::string runtime_refusal(const std::vector<unsigned char>& glb) {
  try {
    GltfRuntime r(glb);
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(GltfRuntime, PlaysTheWeightsChannel) {
  const GltfRuntime r(animated_triangle({0.0f, 1.0f, 2.0f}));
  ASSERT_EQ(r.meshes(), 1u);
  EXPECT_EQ(r.duration(0), 2.0);
  EXPECT_EQ(r.weights(0, 0.5), std::vector<double>{0.5});
  EXPECT_EQ(r.weights(0, 2.0), std::vector<double>{2.0});
  std::vector<Vec3> p, n;
  r.deform(0, std::vector<double>{0.5}, p, n, false);
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[1], Vec3(1, 0, 0.5));
  // An engine's float buffers get the same vertices and normals, rounded to float.
  std::vector<float> fp(9, -1.0f), fn(9, -1.0f);
  r.deform(0, std::vector<float>{0.5f}, fp, fn, false);
  for (std::size_t v = 0; v < 3; ++v)
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(fp[3 * v + std::size_t(c)], float(p[v][c]));
      EXPECT_EQ(fn[3 * v + std::size_t(c)], float(n[v][c]));
    }
  // A buffer of the wrong size is named, and nothing is written.
  std::vector<float> short_buffer(8, -1.0f);
  try {
    r.deform(0, std::vector<float>{0.5f}, short_buffer, fn, false);
    ADD_FAILURE() << "a short positions buffer was taken";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("8 floats of positions"), std::string::npos) << e.what();
  }
  EXPECT_EQ(short_buffer, std::vector<float>(8, -1.0f));
}

TEST(GltfRuntime, RefusesTimesBeforeZero) {
  // csrbf-play-glb read -0.001 as zero frames and -10 as 2^64 frames.
  for (const float first : {-0.001f, -10.0f}) {
    const std::string m = runtime_refusal(animated_triangle({first, 1.0f}));
    EXPECT_NE(m.find("animations[0].samplers[0]: its first time is -"), std::string::npos) << m;
    EXPECT_NE(m.find("times are >= 0"), std::string::npos) << m;
  }
}
