#include "csrbf/morph/openfoam.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <map>
#include <optional>

namespace fs = std::filesystem;

namespace csrbf::morph {

namespace {

using io::FileError;

std::string quote(std::string_view s) {
  std::string out = "'";
  for (const char c : s.substr(0, 80)) out += (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) ? '?' : c;
  if (s.size() > 80) out += "...";
  return out + "'";
}

/// gzip data inflated, refused past max_bytes (checked as it grows: a small file can claim gigabytes).
std::string gunzip(const std::string& data, const fs::path& file, double max_bytes) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw FileError(file.string() + ": cannot start gzip decompression");
  std::string out;
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  zs.avail_in = uInt(std::min<std::size_t>(data.size(), std::numeric_limits<uInt>::max()));
  std::size_t fed = zs.avail_in;
  int rc = Z_OK;
  for (;;) {
    if (double(out.size()) > max_bytes) {
      inflateEnd(&zs);
      throw FileError(file.string() + ": more than " + std::to_string(std::uint64_t(max_bytes)) +
                      " bytes uncompressed; refused");
    }
    const std::size_t before = out.size();
    out.resize(before + (1u << 20));
    zs.next_out = reinterpret_cast<Bytef*>(out.data() + before);
    zs.avail_out = 1u << 20;
    rc = inflate(&zs, Z_NO_FLUSH);
    out.resize(before + (1u << 20) - zs.avail_out);
    if (zs.avail_in == 0 && fed < data.size()) {
      const std::size_t more = std::min<std::size_t>(data.size() - fed, std::numeric_limits<uInt>::max());
      zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data() + fed));
      zs.avail_in = uInt(more);
      fed += more;
    }
    if (rc == Z_STREAM_END) {
      // Concatenated gzip members (gzip allows them) continue; trailing zeros do not.
      if (zs.avail_in >= 2 && zs.next_in[0] == 0x1f && zs.next_in[1] == 0x8b) {
        inflateReset(&zs);
        continue;
      }
      break;
    }
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      const std::string why = zs.msg ? zs.msg : "corrupt data";
      inflateEnd(&zs);
      throw FileError(file.string() + ": not valid gzip data (" + why + ")");
    }
    if (rc == Z_BUF_ERROR && zs.avail_in == 0) {
      inflateEnd(&zs);
      throw FileError(file.string() + ": truncated gzip data (the compressed stream ends early)");
    }
  }
  inflateEnd(&zs);
  return out;
}

/// data as one gzip member, written as pigz writes it: cut into blocks (1 MiB or more, 64 at most
/// beyond 64 MiB), each deflated on its own in parallel at zlib's fastest level and ended by a
/// sync flush (the last by the stream's end), the blocks' CRC-32s combined. Any gzip reader
/// (OpenFOAM's, zlib's, gzip's) reads it as one stream. The fastest level: a 1e7-point case's points
/// took about 20 s to compress at zlib's default level on one core, longer than the whole morph.
std::string gzip(const std::string& data) {
  const std::size_t block = std::max<std::size_t>(std::size_t(1) << 20, data.size() / 64 + 1);
  const std::size_t blocks = std::max<std::size_t>(1, (data.size() + block - 1) / block);
  std::vector<std::string> parts(blocks);
  std::vector<uLong> crcs(blocks);
  std::vector<int> failed(blocks, 0);
  tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t k) {
    const std::size_t begin = std::min(data.size(), k * block), n = std::min(block, data.size() - begin);
    const auto* in = reinterpret_cast<const Bytef*>(data.data() + begin);
    crcs[k] = crc32(0L, in, uInt(n));
    z_stream zs{};
    if (deflateInit2(&zs, Z_BEST_SPEED, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
      failed[k] = 1;
      return;
    }
    std::string& out = parts[k];
    out.resize(deflateBound(&zs, uLong(n)) + 64);  // room for the sync flush's empty block too
    zs.next_in = const_cast<Bytef*>(in);
    zs.avail_in = uInt(n);
    zs.next_out = reinterpret_cast<Bytef*>(out.data());
    zs.avail_out = uInt(out.size());
    const bool last = k + 1 == blocks;
    const int rc = deflate(&zs, last ? Z_FINISH : Z_SYNC_FLUSH);
    if ((last ? rc != Z_STREAM_END : rc != Z_OK) || zs.avail_in != 0) failed[k] = 1;
    out.resize(out.size() - zs.avail_out);
    deflateEnd(&zs);
  });
  if (std::count(failed.begin(), failed.end(), 1)) throw FileError("gzip compression failed");
  std::string out("\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03", 10);  // deflate, no name, no time, Unix
  uLong crc = crcs[0];
  for (std::size_t k = 0; k < blocks; ++k) {
    out += parts[k];
    if (k > 0) crc = crc32_combine(crc, crcs[k], z_off_t(std::min(block, data.size() - k * block)));
  }
  const std::uint32_t size = std::uint32_t(data.size() & 0xffffffffu);
  for (int b = 0; b < 4; ++b) out += char((crc >> (8 * b)) & 0xff);
  for (int b = 0; b < 4; ++b) out += char((size >> (8 * b)) & 0xff);
  return out;
}

struct Loaded {
  fs::path path;
  bool gz = false;
  std::string text;
};

Loaded load(const fs::path& dir, const std::string& name, double max_bytes) {
  Loaded l;
  std::error_code ec;
  for (const fs::path& p : {dir / name, dir / (name + ".gz")})
    if (fs::exists(p, ec) && !fs::is_regular_file(p, ec))
      throw FileError(p.string() + ": not a regular file (a mesh file is read whole, not from a pipe or device)");
  if (fs::exists(dir / name, ec)) {
    l.path = dir / name;
    l.text = io::read_input(l.path, "an OpenFOAM mesh file", max_bytes);
  } else if (fs::exists(dir / (name + ".gz"), ec)) {
    l.path = dir / (name + ".gz");
    l.gz = true;
    try {
      l.text = gunzip(io::read_input(l.path, "an OpenFOAM mesh file", max_bytes), l.path, max_bytes);
    } catch (const std::bad_alloc&) {
      throw FileError(l.path.string() + ": not enough memory to decompress it (--memory-limit bounds it)");
    }
  } else {
    throw FileError(dir.string() + ": no '" + name + "' or '" + name +
                    ".gz' (an OpenFOAM polyMesh holds points, faces, owner, neighbour and boundary)");
  }
  return l;
}

