// The glb container (glTF 2.0 binary) and glTF's accessor component types: one reader and one writer
// of the container for the exporter, the runtime and EXT_meshopt_compression, and the component
// types by name instead of by number.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace csrbf::gltf {

/// accessor.componentType (glTF 2.0, 3.6.2.2).
enum class ComponentType : std::uint32_t {
  Byte = 5120,
  UnsignedByte = 5121,
  Short = 5122,
  UnsignedShort = 5123,
  UnsignedInt = 5125,
  Float = 5126,
};

/// The value glTF's JSON holds for a component type.
constexpr std::uint32_t code(ComponentType t) noexcept { return static_cast<std::uint32_t>(t); }
/// The bytes of one component; 0 where code is not one of glTF's component types.
constexpr std::size_t component_size(std::size_t code) noexcept {
  switch (code) {
    case 5120:
    case 5121:
      return 1;
    case 5122:
    case 5123:
      return 2;
    case 5125:
    case 5126:
      return 4;
    default:
      return 0;
  }
}
/// Whether code is an unsigned integer type (indices: 5121, 5123, 5125).
constexpr bool is_unsigned_integer(std::size_t code) noexcept { return code == 5121 || code == 5123 || code == 5125; }

inline constexpr std::uint32_t kGlbMagic = 0x46546C67u;      ///< "glTF"
inline constexpr std::uint32_t kGlbJsonChunk = 0x4E4F534Au;  ///< "JSON"
inline constexpr std::uint32_t kGlbBinChunk = 0x004E4942u;   ///< "BIN\0"

/// A glb's two chunks, as views into its bytes.
struct GlbChunks {
  std::string_view json;
  std::span<const unsigned char> bin;  ///< empty where the glb has no binary chunk
  /// Whether the glb has a binary chunk within the file. With split_glb's check_bin false, a second
  /// chunk that is not one leaves this false; with check_bin true, it throws.
  bool has_bin = false;
};

/// The chunks of a glb. Throws InvalidInput ("glTF: ...") naming what is wrong: a header cut short, a
/// magic or version that is not glb 2, a length that is not the file's, a first chunk that is not
/// JSON, and (check_bin) a second that is not a binary chunk within the file.
GlbChunks split_glb(std::span<const unsigned char> glb, bool check_bin = true);

/// A glb's bytes up to its binary chunk's data: the header, the JSON chunk (json_text padded with
/// spaces) and the binary chunk's header for bin_size bytes (a multiple of 4). Throws InvalidInput
/// (what: who writes it) where the whole would pass glTF's 4 GiB.
std::vector<unsigned char> glb_head(std::string_view json_text, std::size_t bin_size, const std::string& what);

}  // namespace csrbf::gltf
