// Texture files as csrbf checks them before an image library decodes them (csrbf/io/texture.hpp):
// PNGs and JPEGs built here byte by byte, sound and damaged one way at a time, each damage named;
// their sizes from their headers; a scene's texture files each once and what they take decoded.
#include "csrbf/io/texture.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <zlib.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

using namespace csrbf;
using csrbf::test::TempDir;
using csrbf::test::write_text;
using Size = std::pair<std::uint64_t, std::uint64_t>;

namespace {

std::string be32(std::uint32_t v) {
  return {char(v >> 24), char((v >> 16) & 0xFF), char((v >> 8) & 0xFF), char(v & 0xFF)};
}

/// A PNG chunk: length, type, data and the CRC of type and data (zlib's crc32, as PNG's).
std::string chunk(const std::string& type, const std::string& data) {
  const std::string td = type + data;
  const auto crc = std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(td.data()), uInt(td.size())));
  return be32(std::uint32_t(data.size())) + td + be32(crc);
}

std::string deflated(const std::string& raw) {
  uLongf size = compressBound(uLong(raw.size()));
  std::string out(size, '\0');
  EXPECT_EQ(compress(reinterpret_cast<Bytef*>(out.data()), &size, reinterpret_cast<const Bytef*>(raw.data()),
                     uLong(raw.size())),
            Z_OK);
  out.resize(size);
  return out;
}

/// IHDR's data: 8-bit samples, the given colour type (6: RGBA), interlace 0 or 1 (Adam7).
std::string ihdr(std::uint32_t width, std::uint32_t height, int colour = 6, int interlace = 0) {
  return be32(width) + be32(height) + std::string{char(8), char(colour), char(0), char(0), char(interlace)};
}

/// count rows of `bytes` pixel bytes each, every row led by filter type `filter` (0: None). The pixel
/// bytes are 0 to 4, valid filter types themselves: rows of the wrong length are then refused for
/// their count of bytes, wherever the checker takes a row to start.
std::string scanlines(std::size_t count, std::size_t bytes, char filter = 0) {
  std::string raw;
  for (std::size_t y = 0; y < count; ++y) {
    raw += filter;
    for (std::size_t i = 0; i < bytes; ++i) raw += char((i + 2 * y) % 5);
  }
  return raw;
}

const std::string kSignature = "\x89PNG\r\n\x1a\n";

/// A whole PNG of these rows (IHDR, one IDAT, IEND).
std::string png(const std::string& header, const std::string& raw) {
  return kSignature + chunk("IHDR", header) + chunk("IDAT", deflated(raw)) + chunk("IEND", "");
}

/// The 5 x 3 RGBA image: 3 rows of a filter byte and 20 pixel bytes.
std::string png_5x3() { return png(ihdr(5, 3), scanlines(3, 20)); }

/// A JFIF APP0 segment (version 1.1, 1:1 density, no thumbnail): 2 + 16 bytes.
const std::string kApp0("\xFF\xE0\x00\x10JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00", 18);

/// A baseline JPEG's markers around a frame of width x height: SOI, an APP0 (JFIF) segment, SOF0 and,
/// with `ended`, EOI. No scan: csrbf reads the frame and the end marker alone.
std::string jpeg(std::uint16_t width, std::uint16_t height, bool ended = true) {
  std::string j = "\xFF\xD8";
  j += kApp0;
  j += std::string("\xFF\xC0\x00\x11\x08", 5) + char(height >> 8) + char(height & 0xFF) + char(width >> 8) +
       char(width & 0xFF) + std::string("\x03\x01\x22\x00\x02\x11\x01\x03\x11\x01", 10);
  if (ended) j += "\xFF\xD9";
  return j;
}

/// texture_problem of these bytes, written to dir / name.
std::string problem_of(const TempDir& dir, const std::string& bytes, const std::string& name = "t.png") {
  write_text(dir / name, bytes);
  return io::texture_problem(dir / name);
}

bool has(const std::string& text, const std::string& words) { return text.find(words) != std::string::npos; }

}  // namespace