/// OpenFOAM's tokens over one file's text: words, numbers, punctuation, comments skipped; binary
/// list bodies read as raw bytes. Errors name the file and the line.
class Parser {
 public:
  Parser(const std::string& text, std::string name) : t_(text), name_(std::move(name)) {}

  std::size_t pos = 0;

  [[noreturn]] void fail(const std::string& message) const { fail_at(pos, message); }
  [[noreturn]] void fail_at(std::size_t at, const std::string& message) const {
    const std::size_t line =
        1 + std::size_t(std::count(t_.begin(), t_.begin() + std::ptrdiff_t(std::min(at, t_.size())), '\n'));
    throw FileError(name_ + ":" + std::to_string(line) + ": " + message);
  }
  const std::string& name() const { return name_; }

  void skip() {
    while (pos < t_.size()) {
      const char c = t_[pos];
      if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v') {
        ++pos;
      } else if (c == '/' && pos + 1 < t_.size() && t_[pos + 1] == '/') {
        const auto e = t_.find('\n', pos);
        pos = e == std::string::npos ? t_.size() : e + 1;
      } else if (c == '/' && pos + 1 < t_.size() && t_[pos + 1] == '*') {
        const auto e = t_.find("*/", pos + 2);
        if (e == std::string::npos) fail("a comment '/*' that never ends");
        pos = e + 2;
      } else {
        break;
      }
    }
  }
  bool at_end() {
    skip();
    return pos >= t_.size();
  }
  char peek() {
    skip();
    if (pos >= t_.size()) fail("unexpected end of file (truncated?)");
    return t_[pos];
  }
  /// expect(c, what) with the message built only on failure (per point and per face, a message
  /// built each time cost more than the parse).
  template <class F>
  void expect_lazy(char c, F&& what) {
    if (peek() != c) fail(std::string("expected '") + c + "' " + what() + ", got " + quote(word_at(pos)));
    ++pos;
  }
  void expect(char c, const char* what) {
    if (peek() != c) fail(std::string("expected '") + c + "' " + what + ", got " + quote(word_at(pos)));
    ++pos;
  }
  /// A word: a quoted string, one punctuation character, or a run up to whitespace or punctuation.
  std::string_view word() {
    skip();
    if (pos >= t_.size()) fail("unexpected end of file (truncated?)");
    const std::size_t b = pos;
    if (t_[pos] == '"') {
      const auto e = t_.find('"', pos + 1);
      if (e == std::string::npos) fail("a quoted string that never ends");
      pos = e + 1;
    } else if (is_punct(t_[pos])) {
      ++pos;
    } else {
      while (pos < t_.size() && !is_space(t_[pos]) && !is_punct(t_[pos])) ++pos;
    }
    return std::string_view(t_).substr(b, pos - b);
  }
  std::uint64_t count(const std::string& what, std::uint64_t max) {
    const std::size_t at = (skip(), pos);
    const auto w = word();
    std::uint64_t v = 0;
    const auto r = std::from_chars(w.data(), w.data() + w.size(), v);
    if (r.ec != std::errc() || r.ptr != w.data() + w.size())
      fail_at(at, "expected the number of " + what + ", got " + quote(w));
    if (v > max)
      fail_at(at, std::to_string(v) + " " + what + " cannot fit in the " + std::to_string(t_.size()) +
                      "-byte file (truncated, or a count that lies)");
    return v;
  }
  /// A non-negative integer, parsed directly (the labels of faces, owner and neighbour are most of
  /// a mesh's text); anything else goes through integer() for its message.
  std::uint64_t label(const char* what) {
    while (pos < t_.size() && (t_[pos] == ' ' || t_[pos] == '\n' || t_[pos] == '\t' || t_[pos] == '\r')) ++pos;
    std::size_t i = pos;
    std::uint64_t v = 0;
    while (i < t_.size() && t_[i] >= '0' && t_[i] <= '9' && i - pos < 18) v = v * 10 + std::uint64_t(t_[i++] - '0');
    if (i == pos || (i < t_.size() && !is_space(t_[i]) && !is_punct(t_[i]))) {
      const auto x = integer(what);
      if (x < 0) fail("negative " + std::string(what) + " " + std::to_string(x));
      return std::uint64_t(x);
    }
    pos = i;
    return v;
  }
  double number(const char* what) {
    const std::size_t at = (skip(), pos);
    const auto w = word();
    double v = 0;
    const auto r = std::from_chars(w.data(), w.data() + w.size(), v);
    if (r.ec != std::errc() || r.ptr != w.data() + w.size())
      fail_at(at, std::string("expected ") + what + ", got " + quote(w));
    if (!std::isfinite(v)) fail_at(at, std::string(what) + " " + quote(w) + " is not finite");
    return v;
  }
  std::int64_t integer(const char* what) {
    const std::size_t at = (skip(), pos);
    const auto w = word();
    std::int64_t v = 0;
    const auto r = std::from_chars(w.data(), w.data() + w.size(), v);
    if (r.ec != std::errc() || r.ptr != w.data() + w.size())
      fail_at(at, std::string("expected ") + what + ", got " + quote(w));
    return v;
  }
  /// Raw bytes of a binary list body, which starts right after '('.
  const char* raw(std::size_t bytes, const std::string& what) {
    if (bytes > t_.size() - pos)
      fail(what + " need " + std::to_string(bytes) + " bytes of binary data, but only " +
           std::to_string(t_.size() - pos) + " remain (truncated, or a header that lies)");
    const char* p = t_.data() + pos;
    pos += bytes;
    return p;
  }
  std::size_t remaining() const { return t_.size() - std::min(pos, t_.size()); }

  /// Skips a dictionary entry's value up to and including its ';' (lists and sub-dictionaries nest).
  void skip_value() {
    int depth = 0;
    for (;;) {
      const auto w = word();
      if (w == "(" || w == "{" || w == "[") ++depth;
      if (w == ")" || w == "}" || w == "]") {
        if (depth == 0) fail("unbalanced " + quote(w));
        --depth;
        if (depth == 0 && w == "}") {
          if (peek() != ';') return;  // a sub-dictionary needs no ';'
        }
      }
      if (w == ";" && depth == 0) return;
    }
  }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
  static bool is_punct(char c) {
    return c == '(' || c == ')' || c == '{' || c == '}' || c == ';' || c == '[' || c == ']';
  }
  std::string_view word_at(std::size_t at) const {
    if (at >= t_.size()) return "end of file";
    std::size_t e = at + 1;
    while (e < t_.size() && e < at + 40 && !is_space(t_[e]) && !is_punct(t_[at])) ++e;
    return std::string_view(t_).substr(at, e - at);
  }

  const std::string& t_;
  std::string name_;
};

