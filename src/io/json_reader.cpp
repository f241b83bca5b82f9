#include "json_reader.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/units.hpp"

#include "text.hpp"

#include <algorithm>
#include <fstream>
#include <set>
#include <vector>
#include <sstream>

namespace csrbf::io::detail {

namespace {
struct TooDeep {
  int depth;
};
struct DuplicateKey {
  std::string key;
};
}  // namespace

nlohmann::json parse_json(const std::string& text, const std::string& name) {
  try {
    // Nesting is limited while parsing, so that nothing later (messages, copies) recurses deeply.
    // A key given twice in one object is refused (nlohmann would keep the last silently).
    std::vector<std::set<std::string>> keys;
    using Event = nlohmann::json::parse_event_t;
    const nlohmann::json::parser_callback_t limit = [&keys](int depth, Event event, nlohmann::json& parsed) {
      if (depth > kMaxJsonDepth && (event == Event::object_start || event == Event::array_start)) throw TooDeep{depth};
      if (event == Event::object_start)
        keys.emplace_back();
      else if (event == Event::object_end && !keys.empty())
        keys.pop_back();
      else if (event == Event::key && !keys.empty() && !keys.back().insert(parsed.get<std::string>()).second)
        throw DuplicateKey{parsed.get<std::string>()};
      return true;
    };
    return nlohmann::json::parse(text, limit);
  } catch (const TooDeep& d) {
    throw FileError(name + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) +
                    " levels (arrays and objects)");
  } catch (const DuplicateKey& k) {
    throw FileError(name + ": the key \"" + detail::cut(k.key) + "\" appears twice in one object");
  } catch (const nlohmann::json::exception& e) {
    // nlohmann's message reads "[json.exception.parse_error.101] parse error at line 3, column 5: ...";
    // a number too large for a double is an out_of_range.406 error.
    std::string m = e.what();
    const auto k = m.find("] ");
    if (k != std::string::npos) m = m.substr(k + 2);
    throw FileError(name + ": not valid JSON: " + m);
  }
}

nlohmann::json read_json_file(const std::filesystem::path& path, double max_bytes) {
  // csrbf's documents are small (controls inline take about 100 bytes each): 1 GiB at most.
  return parse_json(read_input(path, "a JSON file", std::min(max_bytes, kGiB)), path.string());
}

namespace {
/// A short text for a value: scalars as JSON (cut), containers by their size only (no recursion).
std::string shown(const nlohmann::json& j) {
  if (j.is_array()) return "an array of " + std::to_string(j.size()) + " elements";
  if (j.is_object()) return "an object with " + std::to_string(j.size()) + " members";
  // A cut string may end inside a UTF-8 sequence (and the file's may be invalid to begin with):
  // replaced, never thrown from inside an error message (fuzz_deformation).
  constexpr auto replace = nlohmann::json::error_handler_t::replace;
  std::string s;
  if (j.is_string()) {
    const auto& str = j.get_ref<const std::string&>();
    s = nlohmann::json(str.size() > 60 ? str.substr(0, 60) : str).dump(-1, ' ', false, replace);
  } else {
    s = j.dump(-1, ' ', false, replace);
  }
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}
}  // namespace

void JsonNode::fail(const std::string& message) const {
  throw FileError(*file_ + ": " + (path_.empty() ? std::string("(top level)") : path_) + ": " + message);
}

void JsonNode::expected(const std::string& what) const { fail("expected " + what + ", got " + shown(*j_)); }

JsonNode JsonNode::operator[](const char* key) const {
  if (!j_->is_object()) expected("an object");
  const auto it = j_->find(key);
  const std::string p = path_.empty() ? std::string(key) : path_ + "." + key;
  if (it == j_->end()) JsonNode(*j_, *file_, p).fail("missing (required)");
  return JsonNode(*it, *file_, p);
}

JsonNode JsonNode::operator[](std::size_t i) const {
  if (!j_->is_array()) expected("an array");
  const std::string p = path_ + "[" + std::to_string(i) + "]";
  if (i >= j_->size()) JsonNode(*j_, *file_, p).fail("missing");
  return JsonNode((*j_)[i], *file_, p);
}

std::size_t JsonNode::size() const {
  if (!j_->is_array()) expected("an array");
  return j_->size();
}

void JsonNode::only(std::initializer_list<const char*> allowed) const {
  if (!j_->is_object()) expected("an object");
  for (auto it = j_->begin(); it != j_->end(); ++it) {
    bool ok = false;
    for (const char* a : allowed) ok = ok || it.key() == a;
    if (ok) continue;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    const std::string p = path_.empty() ? it.key() : path_ + "." + it.key();
    JsonNode(*it, *file_, p).fail("unknown key '" + it.key() + "' (allowed here: " + list + ")");
  }
}

double JsonNode::number() const {
  if (!j_->is_number()) expected("a number");
  const double v = j_->get<double>();
  if (!std::isfinite(v)) expected("a finite number");
  return v;
}

double JsonNode::number(double lo, double hi) const {
  const double v = number();
  if (v < lo || v > hi) {
    std::ostringstream m;
    m << "expected a number in [" << lo << ", " << hi << "], got " << shown(*j_);
    fail(m.str());
  }
  return v;
}

double JsonNode::positive() const {
  const double v = number();
  if (!(v > 0)) expected("a number > 0");
  // The range of every length csrbf takes (SpaceMap::fit limits radii to it).
  if (v < 1e-150 || v > 1e150) expected("a number in [1e-150, 1e150]");
  return v;
}

std::size_t JsonNode::index() const {
  if (!j_->is_number_unsigned()) expected("an integer >= 0");
  return j_->get<std::size_t>();
}

std::string JsonNode::string() const {
  if (!j_->is_string()) expected("a string");
  return j_->get<std::string>();
}

bool JsonNode::boolean() const {
  if (!j_->is_boolean()) expected("true or false");
  return j_->get<bool>();
}

Vec3 JsonNode::vec3() const {
  if (!j_->is_array() || j_->size() != 3) expected("[x, y, z]");
  Vec3 v;
  // Coordinates within +-1e150, as SpaceMap::fit takes them: products and sums stay finite.
  for (std::size_t k = 0; k < 3; ++k) v[Eigen::Index(k)] = (*this)[k].number(-1e150, 1e150);
  return v;
}

Vec3 JsonNode::color() const {
  if (!j_->is_array() || j_->size() != 3) expected("[r, g, b] with each in [0, 1]");
  Vec3 v;
  for (std::size_t k = 0; k < 3; ++k) v[Eigen::Index(k)] = (*this)[k].number(0.0, 1.0);
  return v;
}

}  // namespace csrbf::io::detail
