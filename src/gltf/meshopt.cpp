#include "csrbf/gltf/meshopt.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/gltf/detail/meshopt_compress.hpp"
#include "csrbf/gltf/glb.hpp"

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>

namespace csrbf::gltf {

using json = nlohmann::json;

namespace {

const char* mode_name(MeshoptView::Mode m) {
  return m == MeshoptView::Mode::Attributes  ? "ATTRIBUTES"
         : m == MeshoptView::Mode::Triangles ? "TRIANGLES"
                                             : "INDICES";
}

std::vector<std::uint32_t> indices_of(const unsigned char* p, std::size_t count, std::size_t size) {
  std::vector<std::uint32_t> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (size == 2) {
      std::uint16_t v;
      std::memcpy(&v, p + 2 * i, 2);
      out[i] = v;
    } else {
      std::memcpy(&out[i], p + 4 * i, 4);
    }
  }
  return out;
}

/// Decodes count elements of stride bytes from data in mode into out; false where they do not decode.
bool decode(MeshoptView::Mode mode, std::size_t count, std::size_t stride, const unsigned char* data,
            std::size_t length, unsigned char* out) {
  switch (mode) {
    case MeshoptView::Mode::Attributes:
      return meshopt_decodeVertexBuffer(out, count, stride, data, length) == 0;
    case MeshoptView::Mode::Triangles:
      return meshopt_decodeIndexBuffer(out, count, stride, data, length) == 0;
    case MeshoptView::Mode::Indices:
      return meshopt_decodeIndexSequence(out, count, stride, data, length) == 0;
    default:
      return false;
  }
}

}  // namespace