struct Header {
  std::map<std::string, std::string> entries;
  bool binary = false;
  int label_bytes = 4, scalar_bytes = 8;
  std::string cls;
};

/// FoamFile { version 2.0; format ascii|binary; class ...; arch "LSB;label=32;scalar=64"; ... }
Header read_header(Parser& p) {
  Header h;
  const auto first = p.word();
  if (first != "FoamFile") p.fail("expected the 'FoamFile' header, got " + quote(first) + " (not an OpenFOAM file?)");
  p.expect('{', "after FoamFile");
  for (int n = 0;; ++n) {
    if (n > 64) p.fail("FoamFile header with more than 64 entries");
    if (p.peek() == '}') {
      ++p.pos;
      break;
    }
    const std::string key(p.word());
    std::string value;
    for (;;) {
      const auto w = p.word();
      if (w == ";") break;
      if (w == "{" || w == "}" || w == "(" || w == ")")
        p.fail("unexpected " + quote(w) + " in FoamFile entry " + quote(key));
      if (!value.empty()) value += ' ';
      value += w;
    }
    if (value.size() >= 2 && value.front() == '"' && value.back() == '"') value = value.substr(1, value.size() - 2);
    h.entries[key] = value;
  }
  const auto format = h.entries.find("format");
  if (format == h.entries.end()) p.fail("the FoamFile header has no 'format' (ascii or binary)");
  if (format->second == "binary")
    h.binary = true;
  else if (format->second != "ascii")
    p.fail("FoamFile format " + quote(format->second) + ": expected ascii or binary");
  if (const auto c = h.entries.find("class"); c != h.entries.end()) h.cls = c->second;
  if (const auto a = h.entries.find("arch"); a != h.entries.end()) {
    const std::string& arch = a->second;
    if (arch.find("MSB") != std::string::npos) p.fail("arch " + quote(arch) + ": big-endian binary files are not read");
    for (const auto& [key, bytes] :
         {std::pair<std::string, int*>{"label=", &h.label_bytes}, {"scalar=", &h.scalar_bytes}}) {
      const auto at = arch.find(key);
      if (at == std::string::npos) continue;
      const int bits = std::atoi(arch.c_str() + at + key.size());
      if (bits != 32 && bits != 64)
        p.fail("arch " + quote(arch) + ": " + key + std::to_string(bits) + " is not 32 or 64");
      *bytes = bits / 8;
    }
  }
  return h;
}

/// Labels are kept as 32 bits; faces below 2^31 (the quality measure marks a cell's neighbour faces
/// by the top bit).
constexpr std::uint64_t kNoBound = std::uint64_t(std::numeric_limits<std::uint32_t>::max());
constexpr std::uint64_t kMaxFaces = std::uint64_t(1) << 31;

/// Label i of a binary list of 4- or 8-byte labels (arch "label=32|64").
std::int64_t binary_label(const char* raw, std::uint64_t i, int bytes) {
  if (bytes == 4) {
    std::int32_t x;
    std::memcpy(&x, raw + 4 * i, 4);
    return x;
  }
  std::int64_t v;
  std::memcpy(&v, raw + 8 * i, 8);
  return v;
}

std::vector<std::uint32_t> read_labels(Parser& p, const Header& h, const std::string& what, std::uint64_t bound) {
  const std::size_t min_bytes = h.binary ? std::size_t(h.label_bytes) : 2;
  const std::uint64_t n = p.count(what, p.remaining() / min_bytes + 1);
  std::vector<std::uint32_t> out;
  const auto check = [&](std::int64_t v, std::uint64_t i) -> std::uint32_t {
    if (v < 0 || std::uint64_t(v) >= bound)
      p.fail(what + "[" + std::to_string(i) + "] = " + std::to_string(v) + ": out of range [0, " +
             std::to_string(bound) + ")");
    return std::uint32_t(v);
  };
  if (p.peek() == '{') {  // uniform: N{value}
    ++p.pos;
    const auto v = p.integer("a label");
    p.expect('}', "after a uniform list's value");
    out.assign(n, n ? check(v, 0) : 0);
    return out;
  }
  p.expect('(', ("to open the list of " + what).c_str());
  out.resize(n);
  if (h.binary) {
    const char* raw = p.raw(n * std::size_t(h.label_bytes), std::to_string(n) + " " + what);
    for (std::uint64_t i = 0; i < n; ++i) {
      out[i] = check(binary_label(raw, i, h.label_bytes), i);
    }
  } else {
    for (std::uint64_t i = 0; i < n; ++i)
      out[i] = check(std::int64_t(std::min<std::uint64_t>(p.label("a label"), kNoBound)), i);
  }
  p.expect(')', ("to close the list of " + std::to_string(n) + " " + what + " (more entries than the count?)").c_str());
  return out;
}

