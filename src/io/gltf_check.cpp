// The structural check of a glTF 2.0 file before assimp reads it (gltf_check.hpp).
#include "gltf_check.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/gltf/glb.hpp"
#include "text.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace csrbf::io::detail {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// Deeper JSON than this is refused: glTF needs a handful of levels, and assimp's parser recurses
/// (a million levels overflowed its stack).
constexpr int kMaxJsonDepth = 256;
/// Node trees deeper than this are refused (assimp recurses over the node tree).
constexpr std::size_t kMaxNodeDepth = 1000;
/// Bytes a vertex costs once read (positions, normals, colours, texture coordinates, indices).
constexpr double kBytesPerVertex = 64;
/// The component types assimp is given: float positions and normals, unsigned indices.
constexpr std::uint64_t kFloat = gltf::code(gltf::ComponentType::Float),
                        kUnsignedByte = gltf::code(gltf::ComponentType::UnsignedByte),
                        kUnsignedShort = gltf::code(gltf::ComponentType::UnsignedShort),
                        kUnsignedInt = gltf::code(gltf::ComponentType::UnsignedInt);

struct DepthLimit {};

class Checker {
 public:
  Checker(const fs::path& path, const std::string& data, std::string_view bin, const json& j, double max_bytes)
      : path_(path), name_(path.string()), data_(data), bin_(bin), j_(j), max_bytes_(max_bytes) {}

  void run() {
    check_asset();
    check_buffers();
    check_buffer_views();
    check_accessors();
    check_meshes();
    check_nodes();
  }

