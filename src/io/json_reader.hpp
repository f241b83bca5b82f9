// Reading JSON documents with errors that name the file and the JSON path of the bad value, e.g.
// "scene.json: objects[1].trajectory.keys[3].time: expected a number, got "abc"" (private to
// csrbf::io).
#pragma once

#include "csrbf/io/deformation.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/units.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <string>

namespace csrbf::io::detail {

/// Arrays and objects nest at most this deep (csrbf's documents need 6 levels).
constexpr int kMaxJsonDepth = 64;

/// Parses a whole file; a syntax error names the line and column; nesting deeper than
/// kMaxJsonDepth is refused.
/// At most max_bytes of text (and 1 GiB), also from a pipe.
nlohmann::json read_json_file(const std::filesystem::path& path, double max_bytes = kGiB);
/// Parses text; name is the file name used in messages.
nlohmann::json parse_json(const std::string& text, const std::string& name);

/// A value inside a document and where it is. Borrows the json and the file name.
class JsonNode {
 public:
  JsonNode(const nlohmann::json& j, const std::string& file, std::string path = {})
      : j_(&j), file_(&file), path_(std::move(path)) {}

  const nlohmann::json& json() const { return *j_; }
  const std::string& path() const { return path_; }
  const std::string& file() const { return *file_; }

  [[noreturn]] void fail(const std::string& message) const;
  /// "expected <what>, got <the value>".
  [[noreturn]] void expected(const std::string& what) const;

  bool has(const char* key) const { return j_->is_object() && j_->contains(key); }
  /// Member `key` of an object (an error naming the path if this is not an object or key is absent).
  JsonNode operator[](const char* key) const;
  /// Element i of an array.
  JsonNode operator[](std::size_t i) const;
  /// Elements of an array (error if not an array).
  std::size_t size() const;
  /// Throws for a member not in `allowed`, naming it and listing the allowed ones.
  void only(std::initializer_list<const char*> allowed) const;

  double number() const;
  /// A number in [lo, hi].
  double number(double lo, double hi) const;
  /// A number > 0.
  double positive() const;
  std::size_t index() const;  ///< a non-negative integer
  std::string string() const;
  bool boolean() const;
  Vec3 vec3() const;  ///< [x, y, z] of finite numbers
  /// An RGB colour, [r, g, b] in [0, 1].
  Vec3 color() const;

 private:
  const nlohmann::json* j_;
  const std::string* file_;
  std::string path_;
};

/// The keys of a deformation in node: kernel, radius, polynomial, and sources + destinations or
/// controls (a controls text file, relative to base). The caller checks for unknown keys.
DeformationSpec parse_deformation(const JsonNode& node, const std::filesystem::path& base);

}  // namespace csrbf::io::detail