void read_points(Parser& p, const Header& h, FoamPointsFile& f, std::vector<Vec3>& pts) {
  if (!h.cls.empty() && h.cls != "vectorField" && h.cls != "pointField")
    p.fail("class " + quote(h.cls) + ": expected vectorField");
  const std::size_t min_bytes = h.binary ? 3 * std::size_t(h.scalar_bytes) : 7;  // "(0 0 0)"
  const std::uint64_t n = p.count("points", std::min<std::uint64_t>(kNoBound, p.remaining() / min_bytes + 1));
  p.expect('(', "to open the list of points");
  f.body_begin = p.pos;
  pts.resize(n);
  if (h.binary) {
    const char* raw = p.raw(n * 3 * std::size_t(h.scalar_bytes), std::to_string(n) + " points");
    for (std::uint64_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        double v;
        if (h.scalar_bytes == 8) {
          std::memcpy(&v, raw + 8 * (3 * i + std::uint64_t(c)), 8);
        } else {
          float x;
          std::memcpy(&x, raw + 4 * (3 * i + std::uint64_t(c)), 4);
          v = x;
        }
        if (!std::isfinite(v)) p.fail("point " + std::to_string(i) + " has a coordinate that is not finite");
        pts[i][c] = v;
      }
  } else {
    for (std::uint64_t i = 0; i < n; ++i) {
      p.expect_lazy('(', [&] { return "to open point " + std::to_string(i); });
      for (int c = 0; c < 3; ++c) pts[i][c] = p.number("a coordinate");
      p.expect_lazy(')', [&] { return "to close point " + std::to_string(i) + " (a point has 3 coordinates)"; });
    }
  }
  p.skip();
  f.body_end = p.pos;
  p.expect(')', ("to close the list of " + std::to_string(n) + " points (more points than the count?)").c_str());
}

void read_faces(Parser& p, const Header& h, PolyTopology& t, std::size_t points) {
  if (h.cls == "faceCompactList") {
    const auto start = read_labels(p, h, "face offsets", kNoBound);
    const auto labels = read_labels(p, h, "face point labels", points);
    if (start.empty()) p.fail("a faceCompactList needs at least one offset");
    if (start.front() != 0 || start.back() != labels.size())
      p.fail("face offsets run from " + std::to_string(start.front()) + " to " + std::to_string(start.back()) +
             ", but there are " + std::to_string(labels.size()) + " point labels");
    for (std::size_t f = 0; f + 1 < start.size(); ++f)
      if (start[f + 1] < start[f] + 3)
        p.fail("face " + std::to_string(f) + " has " +
               std::to_string(std::int64_t(start[f + 1]) - std::int64_t(start[f])) + " points (at least 3)");
    t.face_start.assign(start.begin(), start.end());
    t.face_points = labels;
    return;
  }
  if (!h.cls.empty() && h.cls != "faceList") p.fail("class " + quote(h.cls) + ": expected faceList or faceCompactList");
  const std::uint64_t n = p.count("faces", std::min<std::uint64_t>(kNoBound, p.remaining() / 8 + 1));
  p.expect('(', "to open the list of faces");
  t.face_start.assign(1, 0);
  t.face_start.reserve(n + 1);
  t.face_points.reserve(4 * n);
  for (std::uint64_t f = 0; f < n; ++f) {
    const std::uint64_t k = p.label("the number of points of a face");
    if (k > p.remaining() / (h.binary ? 4 : 2) + 1)
      p.fail("face " + std::to_string(f) + ": " + std::to_string(k) +
             " points cannot fit in the file (truncated, or a count that lies)");
    if (k < 3) p.fail("face " + std::to_string(f) + " has " + std::to_string(k) + " points (at least 3)");
    p.expect_lazy('(', [&] { return "to open face " + std::to_string(f); });
    if (h.binary) {
      const char* raw = p.raw(k * std::size_t(h.label_bytes), "face " + std::to_string(f));
      for (std::uint64_t i = 0; i < k; ++i) {
        const std::int64_t v = binary_label(raw, i, h.label_bytes);
        if (v < 0 || std::uint64_t(v) >= points)
          p.fail("face " + std::to_string(f) + " uses point " + std::to_string(v) + ", but there are " +
                 std::to_string(points) + " points");
        t.face_points.push_back(std::uint32_t(v));
      }
    } else {
      for (std::uint64_t i = 0; i < k; ++i) {
        const std::uint64_t v = p.label("a point label");
        if (v >= points)
          p.fail("face " + std::to_string(f) + " uses point " + std::to_string(v) + ", but there are " +
                 std::to_string(points) + " points");
        t.face_points.push_back(std::uint32_t(v));
      }
    }
    p.expect_lazy(')', [&] { return "to close face " + std::to_string(f) + " (more labels than its count?)"; });
    t.face_start.push_back(t.face_points.size());
  }
  p.expect(')', ("to close the list of " + std::to_string(n) + " faces").c_str());
}

