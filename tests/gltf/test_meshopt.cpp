// EXT_meshopt_compression's reader (csrbf/gltf/meshopt.hpp) on small files written here: views
// compressed by the exporter's side decode to their own bytes, a glb without the extension comes
// back as it is, and what meshoptimizer's decoders would assert on or cannot read is refused by name.
#include "csrbf/errors.hpp"
#include "csrbf/gltf/detail/meshopt_compress.hpp"
#include "csrbf/gltf/glb.hpp"
#include "csrbf/gltf/meshopt.hpp"

#include <gtest/gtest.h>

#include "gltf/glb_of.hpp"
#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

using namespace csrbf;
using namespace csrbf::gltf;

namespace {

using test::glb_of;

/// A glb of one EXT_meshopt_compression view of the given mode, count and byteStride over 64 bytes.
std::vector<unsigned char> meshopt_view(const std::string& mode, std::size_t count, std::size_t stride) {
  const std::string json =
      R"({"asset":{"version":"2.0"},"extensionsUsed":["EXT_meshopt_compression"],)"
      R"("extensionsRequired":["EXT_meshopt_compression"],"buffers":[{"byteLength":64},{"byteLength":)" +
      std::to_string(count * stride) +
      R"(,"extensions":{"EXT_meshopt_compression":{"fallback":true}}}],"bufferViews":[{"buffer":1,"byteLength":)" +
      std::to_string(count * stride) +
      R"(,"extensions":{"EXT_meshopt_compression":{"buffer":0,"byteOffset":0,"byteLength":64,"byteStride":)" +
      std::to_string(stride) + R"(,"count":)" + std::to_string(count) + R"(,"mode":")" + mode + R"("}}}]})";
  return glb_of(json, std::vector<unsigned char>(64, 0));
}

std::string refusal(const std::vector<unsigned char>& glb) {
  try {
    gltf_without_meshopt(glb);
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "decoded";
}

template <class T>
void append(std::vector<unsigned char>& bin, const std::vector<T>& values) {
  const std::size_t at = bin.size();
  bin.resize(at + values.size() * sizeof(T));
  std::memcpy(bin.data() + at, values.data(), values.size() * sizeof(T));
}

}  // namespace

TEST(GltfMeshopt, RefusesWhatItsDecodersAssert) {
  // meshoptimizer's decoders assert (abort the process) on both; the extension forbids both.
  for (const std::size_t stride : {1u, 3u, 6u}) {
    try {
      gltf_without_meshopt(meshopt_view("ATTRIBUTES", 4, stride));
      ADD_FAILURE() << "stride " << stride << " accepted";
    } catch (const InvalidInput& e) {
      EXPECT_NE(
          std::string(e.what()).find("byteStride " + std::to_string(stride) + " of ATTRIBUTES is not a multiple of 4"),
          std::string::npos)
          << e.what();
    }
  }
  try {
    gltf_without_meshopt(meshopt_view("TRIANGLES", 4, 2));
    ADD_FAILURE() << "4 triangle indices accepted";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("count 4 of TRIANGLES is not a multiple of 3"), std::string::npos) << e.what();
  }
}

TEST(GltfMeshopt, CompressedViewsDecodeToTheirOwnBytes) {
  // Positions (ATTRIBUTES, 12 bytes), two triangles (TRIANGLES, 16-bit) and an index list
  // (INDICES, 32-bit), compressed as `csrbf export --meshopt` compresses them.
  const std::vector<float> positions{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0.5f};
  const std::vector<std::uint16_t> triangles{0, 1, 2, 2, 1, 3};
  const std::vector<std::uint32_t> indices{3, 0, 2, 1, 3, 3, 0, 1};
  std::vector<unsigned char> bin;
  append(bin, positions);
  append(bin, triangles);
  append(bin, indices);
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}},
                        {"buffers", {{{"byteLength", bin.size()}}}},
                        {"bufferViews",
                         {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 48}},
                          {{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 12}},
                          {{"buffer", 0}, {"byteOffset", 60}, {"byteLength", 32}}}}};
  const std::vector<unsigned char> plain = bin;
  meshopt_compress(
      doc, bin,
      {{MeshoptView::Mode::Attributes, 12}, {MeshoptView::Mode::Triangles, 2}, {MeshoptView::Mode::Indices, 4}});
  EXPECT_EQ(doc["extensionsRequired"], nlohmann::json::array({"EXT_meshopt_compression"}));
  const std::vector<unsigned char> packed = glb_of(doc.dump(), bin);
  const std::vector<unsigned char> decoded = gltf_without_meshopt(packed);
  const GlbChunks chunks = split_glb(decoded);
  const nlohmann::json out = nlohmann::json::parse(chunks.json);
  EXPECT_FALSE(out.contains("extensionsUsed"));
  EXPECT_FALSE(out.contains("extensionsRequired"));
  ASSERT_EQ(out["buffers"].size(), 1u);
  ASSERT_EQ(out["bufferViews"].size(), 3u);
  std::vector<std::size_t> offsets;
  for (const auto& v : out["bufferViews"]) {
    EXPECT_EQ(v["buffer"], 0);
    EXPECT_FALSE(v.contains("extensions"));
    offsets.push_back(v["byteOffset"].get<std::size_t>());
  }
  EXPECT_EQ(offsets, (std::vector<std::size_t>{0, 48, 60}));
  ASSERT_EQ(chunks.bin.size(), 92u);
  EXPECT_EQ(std::memcmp(chunks.bin.data(), plain.data(), 48), 0);            // positions bit for bit
  EXPECT_EQ(std::memcmp(chunks.bin.data() + 60, plain.data() + 60, 32), 0);  // the index list
  // The triangle codec may rotate a triangle's corners, keeping its winding.
  std::uint16_t got[6];
  std::memcpy(got, chunks.bin.data() + 48, 12);
  for (int t = 0; t < 2; ++t) {
    bool rotated = false;
    for (int r = 0; r < 3; ++r)
      rotated |= got[3 * t + r] == triangles[std::size_t(3 * t)] &&
                 got[3 * t + (r + 1) % 3] == triangles[std::size_t(3 * t + 1)] &&
                 got[3 * t + (r + 2) % 3] == triangles[std::size_t(3 * t + 2)];
    EXPECT_TRUE(rotated) << "triangle " << t;
  }
}

TEST(GltfMeshopt, AGlbWithoutTheExtensionIsReturnedAsItIs) {
  const std::vector<unsigned char> glb =
      glb_of(R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":8}],"bufferViews":[{"buffer":0,"byteLength":8}]})",
             {1, 2, 3, 4, 5, 6, 7, 8});
  EXPECT_EQ(gltf_without_meshopt(glb), glb);
  // Not a glb at all: its reader names what is wrong, not this one.
  const std::vector<unsigned char> junk{'n', 'o', 't', ' ', 'a', ' ', 'g', 'l', 'b'};
  EXPECT_EQ(gltf_without_meshopt(junk), junk);
}

TEST(GltfMeshopt, WhatItCannotReadIsNamed) {
  EXPECT_EQ(refusal(meshopt_view("QUADS", 4, 4)), "glTF: bufferViews[0]: mode 'QUADS' is not known");
  EXPECT_EQ(refusal(meshopt_view("INDICES", 4, 3)), "glTF: bufferViews[0]: indices of 3 bytes");
  // 64 zero bytes are no compressed vertex data (its header byte is 0xa0).
  EXPECT_EQ(refusal(meshopt_view("ATTRIBUTES", 4, 4)),
            "glTF: bufferViews[0]: its EXT_meshopt_compression data does not decode");
}