void meshopt_compress(json& doc, std::vector<unsigned char>& bin, const std::vector<MeshoptView>& views) {
  // The codec versions EXT_meshopt_compression specifies: vertex 0, index 1.
  meshopt_encodeVertexVersion(0);
  meshopt_encodeIndexVersion(1);
  std::vector<unsigned char> packed, encoded, check;
  packed.reserve(bin.size());
  std::size_t fallback = 0;
  json& list = doc["bufferViews"];
  for (std::size_t v = 0; v < list.size(); ++v) {
    json& bv = list[v];
    const std::size_t offset = bv["byteOffset"].get<std::size_t>(), length = bv["byteLength"].get<std::size_t>();
    const unsigned char* src = bin.data() + offset;
    const MeshoptView h = v < views.size() ? views[v] : MeshoptView{};
    while (packed.size() % 4) packed.push_back(0);
    const std::size_t count = h.stride ? length / h.stride : 0;
    if (h.mode == MeshoptView::Mode::None || count == 0 || length % h.stride != 0) {
      bv["byteOffset"] = packed.size();
      packed.insert(packed.end(), src, src + length);
      continue;
    }
    std::size_t n = 0;
    std::vector<std::uint32_t> ix;  // index modes: the view's indices, 32-bit
    if (h.mode == MeshoptView::Mode::Attributes) {
      encoded.resize(meshopt_encodeVertexBufferBound(count, h.stride));
      n = meshopt_encodeVertexBuffer(encoded.data(), encoded.size(), src, count, h.stride);
    } else {
      ix = indices_of(src, count, h.stride);
      std::uint32_t most = 0;
      for (const auto i : ix) most = std::max(most, i);
      if (h.mode == MeshoptView::Mode::Triangles) {
        encoded.resize(meshopt_encodeIndexBufferBound(count, std::size_t(most) + 1));
        n = meshopt_encodeIndexBuffer(encoded.data(), encoded.size(), ix.data(), count);
      } else {
        encoded.resize(meshopt_encodeIndexSequenceBound(count, std::size_t(most) + 1));
        n = meshopt_encodeIndexSequence(encoded.data(), encoded.size(), ix.data(), count);
      }
    }
    // Read back before it is written: the decoded bytes must be the view's (the triangle codec may
    // rotate a triangle's three indices, keeping its winding).
    check.assign(length, 0);
    bool same = n > 0 && decode(h.mode, count, h.stride, encoded.data(), n, check.data());
    if (same && h.mode == MeshoptView::Mode::Triangles) {
      const auto& a = ix;
      const auto b = indices_of(check.data(), count, h.stride);
      for (std::size_t t = 0; same && t + 2 < count; t += 3) {
        bool rotated = false;
        for (std::size_t r = 0; r < 3; ++r)
          rotated |= a[t] == b[t + r] && a[t + 1] == b[t + (r + 1) % 3] && a[t + 2] == b[t + (r + 2) % 3];
        same = rotated;
      }
    } else if (same) {
      same = std::memcmp(check.data(), src, length) == 0;
    }
    if (!same)
      throw InvalidInput("export --meshopt: bufferViews[" + std::to_string(v) + "] (" + mode_name(h.mode) +
                         ") did not decode to its own bytes");
    json ext = {{"buffer", 0},    {"byteOffset", packed.size()}, {"byteLength", n}, {"byteStride", h.stride},
                {"count", count}, {"mode", mode_name(h.mode)}};
    packed.insert(packed.end(), encoded.begin(), encoded.begin() + std::ptrdiff_t(n));
    // The view itself lies in the fallback buffer, which holds no data.
    while (fallback % 4) ++fallback;
    bv["buffer"] = 1;
    bv["byteOffset"] = fallback;
    fallback += length;
    bv["extensions"]["EXT_meshopt_compression"] = std::move(ext);
  }
  while (packed.size() % 4) packed.push_back(0);
  while (fallback % 4) ++fallback;
  bin = std::move(packed);
  doc["buffers"] = json::array(
      {json{{"byteLength", bin.size()}}, json{{"byteLength", std::max<std::size_t>(fallback, 4)},
                                              {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}});
  doc["extensionsUsed"].push_back("EXT_meshopt_compression");
  doc["extensionsRequired"].push_back("EXT_meshopt_compression");
}

std::vector<unsigned char> gltf_without_meshopt(const std::vector<unsigned char>& glb) {
  // A header or JSON that does not read is returned as it is: its reader names what is wrong.
  GlbChunks chunks;
  try {
    chunks = split_glb(glb, false);
  } catch (const InvalidInput&) {
    return glb;
  }
  json doc = json::parse(chunks.json.begin(), chunks.json.end(), nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) return glb;
  const auto& used =
      doc.contains("extensionsUsed") && doc["extensionsUsed"].is_array() ? doc["extensionsUsed"] : json();
  if (used.is_null() || std::find(used.begin(), used.end(), "EXT_meshopt_compression") == used.end()) return glb;
  if (!chunks.has_bin) throw InvalidInput("glTF: the glb's second chunk is not a binary chunk within the file");
  const unsigned char* bin = chunks.bin.data();
  const std::size_t bin_length = chunks.bin.size();
  std::vector<unsigned char> out;
  try {
    json& list = doc.at("bufferViews");
    for (std::size_t v = 0; v < list.size(); ++v) {
      json& bv = list.at(v);
      const std::string where = "bufferViews[" + std::to_string(v) + "]";
      const std::size_t length = bv.at("byteLength").get<std::size_t>();
      while (out.size() % 4) out.push_back(0);
      const std::size_t at = out.size();
      if (bv.contains("extensions") && bv["extensions"].contains("EXT_meshopt_compression")) {
        const json& e = bv["extensions"]["EXT_meshopt_compression"];
        const std::size_t off = e.at("byteOffset").get<std::size_t>(), n = e.at("byteLength").get<std::size_t>();
        const std::size_t stride = e.at("byteStride").get<std::size_t>(), count = e.at("count").get<std::size_t>();
        const std::string m = e.at("mode").get<std::string>();
        if (e.value("buffer", std::size_t(1)) != 0 || off > bin_length || n > bin_length - off)
          throw InvalidInput("glTF: " + where + ": its compressed bytes lie outside the binary chunk");
        if (stride == 0 || stride > 256 || count > (std::size_t(1) << 32) / stride || count * stride != length)
          throw InvalidInput("glTF: " + where + ": count " + std::to_string(count) + " x byteStride " +
                             std::to_string(stride) + " is not its byteLength " + std::to_string(length));
        if (e.contains("filter") && e["filter"] != "NONE")
          throw InvalidInput("glTF: " + where + ": filter " + e["filter"].dump() + " is not read here");
        const MeshoptView::Mode mode = m == "ATTRIBUTES"  ? MeshoptView::Mode::Attributes
                                       : m == "TRIANGLES" ? MeshoptView::Mode::Triangles
                                       : m == "INDICES"   ? MeshoptView::Mode::Indices
                                                          : MeshoptView::Mode::None;
        if (mode == MeshoptView::Mode::None) throw InvalidInput("glTF: " + where + ": mode '" + m + "' is not known");
        if (mode != MeshoptView::Mode::Attributes && stride != 2 && stride != 4)
          throw InvalidInput("glTF: " + where + ": indices of " + std::to_string(stride) + " bytes");
        // EXT_meshopt_compression: ATTRIBUTES elements are a multiple of 4 bytes, TRIANGLES whole
        // triangles (meshoptimizer's decoders assert both).
        if (mode == MeshoptView::Mode::Attributes && stride % 4 != 0)
          throw InvalidInput("glTF: " + where + ": byteStride " + std::to_string(stride) +
                             " of ATTRIBUTES is not a multiple of 4");
        if (mode == MeshoptView::Mode::Triangles && count % 3 != 0)
          throw InvalidInput("glTF: " + where + ": count " + std::to_string(count) +
                             " of TRIANGLES is not a multiple of 3");
        out.resize(at + length);
        if (!decode(mode, count, stride, bin + off, n, out.data() + at))
          throw InvalidInput("glTF: " + where + ": its EXT_meshopt_compression data does not decode");
        bv["extensions"].erase("EXT_meshopt_compression");
        if (bv["extensions"].empty()) bv.erase("extensions");
      } else {
        const std::size_t off = bv.value("byteOffset", std::size_t(0));
        if (bv.value("buffer", std::size_t(0)) != 0 || off > bin_length || length > bin_length - off)
          throw InvalidInput("glTF: " + where + " lies outside the binary chunk");
        out.insert(out.end(), bin + off, bin + off + length);
      }
      bv["buffer"] = 0;
      bv["byteOffset"] = at;
    }
  } catch (const json::exception& e) {
    throw InvalidInput(std::string("glTF: EXT_meshopt_compression: a value missing or of the wrong type: ") + e.what());
  }
  while (out.size() % 4) out.push_back(0);
  doc["buffers"] = json::array({json{{"byteLength", out.size()}}});
  for (const char* key : {"extensionsUsed", "extensionsRequired"})
    if (doc.contains(key) && doc[key].is_array()) {
      json kept = json::array();
      for (const auto& x : doc[key])
        if (x != "EXT_meshopt_compression") kept.push_back(x);
      doc[key] = kept;
      if (kept.empty()) doc.erase(key);
    }
  std::vector<unsigned char> result = glb_head(doc.dump(), out.size(), "glTF: EXT_meshopt_compression decoded");
  result.insert(result.end(), out.begin(), out.end());
  return result;
}

}  // namespace csrbf::gltf