 private:
  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    throw FileError(name_ + ": glTF " + where + " " + what);
  }
  static std::string shown(const json& v) { return ::csrbf::io::detail::cut(v.dump()); }

  const json& array(const char* key) const {
    static const json none = json::array();
    if (!j_.contains(key)) return none;
    if (!j_[key].is_array()) fail(key, "is not an array");
    return j_[key];
  }
  /// A non-negative integer at obj[key] (def where absent and def >= 0), below `limit`.
  std::uint64_t integer(const json& obj, const char* key, const std::string& where, double limit,
                        std::int64_t def = -1) const {
    if (!obj.contains(key)) {
      if (def < 0) fail(where, std::string("has no ") + key);
      return std::uint64_t(def);
    }
    const json& v = obj[key];
    if (!v.is_number_unsigned() || double(v.get<std::uint64_t>()) >= limit)
      fail(where + "." + key, shown(v) + " is not an integer from 0 to " + format_number(limit - 1));
    return v.get<std::uint64_t>();
  }
  /// An index into the array `of` at obj[key].
  std::size_t index(const json& obj, const char* key, const std::string& where, const char* of) const {
    const std::size_t n = array(of).size();
    if (!obj.contains(key)) fail(where, std::string("has no ") + key);
    const json& v = obj[key];
    if (!v.is_number_unsigned() || v.get<std::uint64_t>() >= n)
      fail(where + "." + key, shown(v) + " is not one of the " + std::to_string(n) + " " + of);
    return v.get<std::size_t>();
  }

  void check_asset() const {
    if (!j_.contains("asset") || !j_["asset"].is_object()) fail("asset", "is missing");
    const json& a = j_["asset"];
    if (!a.contains("version") || !a["version"].is_string() || a["version"].get<std::string>().rfind("2.", 0) != 0)
      fail("asset.version", (a.contains("version") ? shown(a["version"]) : std::string("(missing)")) +
                                " is not 2.x; csrbf reads glTF 2.0");
    if (j_.contains("extensionsRequired")) {
      const json& req = j_["extensionsRequired"];
      if (!req.is_array()) fail("extensionsRequired", "is not an array");
      for (std::size_t k = 0; k < req.size(); ++k) {
        const std::string e = req[k].is_string() ? req[k].get<std::string>() : req[k].dump();
        // Materials and texture transforms change how a mesh looks, not where its vertices are.
        const bool known =
            e.rfind("KHR_materials_", 0) == 0 || e == "KHR_texture_transform" || e == "KHR_lights_punctual";
        if (!known)
          fail("extensionsRequired[" + std::to_string(k) + "]",
               "'" + detail::cut(e) +
                   "' is required by the file and not supported "
                   "(compressed or quantised geometry cannot be read)");
      }
    }
  }

  void check_buffers() {
    const json& buffers = array("buffers");
    double external = 0;
    for (std::size_t k = 0; k < buffers.size(); ++k) {
      const std::string where = "buffers[" + std::to_string(k) + "]";
      const json& b = buffers[k];
      if (!b.is_object()) fail(where, "is not an object");
      const std::uint64_t length = integer(b, "byteLength", where, 1e15);
      double have = 0;
      if (!b.contains("uri")) {
        if (k != 0 || bin_.data() == nullptr)
          fail(where, "has no uri (only a binary glTF's first buffer may use its BIN chunk)");
        have = double(bin_.size());
      } else if (!b["uri"].is_string()) {
        fail(where + ".uri", "is not a string");
      } else {
        const std::string uri = b["uri"].get<std::string>();
        if (uri.rfind("data:", 0) == 0) {
          const auto comma = uri.find(',');
          if (comma == std::string::npos || comma < 12 || uri.compare(comma - 7, 7, ";base64") != 0)
            fail(where + ".uri", "is a data: URI without ';base64,'");
          bytes_.resize(buffers.size());
          bytes_[k] = decode_base64(std::string_view(uri).substr(comma + 1), where + ".uri");
          have = double(bytes_[k].size());
        } else {
          const fs::path file = path_.parent_path() / uri;
          std::error_code ec;
          const auto st = fs::status(file, ec);
          if (ec || st.type() == fs::file_type::not_found)
            fail(where + ".uri", "'" + detail::cut(uri) + "': no such file (" + file.string() + ")");
          if (st.type() != fs::file_type::regular)
            fail(where + ".uri", "'" + detail::cut(uri) + "' is not a regular file");
          have = double(fs::file_size(file, ec));
          external += have;
        }
      }
      if (double(length) > have)
        fail(where + ".byteLength",
             std::to_string(length) + " is more than the " + format_number(have) + " bytes its data holds");
      buffer_length_.push_back(double(length));
    }
    if (external + double(data_.size()) > max_bytes_)
      throw FileError(name_ + ": the glTF and its buffers hold " + format_number(external + double(data_.size())) +
                      " bytes, more than the " + format_number(std::round(max_bytes_)) +
                      " bytes allowed (--memory-limit)");
  }

  /// The bytes of base64 `text` (a data: URI's payload); not valid base64 is refused at `where`.
  std::string decode_base64(std::string_view text, const std::string& where) const {
    std::string out;
    std::uint32_t acc = 0;
    int bits = 0;
    bool padding = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
      const char c = text[i];
      const int v = c >= 'A' && c <= 'Z'   ? c - 'A'
                    : c >= 'a' && c <= 'z' ? c - 'a' + 26
                    : c >= '0' && c <= '9' ? c - '0' + 52
                    : c == '+'             ? 62
                    : c == '/'             ? 63
                                           : -1;
      if (c == '=') {
        padding = true;
        continue;
      }
      if (v < 0 || padding) fail(where, "is not valid base64 at character " + std::to_string(i + 1));
      acc = (acc << 6) | std::uint32_t(v);
      bits += 6;
      if (bits >= 8) {
        bits -= 8;
        out.push_back(char((acc >> bits) & 0xff));
      }
    }
    return out;
  }

  /// The bytes of buffers[k] (checked by check_buffers): the BIN chunk, a data: URI decoded, or the file.
  const std::string& buffer_bytes(std::size_t k) {
    if (bytes_.size() <= k) bytes_.resize(array("buffers").size());
    std::string& out = bytes_[k];
    if (!out.empty()) return out;
    const json& b = array("buffers")[k];
    if (!b.contains("uri"))
      out.assign(bin_.data(), bin_.size());
    else if (const std::string uri = b["uri"].get<std::string>(); uri.rfind("data:", 0) != 0)
      out = read_input(path_.parent_path() / uri, "a glTF buffer", max_bytes_);
    // (a data: URI's bytes were decoded by check_buffers)
    return out;
  }

  /// Every index of a primitive names one of its vertices: assimp dropped faces with an index beyond
  /// them, and crashed on such a line loop.
  void check_indices(std::size_t accessor, double vertices, const std::string& where) {
    const json& a = array("accessors")[accessor];
    if (a.contains("sparse"))
      fail(where + ".indices", "names a sparse accessor; csrbf reads plain index accessors only");
    if (!a.contains("bufferView")) return;  // all zeros
    const std::size_t view = a["bufferView"].get<std::size_t>();
    const json& v = array("bufferViews")[view];
    const std::string& data = buffer_bytes(v["buffer"].get<std::size_t>());
    const int size = component_bytes(component_[accessor]);
    const std::size_t stride = view_stride_[view] > 0 ? std::size_t(view_stride_[view]) : std::size_t(size);
    const std::size_t start =
        std::size_t(v.value("byteOffset", std::uint64_t(0)) + a.value("byteOffset", std::uint64_t(0)));
    const auto count = std::size_t(count_[accessor]);
    for (std::size_t i = 0; i < count; ++i) {
      const std::size_t at = start + i * stride;
      if (at + std::size_t(size) > data.size()) fail(where + ".indices", "runs past the end of its buffer's data");
      std::uint32_t value = 0;
      for (int b = 0; b < size; ++b) value |= std::uint32_t(std::uint8_t(data[at + std::size_t(b)])) << (8 * b);
      if (double(value) >= vertices)
        fail(where + ".indices", "holds " + std::to_string(value) + " at element " + std::to_string(i) +
                                     ", beyond the " + format_number(vertices) + " vertices of its POSITION accessor");
    }
  }

  void check_buffer_views() {
    const json& views = array("bufferViews");
    for (std::size_t k = 0; k < views.size(); ++k) {
      const std::string where = "bufferViews[" + std::to_string(k) + "]";
      const json& v = views[k];
      if (!v.is_object()) fail(where, "is not an object");
      const std::size_t b = index(v, "buffer", where, "buffers");
      const std::uint64_t offset = integer(v, "byteOffset", where, 1e15, 0),
                          length = integer(v, "byteLength", where, 1e15);
      if (double(offset) + double(length) > buffer_length_[b])
        fail(where, "runs to byte " + std::to_string(offset + length) + ", past the " +
                        format_number(buffer_length_[b]) + " bytes of buffers[" + std::to_string(b) + "]");
      const std::uint64_t stride = integer(v, "byteStride", where, 253, 0);
      if (v.contains("byteStride") && (stride < 4 || stride % 4 != 0))
        fail(where + ".byteStride", std::to_string(stride) + " is not a multiple of 4 from 4 to 252");
      view_length_.push_back(double(length));
      view_stride_.push_back(double(stride));
    }
  }

  static int components(const std::string& type) {
    if (type == "SCALAR") return 1;
    if (type == "VEC2") return 2;
    if (type == "VEC3") return 3;
    if (type == "VEC4" || type == "MAT2") return 4;
    if (type == "MAT3") return 9;
    if (type == "MAT4") return 16;
    return 0;
  }
  static int component_bytes(std::uint64_t t) {
    return t > 0xffffffffu ? 0 : int(gltf::component_size(std::size_t(t)));
  }

  /// `count` elements of `bytes` each from byte `offset` of bufferViews[view] fit in it.
  void fits(std::size_t view, double offset, double count, double bytes, const std::string& where) const {
    const double stride = view_stride_[view] > 0 ? view_stride_[view] : bytes;
    if (stride < bytes)
      fail(where, "has elements of " + format_number(bytes) + " bytes, more than bufferViews[" + std::to_string(view) +
                      "].byteStride " + format_number(stride));
    const double end = offset + stride * (count - 1) + bytes;
    if (end > view_length_[view])
      fail(where, "needs bytes up to " + format_number(end) + " of bufferViews[" + std::to_string(view) +
                      "], which holds " + format_number(view_length_[view]));
  }

  void check_accessors() {
    const json& accessors = array("accessors");
    // The smallest element is one byte: a count beyond the bytes of the file and its buffers cannot be real.
    double total = double(data_.size());
    for (double b : buffer_length_) total += b;
    for (std::size_t k = 0; k < accessors.size(); ++k) {
      const std::string where = "accessors[" + std::to_string(k) + "]";
      const json& a = accessors[k];
      if (!a.is_object()) fail(where, "is not an object");
      const std::uint64_t type_code = integer(a, "componentType", where, 1e9);
      const int size = component_bytes(type_code);
      if (size == 0) fail(where + ".componentType", std::to_string(type_code) + " is not a glTF component type");
      const std::string type = a.contains("type") && a["type"].is_string() ? a["type"].get<std::string>() : "";
      const int comps = components(type);
      if (comps == 0)
        fail(where + ".type",
             (a.contains("type") ? shown(a["type"]) : std::string("(missing)")) + " is not a glTF type");
      const std::uint64_t count = integer(a, "count", where, total + 1);
      if (count == 0) fail(where + ".count", "is 0");
      const double element = double(size) * comps;
      if (a.contains("bufferView")) {
        const std::size_t view = index(a, "bufferView", where, "bufferViews");
        fits(view, double(integer(a, "byteOffset", where, 1e15, 0)), double(count), element, where);
      }
      if (a.contains("sparse")) {
        const std::string sw = where + ".sparse";
        const json& s = a["sparse"];
        if (!s.is_object()) fail(sw, "is not an object");
        const std::uint64_t n = integer(s, "count", sw, double(count) + 1);
        if (n == 0) fail(sw + ".count", "is 0");
        for (const char* part : {"indices", "values"}) {
          const std::string pw = sw + "." + part;
          if (!s.contains(part) || !s[part].is_object()) fail(sw, std::string("has no ") + part);
          const json& p = s[part];
          const std::size_t view = index(p, "bufferView", pw, "bufferViews");
          double bytes = element;
          if (std::string(part) == "indices") {
            const std::uint64_t t = integer(p, "componentType", pw, 1e9);
            if (!gltf::is_unsigned_integer(std::size_t(t)))
              fail(pw + ".componentType", std::to_string(t) + " is not an unsigned integer type");
            bytes = component_bytes(t);
          }
          const double offset = double(integer(p, "byteOffset", pw, 1e15, 0));
          if (offset + bytes * double(n) > view_length_[view])
            fail(pw, "needs bytes up to " + format_number(offset + bytes * double(n)) + " of bufferViews[" +
                         std::to_string(view) + "], which holds " + format_number(view_length_[view]));
        }
      }
      count_.push_back(double(count));
      type_.push_back(type);
      component_.push_back(type_code);
    }
  }

  /// The accessor at obj[key] must hold `type` elements of one of `components`.
  std::size_t typed(const json& obj, const char* key, const std::string& where, const char* type,
                    std::initializer_list<std::uint64_t> allowed, const char* what) const {
    const std::size_t k = index(obj, key, where, "accessors");
    bool ok = type_[k] == type;
    bool comp = false;
    for (auto c : allowed) comp = comp || component_[k] == c;
    if (!ok || !comp)
      fail(where + "." + key, "names accessors[" + std::to_string(k) + "] of " + type_[k] + " " +
                                  std::to_string(component_[k]) + "; " + what);
    return k;
  }

  void check_meshes() {
    const json& meshes = array("meshes");
    for (std::size_t m = 0; m < meshes.size(); ++m) {
      const std::string mw = "meshes[" + std::to_string(m) + "]";
      if (!meshes[m].is_object() || !meshes[m].contains("primitives") || !meshes[m]["primitives"].is_array())
        fail(mw, "has no primitives array");
      const json& prims = meshes[m]["primitives"];
      double vertices = 0;
      for (std::size_t p = 0; p < prims.size(); ++p) {
        const json& pr = prims[p];
        const std::string pw = mw + ".primitives[" + std::to_string(p) + "]";
        if (!pr.is_object() || !pr.contains("attributes") || !pr["attributes"].is_object() ||
            !pr["attributes"].contains("POSITION"))
          fail(pw, "has no attributes.POSITION");
        const json& at = pr["attributes"];
        const std::size_t pos =
            typed(at, "POSITION", pw + ".attributes", "VEC3", {kFloat}, "positions are VEC3 of floats (5126)");
        if (at.contains("NORMAL"))
          typed(at, "NORMAL", pw + ".attributes", "VEC3", {kFloat}, "normals are VEC3 of floats (5126)");
        vertices += count_[pos];
        double elements = count_[pos];
        if (pr.contains("indices")) {
          const std::size_t ix = typed(pr, "indices", pw, "SCALAR", {kUnsignedByte, kUnsignedShort, kUnsignedInt},
                                       "indices are SCALAR unsigned integers");
          elements = count_[ix];
          check_indices(ix, count_[pos], pw);
        }
        std::int64_t mode = 4;
        if (pr.contains("mode")) {
          if (!pr["mode"].is_number_integer() || pr["mode"].get<std::int64_t>() < 0 ||
              pr["mode"].get<std::int64_t>() > 6)
            fail(pw + ".mode", shown(pr["mode"]) + " is not 0..6");
          mode = pr["mode"].get<std::int64_t>();
        }
        // points need 1 element, lines and line strips or loops 2, triangles, strips and fans 3.
        const double least = mode == 0 ? 1 : mode <= 3 ? 2 : 3;
        if (elements < least)
          fail(pw, "has " + format_number(elements) + " elements; its mode " + std::to_string(mode) +
                       " needs at least " + format_number(least));
        if (pr.contains("targets")) {
          if (!pr["targets"].is_array()) fail(pw + ".targets", "is not an array");
          for (std::size_t t = 0; t < pr["targets"].size(); ++t) {
            const json& target = pr["targets"][t];
            const std::string tw = pw + ".targets[" + std::to_string(t) + "]";
            if (!target.is_object()) fail(tw, "is not an object");
            if (target.contains("POSITION"))
              typed(target, "POSITION", tw, "VEC3", {kFloat}, "positions are VEC3 of floats (5126)");
          }
        }
      }
      mesh_vertices_.push_back(vertices);
    }
  }

  /// glTF's nodes form trees: no node is the child of two nodes, none its own ancestor. Each tree
  /// is walked without recursion; its depth and the vertices it instances are bounded.
  void check_nodes() {
    const json& nodes = array("nodes");
    std::vector<std::int64_t> parent(nodes.size(), -1);
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      const std::string where = "nodes[" + std::to_string(k) + "]";
      if (!nodes[k].is_object()) fail(where, "is not an object");
      if (nodes[k].contains("mesh")) index(nodes[k], "mesh", where, "meshes");
      // A transform that is not numbers became the identity in assimp, silently.
      for (const auto& [key, count] :
           {std::pair<const char*, std::size_t>{"matrix", 16}, {"translation", 3}, {"rotation", 4}, {"scale", 3}}) {
        if (!nodes[k].contains(key)) continue;
        const json& t = nodes[k][key];
        bool ok = t.is_array() && t.size() == count;
        for (std::size_t i = 0; ok && i < t.size(); ++i) ok = t[i].is_number() && std::isfinite(t[i].get<double>());
        if (!ok) fail(where + "." + key, shown(t) + " is not an array of " + std::to_string(count) + " finite numbers");
      }
      if (!nodes[k].contains("children")) continue;
      const json& children = nodes[k]["children"];
      if (!children.is_array()) fail(where + ".children", "is not an array");
      for (std::size_t c = 0; c < children.size(); ++c) {
        const std::string cw = where + ".children[" + std::to_string(c) + "]";
        if (!children[c].is_number_unsigned() || children[c].get<std::uint64_t>() >= nodes.size())
          fail(cw, shown(children[c]) + " is not one of the " + std::to_string(nodes.size()) + " nodes");
        const std::size_t child = children[c].get<std::size_t>();
        if (parent[child] >= 0 || child == k)
          fail(cw, "makes node " + std::to_string(child) + " the child of " +
                       (child == k ? std::string("itself") : "a second node (" + std::to_string(parent[child]) + ")") +
                       "; glTF's nodes form trees");
        parent[child] = std::int64_t(k);
      }
    }
    // Depth by walking up from every node (each walk bounded by kMaxNodeDepth; a cycle never reaches a root).
    double vertices = 0;
    for (std::size_t k = 0; k < nodes.size(); ++k) {
      std::size_t depth = 0;
      for (std::int64_t p = parent[k]; p >= 0; p = parent[std::size_t(p)])
        if (++depth > kMaxNodeDepth)
          fail("nodes[" + std::to_string(k) + "]",
               "lies more than " + std::to_string(kMaxNodeDepth) + " levels deep, or in a cycle of children");
      if (nodes[k].contains("mesh")) vertices += mesh_vertices_[nodes[k]["mesh"].get<std::size_t>()];
    }
    if (vertices * kBytesPerVertex > max_bytes_)
      throw FileError(name_ + ": the glTF's nodes instance " + format_number(vertices) + " vertices, about " +
                      format_number(std::round(vertices * kBytesPerVertex)) + " bytes, more than the " +
                      format_number(std::round(max_bytes_)) + " bytes allowed (--memory-limit)");
  }

  const fs::path& path_;
  std::string name_;
  const std::string& data_;
  std::string_view bin_;
  const json& j_;
  double max_bytes_;
  std::vector<double> buffer_length_, view_length_, view_stride_, count_, mesh_vertices_;
  std::vector<std::string> type_;
  std::vector<std::uint64_t> component_;
  std::vector<std::string> bytes_;  // buffers' bytes, read when indices are checked
};

}  // namespace