void read_boundary(Parser& p, std::vector<Patch>& patches,
                   std::vector<std::pair<std::uint64_t, std::uint64_t>>& ranges) {
  const std::uint64_t n = p.count("patches", p.remaining() / 4 + 1);
  p.expect('(', "to open the list of patches");
  for (std::uint64_t i = 0; i < n; ++i) {
    Patch patch;
    patch.name = std::string(p.word());
    if (patch.name == ")" || patch.name == "(" || patch.name == "{")
      p.fail("patch " + std::to_string(i) + ": expected a name, got " + quote(patch.name) +
             " (fewer patches than the count?)");
    p.expect('{', ("after patch name " + quote(patch.name)).c_str());
    std::optional<std::int64_t> n_faces, start_face;
    for (;;) {
      if (p.peek() == '}') {
        ++p.pos;
        break;
      }
      const std::string key(p.word());
      if (key == "nFaces" || key == "startFace") {
        const auto v = p.integer(key.c_str());
        if (v < 0) p.fail("patch " + quote(patch.name) + ": " + key + " " + std::to_string(v) + " is negative");
        (key == "nFaces" ? n_faces : start_face) = v;
        p.expect(';', ("after " + key).c_str());
      } else if (key == "type") {
        patch.type = std::string(p.word());
        p.expect(';', "after type");
      } else if (key == "inGroups") {  // inGroups List<word> 2(wall movingWalls);
        int depth = 0;
        for (;;) {
          const std::string w(p.word());
          if (w == "(")
            ++depth;
          else if (w == ")")
            --depth;
          else if (w == ";" && depth == 0)
            break;
          else if (depth == 1)
            patch.groups.push_back(w);
          if (depth < 0 || w == "{" || w == "}" || w == "end of file")
            p.fail("patch " + quote(patch.name) + ": inGroups must be a list of words, e.g. inGroups 1(wall);");
        }
      } else {
        p.skip_value();
      }
    }
    if (!n_faces || !start_face) p.fail("patch " + quote(patch.name) + " has no " + (n_faces ? "startFace" : "nFaces"));
    ranges.emplace_back(std::uint64_t(*start_face), std::uint64_t(*n_faces));
    patches.push_back(std::move(patch));
  }
  p.expect(')', ("to close the list of " + std::to_string(n) + " patches").c_str());
}

fs::path find_poly_mesh(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path / "constant" / "polyMesh", ec)) return path / "constant" / "polyMesh";
  for (const char* f : {"faces", "faces.gz", "owner", "owner.gz"})
    if (fs::exists(path / f, ec)) return path;
  return {};
}

}  // namespace

bool is_openfoam(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec) && !find_poly_mesh(path).empty();
}