TEST(Texture, ASoundPngHasNoProblemAndItsSizeFromIhdr) {
  const TempDir dir;
  const std::string bytes = png_5x3();
  EXPECT_EQ(problem_of(dir, bytes), "");
  std::string why = "untouched";
  EXPECT_EQ(io::texture_size(dir / "t.png", &why), Size(5, 3));
  EXPECT_EQ(why, "untouched");
  // The same rows in two IDAT chunks are the same image data.
  const std::string z = deflated(scanlines(3, 20));
  const std::string split = kSignature + chunk("IHDR", ihdr(5, 3)) + chunk("IDAT", z.substr(0, 7)) +
                            chunk("IDAT", z.substr(7)) + chunk("tEXt", std::string("Comment\0csrbf", 13)) +
                            chunk("IEND", "");
  EXPECT_EQ(problem_of(dir, split), "");
}

TEST(Texture, APngCutShortAnywhereIsRefused) {
  const TempDir dir;
  const std::string bytes = png_5x3();
  // Shorter than "\x89PNG": not recognised as a PNG at all.
  for (std::size_t n = 0; n < 4; ++n) EXPECT_EQ(problem_of(dir, bytes.substr(0, n)), "it is not a PNG or JPEG image");
  // From the signature on, every length short of the whole file: inside a chunk or past its end.
  for (std::size_t n = 4; n < bytes.size(); ++n) {
    const std::string p = problem_of(dir, bytes.substr(0, n));
    EXPECT_TRUE(has(p, "cut short?")) << n << ": " << p;
  }
  EXPECT_EQ(problem_of(dir, bytes.substr(0, 8)), "it ends inside a chunk at byte 8 (cut short?)");
  EXPECT_EQ(problem_of(dir, bytes.substr(0, 8 + 12 + 5)), "chunk 'IHDR' at byte 8 runs past the end (cut short?)");
  // Cut inside IDAT's data (the signature and IHDR take 8 + 25 = 33 bytes).
  EXPECT_EQ(problem_of(dir, bytes.substr(0, 33 + 12 + 3)), "chunk 'IDAT' at byte 33 runs past the end (cut short?)");
}

TEST(Texture, APngChunkFailingItsCrcIsNamed) {
  const TempDir dir;
  std::string bytes = png_5x3();
  bytes[8 + 8 + 3] = char(6);  // IHDR's width 5 -> 6, its CRC left as it was
  EXPECT_EQ(problem_of(dir, bytes), "chunk 'IHDR' at byte 8 fails its CRC");
  bytes = png_5x3();
  bytes[bytes.size() - 13] ^= 0x01;  // the last byte of IDAT's CRC (IEND's chunk is 12 bytes)
  EXPECT_EQ(problem_of(dir, bytes), "chunk 'IDAT' at byte 33 fails its CRC");
}

TEST(Texture, APngWhoseFirstChunkIsNotIhdrIsRefused) {
  const TempDir dir;
  const std::string raw = scanlines(3, 20);
  const std::string late = kSignature + chunk("tEXt", std::string("Title\0x", 7)) + chunk("IHDR", ihdr(5, 3)) +
                           chunk("IDAT", deflated(raw)) + chunk("IEND", "");
  EXPECT_EQ(problem_of(dir, late), "its first chunk is not IHDR");
  // An IHDR of the wrong length is not one either.
  EXPECT_EQ(
      problem_of(dir, kSignature + chunk("IHDR", ihdr(5, 3) + "x") + chunk("IDAT", deflated(raw)) + chunk("IEND", "")),
      "its first chunk is not IHDR");
  // texture_size reads the header alone (that one's IHDR is in its place), and no PNG without it there.
  std::string why;
  EXPECT_EQ(io::texture_size(dir / "t.png", &why), Size(5, 3));
  EXPECT_EQ(why, "");
  write_text(dir / "late.png", late);
  EXPECT_EQ(io::texture_size(dir / "late.png", &why), Size(0, 0));
  EXPECT_TRUE(has(why, "is not a PNG or JPEG image")) << why;
}