void check_gltf(const fs::path& path, bool binary, double max_bytes) {
  const std::string data = read_input(path, "a mesh", max_bytes);
  const std::string name = path.string();
  std::string_view json_text = data, bin;
  if (binary) {
    // The header and the chunks' lengths: assimp allocates what they claim before reading.
    if (data.size() < 20 || data.compare(0, 4, "glTF") != 0)
      throw FileError(name + ": not a binary glTF (no 'glTF' header of 20 bytes)");
    std::uint32_t version = 0, total = 0, n = 0;
    std::memcpy(&version, data.data() + 4, 4);
    std::memcpy(&total, data.data() + 8, 4);
    std::memcpy(&n, data.data() + 12, 4);
    if (version != 2)
      throw FileError(name + ": binary glTF version " + std::to_string(version) + "; csrbf reads version 2");
    if (total != data.size())
      throw FileError(name + ": the binary glTF header gives a length of " + std::to_string(total) +
                      " bytes, the file has " + std::to_string(data.size()));
    if (n > data.size() - 20 || data.compare(16, 4, "JSON") != 0)
      throw FileError(name + ": the binary glTF's first chunk is not a JSON chunk of " + std::to_string(n) +
                      " bytes within the file");
    json_text = std::string_view(data).substr(20, n);
    for (std::size_t off = 20 + std::size_t(n); off < data.size();) {
      std::uint32_t len = 0;
      if (data.size() - off < 8)
        throw FileError(name + ": a binary glTF chunk header is cut at byte " + std::to_string(off));
      std::memcpy(&len, data.data() + off, 4);
      if (len > data.size() - off - 8)
        throw FileError(name + ": the binary glTF chunk at byte " + std::to_string(off) + " claims " +
                        std::to_string(len) + " bytes, beyond the end of the file");
      if (bin.data() == nullptr && data.compare(off + 4, 4, std::string_view("BIN\0", 4)) == 0)
        bin = std::string_view(data).substr(off + 8, len);
      off += 8 + std::size_t(len);
    }
  }
  json j;
  try {
    j = json::parse(json_text, [](int depth, json::parse_event_t, json&) {
      if (depth > kMaxJsonDepth) throw DepthLimit{};
      return true;
    });
  } catch (const DepthLimit&) {
    throw FileError(name + ": the glTF's JSON nests deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  } catch (const json::exception& e) {
    throw FileError(name + ": the glTF's JSON is not valid: " + cut(e.what()));
  }
  if (!j.is_object()) throw FileError(name + ": the glTF's JSON is not an object");
  Checker(path, data, bin, j, max_bytes).run();
}

}  // namespace csrbf::io::detail