std::vector<std::string> foam_times(const fs::path& case_folder) {
  std::vector<std::pair<double, std::string>> times;
  std::error_code ec;
  for (fs::directory_iterator it(case_folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    double v = 0;
    const auto r = std::from_chars(name.data(), name.data() + name.size(), v);
    if (r.ec == std::errc() && r.ptr == name.data() + name.size() && std::isfinite(v) && it->is_directory(ec))
      times.emplace_back(v, name);
  }
  std::sort(times.begin(), times.end());
  std::vector<std::string> out;
  for (auto& t : times) out.push_back(std::move(t.second));
  return out;
}

namespace {

/// The time folder that `time` names (foam_times' spelling), or an error listing the case's times.
std::string find_time(const fs::path& root, const std::string& time) {
  const std::vector<std::string> times = foam_times(root);
  std::string list;
  for (const auto& t : times) list += (list.empty() ? "" : ", ") + t;
  if (list.empty()) list = "none";
  if (time == "latest") {
    if (times.empty()) throw FileError(root.string() + ": -time latest: the case has no time folders");
    return times.back();
  }
  double want = 0;
  const auto r = std::from_chars(time.data(), time.data() + time.size(), want);
  if (r.ec != std::errc() || r.ptr != time.data() + time.size() || !std::isfinite(want))
    throw FileError("-time '" + time + "': expected latest or a time (a number); the case's times: " + list);
  for (const auto& t : times) {
    const double v = std::strtod(t.c_str(), nullptr);
    if (std::abs(v - want) <= 1e-12 * std::max(1.0, std::abs(want))) return t;
  }
  throw FileError(root.string() + ": no time folder " + time + "; the case's times: " + list);
}

bool has_file(const fs::path& dir, const char* name) {
  std::error_code ec;
  return fs::exists(dir / name, ec) || fs::exists(dir / (std::string(name) + ".gz"), ec);
}

}  // namespace

namespace {

// Where read_openfoam's phases find the files, and the files they name in later messages.
struct CaseFiles {
  fs::path points_dir, target_dir;  // where the points are read, and where the moved ones go
  fs::path owner, neighbour;
};

/// The case's folders: its polyMesh, and with a time, the time's folders the files come from.
FoamCase locate_case(const fs::path& path, const std::string& time, CaseFiles& files) {
  std::error_code ec;
  if (!fs::is_directory(path, ec))
    throw FileError(path.string() + ": not a folder (an OpenFOAM case, or its constant/polyMesh, is a folder)");
  FoamCase c;
  c.root = path;
  c.poly_mesh = find_poly_mesh(path);
  if (c.poly_mesh.empty())
    throw FileError(path.string() + ": not an OpenFOAM case: no constant/polyMesh, and no faces or owner file");
  files.points_dir = files.target_dir = c.poly_mesh;
  if (!time.empty()) {
    if (c.poly_mesh != path / "constant" / "polyMesh")
      throw FileError(path.string() +
                      ": -time needs the case folder (holding constant/ and the time folders), "
                      "not a polyMesh folder");
    c.time = find_time(path, time);
    files.target_dir = path / c.time / "polyMesh";
    // As OpenFOAM's findInstance: the points of the latest time up to this one whose polyMesh holds
    // them (a solver writes times without a mesh after a morph wrote one), else constant's; the
    // faces (and their owner, neighbour and boundary) likewise, where the topology changed.
    const std::vector<std::string> times = foam_times(path);
    bool points_found = false, faces_found = false;
    for (auto it = std::find(times.rbegin(), times.rend(), c.time); it != times.rend(); ++it) {
      const fs::path dir = path / *it / "polyMesh";
      if (!points_found && has_file(dir, "points")) files.points_dir = dir, points_found = true;
      if (!faces_found && has_file(dir, "faces")) c.poly_mesh = dir, faces_found = true;
      if (points_found && faces_found) break;
    }
  }
  return c;
}

// The four files are read and parsed at once (a task each; the faces, the largest, first). Each
// task keeps its own error, and the errors are told in the order a serial read meets them:
// points, faces, owner, neighbour, whatever the threads' timing. A face's point labels are
// checked against the points' count when both are read: where one is out of range (or the faces
// failed), the faces are parsed again with the bound, which names the face and its line as the
// serial read did.
void read_mesh_files(FoamCase& c, CaseFiles& files, double max_file_bytes) {
  VolumeMesh& m = c.mesh;
  Loaded faces_file, owner_file, neighbour_file;
  std::uint32_t largest_label = 0;
  std::exception_ptr points_failed, faces_failed, owner_failed, neighbour_failed;
  bool faces_file_error = false;  // a FileError (not out of memory): parsed again to name it
  const auto kept = [](std::exception_ptr& failed, auto&& work) {
    return [&failed, &work] {
      try {
        work();
      } catch (...) {
        failed = std::current_exception();
      }
    };
  };
  const auto read_faces_file = [&] {
    faces_file = load(c.poly_mesh, "faces", max_file_bytes);
    Parser p(faces_file.text, faces_file.path.string());
    try {
      read_faces(p, read_header(p), m.poly, kNoBound);
    } catch (const FileError&) {
      faces_file_error = true;
      throw;
    }
    for (const std::uint32_t v : m.poly.face_points) largest_label = std::max(largest_label, v);
  };
  const auto read_points_file = [&] {
    Loaded l = load(files.points_dir, "points", max_file_bytes);
    Parser p(l.text, l.path.string());
    const Header h = read_header(p);
    c.points_file.path = l.path;
    c.points_file.target = files.target_dir / l.path.filename();
    c.points_file.gzip = l.gz;
    c.points_file.binary = h.binary;
    c.points_file.scalar_bytes = h.scalar_bytes;
    read_points(p, h, c.points_file, m.points);
    c.points_file.text = std::move(l.text);
  };
  const auto read_owner_file = [&] {
    owner_file = load(c.poly_mesh, "owner", max_file_bytes);
    Parser p(owner_file.text, owner_file.path.string());
    m.poly.owner = read_labels(p, read_header(p), "owner cells", kNoBound);
    owner_file.text = std::string();
  };
  const auto read_neighbour_file = [&] {
    neighbour_file = load(c.poly_mesh, "neighbour", max_file_bytes);
    Parser p(neighbour_file.text, neighbour_file.path.string());
    m.poly.neighbour = read_labels(p, read_header(p), "neighbour cells", kNoBound);
    neighbour_file.text = std::string();
  };
  tbb::parallel_invoke(kept(faces_failed, read_faces_file), kept(points_failed, read_points_file),
                       kept(owner_failed, read_owner_file), kept(neighbour_failed, read_neighbour_file));
  if (points_failed) std::rethrow_exception(points_failed);
  const std::size_t np = m.points.size();
  if (faces_failed && !faces_file_error) std::rethrow_exception(faces_failed);
  if (faces_failed || (!m.poly.face_points.empty() && largest_label >= np)) {
    Parser p(faces_file.text, faces_file.path.string());
    PolyTopology again;
    read_faces(p, read_header(p), again, np);  // throws, naming the face
    if (faces_failed) std::rethrow_exception(faces_failed);
  }
  if (owner_failed) std::rethrow_exception(owner_failed);
  if (neighbour_failed) std::rethrow_exception(neighbour_failed);
  files.owner = owner_file.path;
  files.neighbour = neighbour_file.path;
}

/// Owner and neighbour against the faces; the number of cells they name.
void check_cells(FoamCase& c, const CaseFiles& files) {
  VolumeMesh& m = c.mesh;
  const std::size_t nf = m.poly.face_start.size() - 1;
  if (nf >= kMaxFaces)
    throw FileError(c.poly_mesh.string() + ": " + std::to_string(nf) + " faces: more than csrbf reads (2^31)");
  if (m.poly.owner.size() != nf)
    throw FileError(files.owner.string() + ": " + std::to_string(m.poly.owner.size()) + " owner cells, but faces has " +
                    std::to_string(nf) + " faces");
  if (m.poly.neighbour.size() > nf)
    throw FileError(files.neighbour.string() + ": " + std::to_string(m.poly.neighbour.size()) +
                    " neighbour cells, more than the " + std::to_string(nf) + " faces");
  std::uint64_t cells = 0;
  for (const auto o : m.poly.owner) cells = std::max<std::uint64_t>(cells, o + 1ull);
  for (const auto o : m.poly.neighbour) cells = std::max<std::uint64_t>(cells, o + 1ull);
  // A cell has 4 faces or more and a face 2 cells or fewer: more cells than half the faces is a label
  // that lies (and would make every per-cell array that large).
  if (cells > nf / 2)
    throw FileError(c.poly_mesh.string() + ": owner and neighbour name cell " + std::to_string(cells - 1) + ", but " +
                    std::to_string(nf) + " faces make at most " + std::to_string(nf / 2) + " cells");
  {
    std::vector<std::uint32_t> faces_of(cells, 0);
    for (const auto o : m.poly.owner) ++faces_of[o];
    for (const auto o : m.poly.neighbour) ++faces_of[o];
    for (std::uint64_t k = 0; k < cells; ++k)
      if (faces_of[k] < 4)
        throw FileError(c.poly_mesh.string() + ": cell " + std::to_string(k) + " has " + std::to_string(faces_of[k]) +
                        " faces in owner and neighbour (a cell has 4 or more)");
  }
  m.poly.cells = cells;
}

/// The boundary file: the patches, which follow the internal faces and each other, with their points.
void read_patches(FoamCase& c, double max_file_bytes) {
  VolumeMesh& m = c.mesh;
  const std::size_t np = m.points.size();
  const std::size_t nf = m.poly.face_start.size() - 1;
  Loaded l = load(c.poly_mesh, "boundary", max_file_bytes);
  Parser p(l.text, l.path.string());
  read_header(p);
  std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges;
  read_boundary(p, m.patches, ranges);
  std::uint64_t next = m.poly.internal_faces();
  std::vector<std::uint32_t> stamp(np, 0);
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    const auto [start, count] = ranges[i];
    const std::string name = "patch '" + m.patches[i].name + "'";
    if (start + count > nf)
      throw FileError(l.path.string() + ": " + name + ": startFace " + std::to_string(start) + " + nFaces " +
                      std::to_string(count) + " passes the " + std::to_string(nf) + " faces");
    if (start != next)
      throw FileError(l.path.string() + ": " + name + ": startFace " + std::to_string(start) + ", expected " +
                      std::to_string(next) + " (patches follow the internal faces and each other)");
    next = start + count;
    m.patches[i].face_begin = start;
    m.patches[i].face_end = start + count;
    m.patches[i].boundary = m.patches[i].type != "processor" && m.patches[i].type != "processorCyclic";
    // The patch's points, each once (a stamp per point), ascending: sorted when few, else
    // gathered by one pass over the stamps.
    std::vector<std::uint32_t>& pts = m.patches[i].points;
    const auto mark = std::uint32_t(i + 1);
    for (std::uint64_t k = m.poly.face_start[start]; k < m.poly.face_start[start + count]; ++k) {
      const std::uint32_t v = m.poly.face_points[k];
      if (stamp[v] != mark) {
        stamp[v] = mark;
        pts.push_back(v);
      }
    }
    if (pts.size() > np / 8) {
      pts.clear();
      for (std::uint32_t v = 0; v < np; ++v)
        if (stamp[v] == mark) pts.push_back(v);
    } else {
      std::sort(pts.begin(), pts.end());
    }
  }
  if (next != nf)
    throw FileError(l.path.string() + ": the patches end at face " + std::to_string(next) + ", but there are " +
                    std::to_string(nf) + " faces (" + std::to_string(m.poly.internal_faces()) + " internal)");
}

// A processor folder of a decomposed case (decomposePar): its points are numbered as in the whole
// mesh (pointProcAddressing), which displacement files and messages use.
void read_point_addressing(FoamCase& c, double max_file_bytes) {
  VolumeMesh& m = c.mesh;
  const std::size_t np = m.points.size();
  std::error_code ec;
  if (!fs::exists(c.poly_mesh / "pointProcAddressing", ec) && !fs::exists(c.poly_mesh / "pointProcAddressing.gz", ec))
    return;
  Loaded l = load(c.poly_mesh, "pointProcAddressing", max_file_bytes);
  Parser p(l.text, l.path.string());
  const std::vector<std::uint32_t> global = read_labels(p, read_header(p), "point labels", kNoBound);
  if (global.size() != np)
    throw FileError(l.path.string() + ": " + std::to_string(global.size()) + " point labels, but points has " +
                    std::to_string(np) + " points");
  std::vector<std::uint32_t> sorted(global);
  std::sort(sorted.begin(), sorted.end());
  const auto twice = std::adjacent_find(sorted.begin(), sorted.end());
  if (twice != sorted.end())
    throw FileError(l.path.string() + ": point label " + std::to_string(*twice) +
                    " is given twice (each of the processor's points is one point of the whole mesh)");
  m.point_ids.assign(global.begin(), global.end());
}

}  // namespace

