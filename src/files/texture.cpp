// A scene's texture files as csrbf checks them before any image library decodes one (PNG and JPEG
// headers, a PNG's every chunk and its inflated rows, a JPEG's end marker) and what they take
// decoded: part of csrbf::files, so that the glTF exporter (csrbf::gltf) reads textures without the
// mesh readers.
#include "csrbf/io/texture.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <set>

namespace csrbf::io {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kMaxTextureBytes = std::uintmax_t(1) << 30;

std::string read_texture_bytes(const fs::path& file, std::string& bytes) {
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec) return "its size cannot be read (" + ec.message() + ")";
  if (size > kMaxTextureBytes) return std::to_string(size) + " bytes; at most 1 GiB is read";
  std::ifstream in(file, std::ios::binary);
  bytes.assign(std::size_t(size), '\0');
  in.read(bytes.data(), std::streamsize(size));
  if (std::size_t(in.gcount()) != size) return "it could not be read whole";
  return {};
}

/// Every chunk of a PNG whole with its CRC, IHDR first and IEND last, and the image data inflating
/// to exactly the rows IHDR promises, each row with a valid filter type. Empty when sound.
std::string png_problem(const fs::path& file) {
  std::string b;
  if (std::string e = read_texture_bytes(file, b); !e.empty()) return e;
  const auto u32 = [&](std::size_t i) {
    return std::uint32_t(static_cast<unsigned char>(b[i])) << 24 |
           std::uint32_t(static_cast<unsigned char>(b[i + 1])) << 16 |
           std::uint32_t(static_cast<unsigned char>(b[i + 2])) << 8 |
           std::uint32_t(static_cast<unsigned char>(b[i + 3]));
  };
  std::size_t at = 8;
  std::string idat;
  std::uint32_t width = 0, height = 0;
  int depth = 0, colour = 0, interlace = 0;
  bool ended = false;
  while (!ended) {
    if (at + 12 > b.size()) return "it ends inside a chunk at byte " + std::to_string(at) + " (cut short?)";
    const std::uint32_t len = u32(at);
    const std::string type = b.substr(at + 4, 4);
    if (len > b.size() - at - 12)
      return "chunk '" + type + "' at byte " + std::to_string(at) + " runs past the end (cut short?)";
    const auto crc = std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(b.data() + at + 4), uInt(len + 4)));
    if (crc != u32(at + 8 + len)) return "chunk '" + type + "' at byte " + std::to_string(at) + " fails its CRC";
    if (at == 8) {
      if (type != "IHDR" || len != 13) return "its first chunk is not IHDR";
      width = u32(at + 8);
      height = u32(at + 12);
      depth = static_cast<unsigned char>(b[at + 16]);
      colour = static_cast<unsigned char>(b[at + 17]);
      interlace = static_cast<unsigned char>(b[at + 20]);
    } else if (type == "IDAT") {
      idat.append(b, at + 8, len);
    }
    ended = type == "IEND";
    at += 12 + len;
  }
  const int channels = colour == 0 ? 1 : colour == 2 ? 3 : colour == 3 ? 1 : colour == 4 ? 2 : colour == 6 ? 4 : 0;
  if (channels == 0 || (depth != 1 && depth != 2 && depth != 4 && depth != 8 && depth != 16) || interlace > 1)
    return "IHDR names colour type " + std::to_string(colour) + ", bit depth " + std::to_string(depth) +
           ", interlace " + std::to_string(interlace);
  // The rows of each pass (Adam7's seven, or one): (count, bytes a row without the filter byte).
  std::vector<std::pair<std::uint64_t, std::uint64_t>> passes;
  const auto row_bytes = [&](std::uint64_t w) { return (w * std::uint64_t(channels) * std::uint64_t(depth) + 7) / 8; };
  if (interlace == 0) {
    passes.emplace_back(height, row_bytes(width));
  } else {
    const int x0[7] = {0, 4, 0, 2, 0, 1, 0}, y0[7] = {0, 0, 4, 0, 2, 0, 1}, dx[7] = {8, 8, 4, 4, 2, 2, 1},
              dy[7] = {8, 8, 8, 4, 4, 2, 2};
    for (int p = 0; p < 7; ++p) {
      const std::uint64_t pw = width > std::uint32_t(x0[p])
                                   ? (width - std::uint64_t(x0[p]) + std::uint64_t(dx[p]) - 1) / std::uint64_t(dx[p])
                                   : 0;
      const std::uint64_t ph = height > std::uint32_t(y0[p])
                                   ? (height - std::uint64_t(y0[p]) + std::uint64_t(dy[p]) - 1) / std::uint64_t(dy[p])
                                   : 0;
      if (pw > 0 && ph > 0) passes.emplace_back(ph, row_bytes(pw));
    }
  }
  // Inflated in pieces, checking each row's filter byte (0-4) where a row starts.
  z_stream z{};
  if (inflateInit(&z) != Z_OK) return "zlib would not start";
  z.next_in = reinterpret_cast<Bytef*>(idat.data());
  z.avail_in = uInt(idat.size());
  std::vector<unsigned char> piece(1 << 16);
  std::size_t pass = 0;
  std::uint64_t row = 0, in_row = 0, total = 0;  // in_row: bytes of the current row seen, filter byte included
  int rc = Z_OK;
  std::string bad;
  while (rc == Z_OK && bad.empty()) {
    z.next_out = piece.data();
    z.avail_out = uInt(piece.size());
    rc = inflate(&z, Z_NO_FLUSH);
    const std::size_t got = piece.size() - z.avail_out;
    for (std::size_t i = 0; i < got && bad.empty(); ++i, ++total) {
      while (pass < passes.size() && row == passes[pass].first) {
        ++pass;
        row = 0;
      }
      if (pass == passes.size()) {
        bad = "its image data holds more than the rows IHDR promises";
        break;
      }
      if (in_row == 0 && piece[i] > 4)
        bad = "row " + std::to_string(row) + " has filter type " + std::to_string(piece[i]);
      if (++in_row == passes[pass].second + 1) {
        in_row = 0;
        ++row;
      }
    }
    if (rc == Z_BUF_ERROR && z.avail_in == 0) break;
  }
  inflateEnd(&z);
  if (!bad.empty()) return bad;
  if (rc != Z_STREAM_END) return "its image data does not inflate to the end (cut short?)";
  std::uint64_t expected = 0;
  for (const auto& [rows, bytes] : passes) expected += rows * (bytes + 1);
  if (total != expected)
    return "its image data inflates to " + std::to_string(total) + " bytes where IHDR promises " +
           std::to_string(expected);
  return {};
}