TEST(Texture, APngWithoutIendIsRefusedWhereIendShouldStart) {
  const TempDir dir;
  const std::string whole = png_5x3();
  const std::string no_end = whole.substr(0, whole.size() - 12);  // IEND's chunk is 12 bytes
  EXPECT_EQ(problem_of(dir, no_end),
            "it ends inside a chunk at byte " + std::to_string(no_end.size()) + " (cut short?)");
}

TEST(Texture, APngsImageDataMustInflateToTheRowsIhdrPromises) {
  const TempDir dir;
  // Two rows of three: 2 x 21 bytes where IHDR's 5 x 3 RGBA promises 3 x 21.
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3), scanlines(2, 20))),
            "its image data inflates to 42 bytes where IHDR promises 63");
  // Rows one pixel short each.
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3), scanlines(3, 16))),
            "its image data inflates to 51 bytes where IHDR promises 63");
  // A row too many.
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3), scanlines(4, 20))),
            "its image data holds more than the rows IHDR promises");
  // Image data that is not a zlib stream, its CRC right.
  EXPECT_EQ(
      problem_of(dir, kSignature + chunk("IHDR", ihdr(5, 3)) + chunk("IDAT", "not zlib at all") + chunk("IEND", "")),
      "its image data does not inflate to the end (cut short?)");
  // The zlib stream cut short, its chunk whole.
  const std::string z = deflated(scanlines(3, 20));
  EXPECT_EQ(problem_of(dir, kSignature + chunk("IHDR", ihdr(5, 3)) + chunk("IDAT", z.substr(0, z.size() - 6)) +
                                chunk("IEND", "")),
            "its image data does not inflate to the end (cut short?)");
}

TEST(Texture, APngRowWithABadFilterTypeIsNamed) {
  const TempDir dir;
  for (char filter = 0; filter <= 4; ++filter)
    EXPECT_EQ(problem_of(dir, png(ihdr(5, 3), scanlines(3, 20, filter))), "") << int(filter);
  std::string raw = scanlines(3, 20);
  raw[21] = char(5);  // row 1's filter byte
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3), raw)), "row 1 has filter type 5");
  raw = scanlines(3, 20);
  raw[0] = char(0xFF);
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3), raw)), "row 0 has filter type 255");
}

TEST(Texture, APngHeaderNamingNoImageIsRefused) {
  const TempDir dir;
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3, 5), scanlines(3, 20))),
            "IHDR names colour type 5, bit depth 8, interlace 0");
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3, 6, 2), scanlines(3, 20))),
            "IHDR names colour type 6, bit depth 8, interlace 2");
}

TEST(Texture, AnInterlacedPngHasAdam7sRows) {
  const TempDir dir;
  // Adam7 over 5 x 3: passes 1, 2 and 4 one pixel in one row, pass 3 none (no row 4), pass 5 three
  // pixels in one row, pass 6 two pixels in two rows, pass 7 five pixels in one row. RGBA rows with
  // their filter bytes: 5 + 5 + 5 + 13 + 2 x 9 + 21 = 67 bytes.
  std::string raw =
      scanlines(1, 4) + scanlines(1, 4) + scanlines(1, 4) + scanlines(1, 12) + scanlines(2, 8) + scanlines(1, 20);
  ASSERT_EQ(raw.size(), 67u);
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3, 6, 1), raw)), "");
  EXPECT_EQ(io::texture_size(dir / "t.png"), Size(5, 3));
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3, 6, 1), scanlines(3, 20))),
            "its image data inflates to 63 bytes where IHDR promises 67");
  raw[5 + 5 + 5 + 13] = char(7);  // pass 6's first row (its row 0)
  EXPECT_EQ(problem_of(dir, png(ihdr(5, 3, 6, 1), raw)), "row 0 has filter type 7");
}