FoamCase read_openfoam(const fs::path& path, double max_file_bytes, const std::string& time) {
  CaseFiles files;
  FoamCase c = locate_case(path, time, files);
  read_mesh_files(c, files, max_file_bytes);
  check_cells(c, files);
  read_patches(c, max_file_bytes);
  read_point_addressing(c, max_file_bytes);
  return c;
}

std::string foam_points_bytes(const FoamCase& c, std::span<const Vec3> points) {
  const FoamPointsFile& f = c.points_file;
  if (points.size() != c.mesh.points.size())
    throw FileError(f.path.string() + ": " + std::to_string(points.size()) + " points to write, the file holds " +
                    std::to_string(c.mesh.points.size()));
  std::string out;
  out.reserve(f.text.size() + (f.binary ? 0 : points.size() * 8));
  out.append(f.text, 0, f.body_begin);
  if (f.binary) {
    for (const Vec3& p : points)
      for (int k = 0; k < 3; ++k) {
        if (f.scalar_bytes == 8) {
          out.append(reinterpret_cast<const char*>(&p[k]), 8);
        } else {
          const float x = float(p[k]);
          if (!std::isfinite(x))
            throw FileError(f.path.string() + ": a coordinate " + std::to_string(p[k]) +
                            " does not fit a 32-bit scalar");
          out.append(reinterpret_cast<const char*>(&x), 4);
        }
      }
    // The binary body is followed by whatever the file had after it (')' and the footer).
    const std::size_t body = points.size() * 3 * std::size_t(f.scalar_bytes);
    out.append(f.text, f.body_begin + body, std::string::npos);
    return out;
  }
  // ASCII: the old body token by token; numbers whose value changed are replaced.
  const std::string& t = f.text;
  std::size_t k = 0;
  char buf[64];
  for (std::size_t i = f.body_begin; i < f.body_end;) {
    const char ch = t[i];
    if (ch == '(' || ch == ')' || ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r' || ch == '\f' || ch == '\v') {
      out += ch;
      ++i;
      continue;
    }
    std::size_t e = i;
    while (e < f.body_end && t[e] != '(' && t[e] != ')' && t[e] != ' ' && t[e] != '\t' && t[e] != '\n' &&
           t[e] != '\r' && t[e] != '\f' && t[e] != '\v')
      ++e;
    const double v = points[k / 3][int(k % 3)];
    double old = 0;
    std::from_chars(t.data() + i, t.data() + e, old);
    if (std::bit_cast<std::uint64_t>(old) == std::bit_cast<std::uint64_t>(v)) {
      out.append(t, i, e - i);
    } else {
      const auto r = std::to_chars(buf, buf + sizeof buf, v);
      out.append(buf, std::size_t(r.ptr - buf));
    }
    ++k;
    i = e;
  }
  out.append(t, f.body_end, std::string::npos);
  return out;
}

