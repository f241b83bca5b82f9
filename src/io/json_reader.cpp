#include "json_reader.hpp"

#include <fstream>
#include <sstream>

namespace csrbf::io::detail {

nlohmann::json parse_json(const std::string& text, const std::string& name) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    // nlohmann's message reads "[json.exception.parse_error.101] parse error at line 3, column 5: ...";
    // a number too large for a double is an out_of_range.406 error.
    std::string m = e.what();
    const auto k = m.find("] ");
    if (k != std::string::npos) m = m.substr(k + 2);
    throw FileError(name + ": not valid JSON: " + m);
  }
}

nlohmann::json read_json_file(const std::filesystem::path& path) {
  check_readable(path, "a JSON file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path.string() + ": cannot open for reading");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_json(text.str(), path.string());
}

namespace {
std::string shown(const nlohmann::json& j) {
  std::string s = j.dump();
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
  for (std::size_t k = 0; k < 3; ++k) v[Eigen::Index(k)] = (*this)[k].number();
  return v;
}

Vec3 JsonNode::color() const {
  if (!j_->is_array() || j_->size() != 3) expected("[r, g, b] with each in [0, 1]");
  Vec3 v;
  for (std::size_t k = 0; k < 3; ++k) v[Eigen::Index(k)] = (*this)[k].number(0.0, 1.0);
  return v;
}

}  // namespace csrbf::io::detail
