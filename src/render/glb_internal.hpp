// The glb container (glTF 2.0 binary): what csrbf::render writes before the binary chunk.
#pragma once

#include "csrbf/errors.hpp"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace csrbf::render {

/// A glb's bytes up to its binary chunk's data: the header, the JSON chunk (doc, padded with
/// spaces) and the binary chunk's header for bin_size bytes (a multiple of 4). Throws
/// InvalidInput where the whole would pass glTF's 4 GiB.
inline std::vector<unsigned char> glb_head(const nlohmann::json& doc, std::size_t bin_size, const std::string& what) {
  std::string text = doc.dump();
  while (text.size() % 4) text.push_back(' ');
  const std::size_t total = 12 + 8 + text.size() + 8 + bin_size;
  if (total > 0xffffffffu)
    throw InvalidInput(what + ": the glb would be " + std::to_string(total) + " bytes; glTF allows 4 GiB");
  std::vector<unsigned char> head;
  head.reserve(28 + text.size());
  const auto u32 = [&](std::size_t x) {
    for (int i = 0; i < 4; ++i) head.push_back((unsigned char)(x >> (8 * i)));
  };
  u32(0x46546C67);  // "glTF"
  u32(2);
  u32(total);
  u32(text.size());
  u32(0x4E4F534A);  // "JSON"
  head.insert(head.end(), text.begin(), text.end());
  u32(bin_size);
  u32(0x004E4942);  // "BIN\0"
  return head;
}

}  // namespace csrbf::render