TEST(Texture, AJpegsSizeFromItsFrameAndItsEndMarker) {
  const TempDir dir;
  EXPECT_EQ(problem_of(dir, jpeg(640, 3), "t.jpg"), "");
  std::string why;
  EXPECT_EQ(io::texture_size(dir / "t.jpg", &why), Size(640, 3));
  EXPECT_EQ(why, "");
  // Padding after the end marker is allowed.
  EXPECT_EQ(problem_of(dir, jpeg(7, 2) + "\r\n", "t.jpg"), "");
  EXPECT_EQ(io::texture_size(dir / "t.jpg"), Size(7, 2));
  // Without its end-of-image marker it was cut short, though its size is still in its frame.
  const std::string cut = jpeg(7, 2, false);
  EXPECT_EQ(problem_of(dir, cut, "t.jpg"), "it does not end with a JPEG end-of-image marker (cut short?)");
  EXPECT_EQ(io::texture_size(dir / "t.jpg"), Size(7, 2));
  EXPECT_TRUE(has(problem_of(dir, cut + std::string(40, 'x'), "t.jpg"), "end-of-image marker"));
  // Markers without a frame: no size.
  write_text(dir / "frameless.jpg", "\xFF\xD8" + kApp0 + std::string(16, '\0') + "\xFF\xD9");
  EXPECT_EQ(io::texture_size(dir / "frameless.jpg", &why), Size(0, 0));
  EXPECT_TRUE(has(why, "no JPEG frame header")) << why;
  EXPECT_TRUE(has(why, "frameless.jpg")) << why;
}

TEST(Texture, AFileThatIsNeitherHasNoSize) {
  const TempDir dir;
  write_text(dir / "notes.png", "GIF89a: a PNG by name alone\n");
  std::string why;
  EXPECT_EQ(io::texture_size(dir / "notes.png", &why), Size(0, 0));
  EXPECT_EQ(why, "texture file '" + (dir / "notes.png").string() + "' is not a PNG or JPEG image");
  EXPECT_EQ(io::texture_size(dir / "notes.png"), Size(0, 0));  // without a reason asked for
  EXPECT_EQ(io::texture_problem(dir / "notes.png"), "it is not a PNG or JPEG image");
  EXPECT_EQ(io::texture_problem(dir / "absent.png"), "it is not a PNG or JPEG image");
}

TEST(Texture, ASceneNamesEachTextureOnceAndWhatTheyTakeDecoded) {
  const TempDir dir;
  const std::string a = (dir / "a.jpg").string(), b = (dir / "b.png").string(), c = (dir / "c.png").string();
  write_text(a, jpeg(7, 2));
  write_text(b, png_5x3());
  write_text(c, png(ihdr(4, 4), scanlines(4, 16)));
  anim::Scene scene;
  scene.objects.resize(3);
  scene.objects[0].material.texture = c;
  scene.objects[0].parts.resize(3);
  scene.objects[0].parts[0].material.texture = b;
  scene.objects[0].parts[1].material.texture = a;  // parts[2] has none
  scene.objects[1].parts.resize(1);
  scene.objects[1].parts[0].material.texture = b;  // again, in another object
  scene.objects[2].material.texture = a;
  EXPECT_EQ(io::texture_files(scene), (std::vector<std::string>{a, b, c}));
  // 4 bytes a pixel, 2.25 times, each file once: 7 x 2, 5 x 3 and 4 x 4 pixels.
  EXPECT_DOUBLE_EQ(io::decoded_texture_bytes(scene), 4 * 2.25 * (14 + 15 + 16));
  EXPECT_DOUBLE_EQ(io::decoded_texture_bytes(scene, true), 4 * 2.25 * 16);
  // A scene without textures names none and takes nothing.
  anim::Scene plain;
  plain.objects.resize(2);
  plain.objects[1].parts.resize(2);
  EXPECT_TRUE(io::texture_files(plain).empty());
  EXPECT_EQ(io::decoded_texture_bytes(plain), 0.0);
  EXPECT_EQ(io::decoded_texture_bytes(plain, true), 0.0);
}