namespace {

/// The file's bytes as they go to disk (gzip'd if the input was).
std::string encoded_points(const FoamCase& c, std::span<const Vec3> points) {
  std::string bytes = foam_points_bytes(c, points);
  return c.points_file.gzip ? gzip(bytes) : bytes;
}

void write_bytes(const fs::path& file, const std::string& bytes) {
  std::ofstream o(file, std::ios::binary | std::ios::trunc);
  if (!o) throw FileError("cannot write '" + file.string() + "': " + std::strerror(errno));
  o.write(bytes.data(), std::streamsize(bytes.size()));
  o.close();
  std::error_code ec;
  if (!o || fs::file_size(file, ec) != bytes.size() || ec)
    throw FileError("cannot write '" + file.string() + "': the disk did not take all " + std::to_string(bytes.size()) +
                    " bytes");
}

/// c's points file in copy_root, a copy of c.root: csrbf's own file there, replaced through a new
/// file (a link in the case is replaced by a file, never written through).
void place_points(const FoamCase& c, const std::string& bytes, const fs::path& copy_root, const fs::path& target) {
  std::error_code ec;
  // Lexically: the path as the case names it, links not followed (fs::relative would resolve them).
  const fs::path rel = target.lexically_normal().lexically_relative(c.root.lexically_normal());
  if (rel.empty() || *rel.begin() == "..")
    throw FileError("cannot place the points of '" + c.root.string() + "' in the copy");
  // A folder on the way that the copy kept as a link (a case whose polyMesh links to another case's)
  // becomes a copy of what it links to: the new points must never go through it into the input.
  fs::path at = copy_root;
  for (auto it = rel.begin(); it != rel.end() && std::next(it) != rel.end(); ++it) {
    at /= *it;
    if (!fs::is_symlink(fs::symlink_status(at, ec))) continue;
    const fs::path linked = fs::canonical(at, ec);
    if (ec) throw FileError("cannot place the points in the copy: '" + at.string() + "' links to nowhere");
    fs::remove(at, ec);  // the link in csrbf's own copy
    if (!ec) fs::copy(linked, at, fs::copy_options::recursive | fs::copy_options::copy_symlinks, ec);
    if (ec)
      throw FileError("cannot copy '" + linked.string() + "' (linked from the case) into the copy: " + ec.message());
  }
  const fs::path copied = copy_root / rel;
  fs::create_directories(copied.parent_path(), ec);  // a time folder whose mesh was constant's
  const fs::path fresh = copied.parent_path() / (".csrbf-new-" + copied.filename().string());
  write_bytes(fresh, bytes);
  fs::rename(fresh, copied, ec);
  if (ec) throw FileError("cannot write '" + copied.string() + "': " + ec.message());
}

}  // namespace

void check_openfoam_copy_target(const FoamCase& c, const fs::path& out) {
  std::error_code ec;
  if (fs::symlink_status(out, ec).type() != fs::file_type::not_found)
    throw FileError("cannot write '" + out.string() +
                    "': it exists (csrbf morph writes a new case folder; --in-place "
                    "rewrites the input's points alone)");
  const fs::path root = fs::weakly_canonical(c.root, ec);
  const fs::path target = fs::weakly_canonical(fs::absolute(out), ec);
  const auto [r_end, t_it] = std::mismatch(root.begin(), root.end(), target.begin(), target.end());
  if (r_end == root.end())
    throw FileError("cannot write '" + out.string() + "': it is inside the case '" + c.root.string() +
                    "' being copied");
}

void copy_openfoam_case(const FoamCase& c, const fs::path& into, const fs::path& out) {
  std::error_code ec;
  // The case named through a link (csrbf morph caselink -o out): copy_symlinks would copy the link
  // itself onto the new folder (EINVAL); the folder it links to is copied.
  fs::path from = c.root;
  if (fs::is_symlink(fs::symlink_status(from, ec))) from = fs::canonical(c.root, ec);
  if (!ec) fs::copy(from, into, fs::copy_options::recursive | fs::copy_options::copy_symlinks, ec);
  if (ec) throw FileError("cannot copy '" + c.root.string() + "' to '" + out.string() + "': " + ec.message());
}

void write_openfoam_copy(const FoamCase& c, std::span<const Vec3> points, const fs::path& out) {
  check_openfoam_copy_target(c, out);
  const std::string bytes = encoded_points(c, points);
  io::Partial partial(out, io::Partial::Kind::Folder);
  copy_openfoam_case(c, partial.path(), out);
  place_points(c, bytes, partial.path(), c.points_file.target);
  partial.commit_new(out);
}

fs::path foam_points_target(const FoamCase& c, const std::string& time) {
  if (time.empty()) return c.points_file.target;
  std::error_code ec;
  if (!fs::is_directory(c.root / "constant", ec))
    throw FileError("'" + c.root.string() + "' is a polyMesh folder, not a case: it has no time folders to write");
  return c.root / time / "polyMesh" / c.points_file.path.filename();
}

void write_openfoam_points_into(const FoamCase& c, std::span<const Vec3> points, const fs::path& copy_root,
                                const std::string& time) {
  place_points(c, encoded_points(c, points), copy_root, foam_points_target(c, time));
}

std::unique_ptr<io::Partial> stage_openfoam_points(const FoamCase& c, std::span<const Vec3> points,
                                                   const std::string& time) {
  const fs::path target = foam_points_target(c, time);
  std::error_code ec;
  fs::create_directories(target.parent_path(), ec);
  if (ec && !fs::is_directory(target.parent_path()))
    throw FileError("cannot write '" + target.string() + "': cannot make its folder: " + ec.message());
  const std::string bytes = encoded_points(c, points);
  auto staged = std::make_unique<io::Partial>(target, io::Partial::Kind::File);
  write_bytes(staged->path(), bytes);
  return staged;
}

void commit_openfoam_points(const FoamCase& c, io::Partial& staged, const std::string& time) {
  staged.commit(foam_points_target(c, time));
}

void write_openfoam_in_place(const FoamCase& c, std::span<const Vec3> points) {
  const std::string bytes = encoded_points(c, points);
  std::error_code ec;
  fs::create_directories(c.points_file.target.parent_path(), ec);  // TIME/polyMesh, new where constant's
  io::write_atomically(c.points_file.target,
                       [&](std::ostream& o) { o.write(bytes.data(), std::streamsize(bytes.size())); });
}

}  // namespace csrbf::morph
