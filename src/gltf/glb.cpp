// The glb container (glb.hpp).
#include "csrbf/gltf/glb.hpp"

#include "csrbf/errors.hpp"

#include <cstring>

namespace csrbf::gltf {

GlbChunks split_glb(std::span<const unsigned char> glb, bool check_bin) {
  const auto u32 = [&](std::size_t at) {
    if (at + 4 > glb.size())
      throw InvalidInput("glTF: the glb ends at byte " + std::to_string(glb.size()) + " inside its header");
    std::uint32_t v;
    std::memcpy(&v, glb.data() + at, 4);
    return std::size_t(v);
  };
  if (u32(0) != kGlbMagic) throw InvalidInput("glTF: not a glb (its first four bytes are not 'glTF')");
  if (u32(4) != 2) throw InvalidInput("glTF: glb version " + std::to_string(u32(4)) + ", expected 2");
  if (u32(8) != glb.size())
    throw InvalidInput("glTF: the glb's header says " + std::to_string(u32(8)) + " bytes, the file has " +
                       std::to_string(glb.size()));
  const std::size_t jl = u32(12);
  if (u32(16) != kGlbJsonChunk || jl > glb.size() - 20)
    throw InvalidInput("glTF: the glb's first chunk is not its JSON");
  GlbChunks out;
  out.json = std::string_view(reinterpret_cast<const char*>(glb.data()) + 20, jl);
  const std::size_t b0 = 20 + jl;
  if (b0 + 8 <= glb.size()) {
    const std::size_t bl = u32(b0);
    if (u32(b0 + 4) != kGlbBinChunk || bl > glb.size() - b0 - 8) {
      if (check_bin) throw InvalidInput("glTF: the glb's second chunk is not a binary chunk within the file");
      return out;
    }
    out.bin = glb.subspan(b0 + 8, bl);
    out.has_bin = true;
  }
  return out;
}

std::vector<unsigned char> glb_head(std::string_view json_text, std::size_t bin_size, const std::string& what) {
  const std::size_t padded = (json_text.size() + 3) / 4 * 4;
  const std::size_t total = 12 + 8 + padded + 8 + bin_size;
  if (total > 0xffffffffu)
    throw InvalidInput(what + ": the glb would be " + std::to_string(total) + " bytes; glTF allows 4 GiB");
  std::vector<unsigned char> head;
  head.reserve(28 + padded);
  const auto u32 = [&](std::size_t x) {
    for (int i = 0; i < 4; ++i) head.push_back((unsigned char)(x >> (8 * i)));
  };
  u32(kGlbMagic);
  u32(2);
  u32(total);
  u32(padded);
  u32(kGlbJsonChunk);
  head.insert(head.end(), json_text.begin(), json_text.end());
  head.resize(head.size() + (padded - json_text.size()), ' ');
  u32(bin_size);
  u32(kGlbBinChunk);
  return head;
}

}  // namespace csrbf::gltf
