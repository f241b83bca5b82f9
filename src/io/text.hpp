// Small text helpers shared by the readers (private to csrbf::io).
#pragma once

#include <charconv>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

namespace csrbf::io::detail {

inline std::string_view trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

inline std::vector<std::string_view> split(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
    std::size_t j = i;
    while (j < s.size() && s[j] != ' ' && s[j] != '\t' && s[j] != '\r') ++j;
    if (j > i) out.push_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

/// A UTF-8 byte order mark at the start of a file is not part of its first line's text.
inline std::string_view skip_bom(std::string_view s) { return s.substr(0, 3) == "\xEF\xBB\xBF" ? s.substr(3) : s; }

/// Text quoted in a message: at most 120 bytes, so that a huge line is not echoed whole.
/// Control bytes (a NUL would end the message early) are shown as \xNN.
inline std::string cut(std::string_view s) {
  const bool whole = s.size() <= 120;
  std::string out;
  for (const char c : whole ? s : s.substr(0, 100)) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 && c != '\t') {
      static const char* hex = "0123456789abcdef";
      out += "\\x";
      out += hex[u >> 4];
      out += hex[u & 15];
    } else {
      out += c;
    }
  }
  if (!whole) out += "... (" + std::to_string(s.size()) + " bytes)";
  return out;
}

/// Whole-token parse; false if the token is not a number. Accepts "nan"/"inf" (callers check).
/// One sign at most ("+-1" is not a number); a value too small for a double (1e-400) reads as 0,
/// one too large (1e400) as infinity, which callers refuse as not finite.
inline bool parse_double(std::string_view t, double& v) {
  if (!t.empty() && t[0] == '+') {
    t.remove_prefix(1);
    if (!t.empty() && (t[0] == '-' || t[0] == '+')) return false;
  }
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (r.ptr != t.data() + t.size()) return false;
  if (r.ec == std::errc::result_out_of_range) {
    const std::string copy(t);
    v = std::strtod(copy.c_str(), nullptr);  // 0 (underflow) or +-HUGE_VAL (overflow), as C reads it
    return true;
  }
  return r.ec == std::errc();
}

template <class I>
inline bool parse_int(std::string_view t, I& v) {
  if (!t.empty() && t[0] == '+') {
    t.remove_prefix(1);
    if (!t.empty() && (t[0] == '-' || t[0] == '+')) return false;
  }
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

}  // namespace csrbf::io::detail
