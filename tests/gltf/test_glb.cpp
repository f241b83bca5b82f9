// The glb container (csrbf/gltf/glb.hpp): what glb_head writes, split_glb reads back, byte for byte
// against glTF 2.0's layout written out by hand here; every malformed header refused by name.
#include "csrbf/errors.hpp"
#include "csrbf/gltf/glb.hpp"

#include <gtest/gtest.h>

#include "gltf/glb_of.hpp"

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

using namespace csrbf;
using namespace csrbf::gltf;

namespace {

using test::glb_of;

std::uint32_t u32_at(const std::vector<unsigned char>& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

std::string message_of(const std::vector<unsigned char>& glb) {
  try {
    split_glb(glb);
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Glb, HeadIsGltf2LayoutWithJsonPaddedBySpaces) {
  const std::string json = R"({"asset":{"version":"2.0"}})";  // 27 bytes: padded to 28
  const std::vector<unsigned char> bin = {1, 2, 3, 4, 5, 6, 7, 8};
  const std::vector<unsigned char> glb = glb_of(json, bin);
  ASSERT_EQ(glb.size(), 12u + 8u + 28u + 8u + 8u);
  EXPECT_EQ(u32_at(glb, 0), 0x46546C67u);  // "glTF"
  EXPECT_EQ(std::string(glb.begin(), glb.begin() + 4), "glTF");
  EXPECT_EQ(u32_at(glb, 4), 2u);
  EXPECT_EQ(u32_at(glb, 8), glb.size());
  EXPECT_EQ(u32_at(glb, 12), 28u);
  EXPECT_EQ(std::string(glb.begin() + 16, glb.begin() + 20), "JSON");
  EXPECT_EQ(std::string(glb.begin() + 20, glb.begin() + 48), json + " ");
  EXPECT_EQ(u32_at(glb, 48), 8u);
  EXPECT_EQ(std::string(glb.begin() + 52, glb.begin() + 56), std::string("BIN\0", 4));
  EXPECT_EQ(std::vector<unsigned char>(glb.begin() + 56, glb.end()), bin);
}

TEST(Glb, SplitReadsBackWhatHeadWrote) {
  const std::string json = R"({"asset":{"version":"2.0"},"x":1234})";  // 36 bytes: no padding
  ASSERT_EQ(json.size() % 4, 0u);
  const std::vector<unsigned char> bin = {9, 8, 7, 6};
  const std::vector<unsigned char> glb = glb_of(json, bin);
  const GlbChunks c = split_glb(glb);
  EXPECT_EQ(c.json, json);
  ASSERT_TRUE(c.has_bin);
  EXPECT_EQ(std::vector<unsigned char>(c.bin.begin(), c.bin.end()), bin);
}

TEST(Glb, NoBinaryChunkIsAllowed) {
  std::vector<unsigned char> glb = glb_of(R"({"a":1})", {});
  glb.resize(glb.size() - 8);  // drop the empty binary chunk's header
  const std::uint32_t n = std::uint32_t(glb.size());
  std::memcpy(glb.data() + 8, &n, 4);
  const GlbChunks c = split_glb(glb);
  EXPECT_FALSE(c.has_bin);
  EXPECT_TRUE(c.bin.empty());
  EXPECT_EQ(c.json, R"({"a":1} )");
}

TEST(Glb, MalformedHeadersAreNamed) {
  const std::vector<unsigned char> good = glb_of(R"({"a":1})", {1, 2, 3, 4});
  EXPECT_EQ(message_of({'g', 'l', 'T'}), "glTF: the glb ends at byte 3 inside its header");
  std::vector<unsigned char> bad = good;
  bad[0] = 'x';
  EXPECT_EQ(message_of(bad), "glTF: not a glb (its first four bytes are not 'glTF')");
  bad = good;
  bad[4] = 1;
  EXPECT_EQ(message_of(bad), "glTF: glb version 1, expected 2");
  bad = good;
  bad.push_back(0);
  EXPECT_EQ(message_of(bad), "glTF: the glb's header says " + std::to_string(good.size()) + " bytes, the file has " +
                                 std::to_string(good.size() + 1));
  bad = good;
  bad[16] = 'j';
  EXPECT_EQ(message_of(bad), "glTF: the glb's first chunk is not its JSON");
  bad = good;
  bad[good.size() - 8] = 'b';  // the binary chunk's type
  EXPECT_EQ(message_of(bad), "glTF: the glb's second chunk is not a binary chunk within the file");
  const GlbChunks lenient = split_glb(bad, false);
  EXPECT_FALSE(lenient.has_bin);  // read leniently: no binary chunk to use
  EXPECT_EQ(lenient.json, R"({"a":1} )");
}

TEST(Glb, ComponentTypesAreGltfsCodes) {
  EXPECT_EQ(code(ComponentType::Byte), 5120u);
  EXPECT_EQ(code(ComponentType::UnsignedByte), 5121u);
  EXPECT_EQ(code(ComponentType::Short), 5122u);
  EXPECT_EQ(code(ComponentType::UnsignedShort), 5123u);
  EXPECT_EQ(code(ComponentType::UnsignedInt), 5125u);
  EXPECT_EQ(code(ComponentType::Float), 5126u);
  EXPECT_EQ(component_size(5120), 1u);
  EXPECT_EQ(component_size(5123), 2u);
  EXPECT_EQ(component_size(5126), 4u);
  EXPECT_EQ(component_size(5124), 0u);  // not a glTF component type
  EXPECT_TRUE(is_unsigned_integer(5125));
  EXPECT_FALSE(is_unsigned_integer(5122));
}