/// A JPEG whose last marker is its end of image (FF D9): a file cut short has none. Empty when sound.
std::string jpeg_problem(const fs::path& file) {
  std::string b;
  if (std::string e = read_texture_bytes(file, b); !e.empty()) return e;
  std::size_t end = b.size();
  while (end > 2 && (b[end - 1] == '\0' || b[end - 1] == '\n' || b[end - 1] == '\r')) --end;  // trailing padding
  if (end < 4 || static_cast<unsigned char>(b[end - 2]) != 0xFF || static_cast<unsigned char>(b[end - 1]) != 0xD9)
    return "it does not end with a JPEG end-of-image marker (cut short?)";
  return {};
}

}  // namespace

std::vector<std::string> texture_files(const anim::Scene& scene) {
  std::set<std::string> files;
  for (const auto& o : scene.objects) {
    if (!o.material.texture.empty()) files.insert(o.material.texture);
    for (const auto& p : o.parts)
      if (!p.material.texture.empty()) files.insert(p.material.texture);
  }
  return {files.begin(), files.end()};
}

double decoded_texture_bytes(const anim::Scene& scene, bool largest) {
  double total = 0;
  for (const auto& f : texture_files(scene)) {
    const auto [w, h] = texture_size(f);
    const double bytes = 2.25 * 4.0 * double(w) * double(h);
    total = largest ? std::max(total, bytes) : total + bytes;
  }
  return total;
}

std::pair<std::uint64_t, std::uint64_t> texture_size(const fs::path& file, std::string* why) {
  std::ifstream in(file, std::ios::binary);
  std::string head(1 << 16, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));
  const auto byte = [&](std::size_t i) { return std::uint64_t(static_cast<unsigned char>(head[i])); };
  std::uint64_t w = 0, h = 0;
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return std::pair<std::uint64_t, std::uint64_t>{0, 0};
  };
  if (head.size() >= 24 && head.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0 && head.compare(12, 4, "IHDR") == 0) {
    w = byte(16) << 24 | byte(17) << 16 | byte(18) << 8 | byte(19);
    h = byte(20) << 24 | byte(21) << 16 | byte(22) << 8 | byte(23);
  } else if (head.size() >= 4 && byte(0) == 0xFF && byte(1) == 0xD8) {
    // JPEG: walk the segments to the first start-of-frame marker (C0-CF but C4, C8, CC).
    std::size_t i = 2;
    while (i + 9 < head.size() && byte(i) == 0xFF) {
      if (byte(i + 1) == 0xFF) {  // fill bytes before a marker
        ++i;
        continue;
      }
      const std::uint64_t marker = byte(i + 1);
      const std::size_t len = std::size_t(byte(i + 2) << 8 | byte(i + 3));
      if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
        h = byte(i + 5) << 8 | byte(i + 6);
        w = byte(i + 7) << 8 | byte(i + 8);
        break;
      }
      if (len < 2) break;
      i += 2 + len;
    }
    if (w == 0 || h == 0) return fail("texture file '" + file.string() + "': no JPEG frame header in its first 64 KiB");
  } else {
    return fail("texture file '" + file.string() + "' is not a PNG or JPEG image");
  }
  return {w, h};
}

std::string texture_problem(const fs::path& file) {
  char head[4] = {};
  std::ifstream in(file, std::ios::binary);
  in.read(head, 4);
  if (in.gcount() == 4 && std::memcmp(head, "\x89PNG", 4) == 0) return png_problem(file);
  if (in.gcount() >= 2 && static_cast<unsigned char>(head[0]) == 0xFF && static_cast<unsigned char>(head[1]) == 0xD8)
    return jpeg_problem(file);
  return "it is not a PNG or JPEG image";
}

}  // namespace csrbf::io
