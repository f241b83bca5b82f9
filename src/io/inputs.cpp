#include "csrbf/io/inputs.hpp"
#include "csrbf/io/memory.hpp"

#include "json_reader.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>

namespace fs = std::filesystem;

namespace csrbf::io {

namespace {

bool names_a_file(const std::string& key) {
  return key == "mesh" || key == "texture" || key == "deformation" || key == "controls" || key == "displacements" ||
         key == "file";
}

void collect(const nlohmann::json& j, const fs::path& base, int depth, std::vector<fs::path>& out) {
  if (depth > 64) return;
  if (j.is_array()) {
    for (const auto& e : j) collect(e, base, depth + 1, out);
  } else if (j.is_object()) {
    for (const auto& [key, value] : j.items()) {
      if (value.is_string() && names_a_file(key)) {
        const std::string& s = value.get_ref<const std::string&>();
        if (!s.empty() && s.find('\0') == std::string::npos) out.push_back(base / s);
      } else {
        collect(value, base, depth + 1, out);
      }
    }
  }
}

void walk(const fs::path& json, int level, std::vector<fs::path>& out, double limit) {
  nlohmann::json j;
  try {
    j = detail::read_json_file(json, json_bytes_within(limit));
  } catch (const std::exception&) {
    return;  // its reader reports it
  }
  const std::size_t first = out.size();
  collect(j, json.parent_path(), 0, out);
  if (level >= 3) return;
  const std::size_t last = out.size();
  for (std::size_t i = first; i < last; ++i) {
    std::error_code ec;
    const fs::path p = out[i];
    if (p.extension() == ".json" && fs::is_regular_file(p, ec)) walk(p, level + 1, out, limit);
  }
}

}  // namespace

std::vector<fs::path> mesh_side_files(const fs::path& mesh, double memory_limit_bytes) {
  std::vector<fs::path> out;
  std::string ext = mesh.extension().string();
  for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".gltf") return out;
  nlohmann::json j;
  try {
    j = detail::read_json_file(mesh, json_bytes_within(memory_limit_bytes));
  } catch (const std::exception&) {
    return out;  // its reader reports it
  }
  if (!j.is_object()) return out;
  for (const char* key : {"buffers", "images"}) {
    if (!j.contains(key) || !j[key].is_array()) continue;
    for (const auto& e : j[key]) {
      if (!e.is_object() || !e.contains("uri") || !e["uri"].is_string()) continue;
      const std::string& uri = e["uri"].get_ref<const std::string&>();
      if (uri.empty() || uri.rfind("data:", 0) == 0 || uri.find('\0') != std::string::npos) continue;
      out.push_back(mesh.parent_path() / uri);
    }
  }
  return out;
}

double json_bytes_within(double memory_limit_bytes) noexcept {
  return std::max(0.0, memory_limit_bytes - resident_bytes()) / 8.0;
}

std::vector<fs::path> referenced_files(const fs::path& json, double memory_limit_bytes) {
  std::vector<fs::path> out{json};
  walk(json, 1, out, memory_limit_bytes);
  const std::size_t named = out.size();
  for (std::size_t i = 0; i < named; ++i)
    for (auto& f : mesh_side_files(out[i], memory_limit_bytes)) out.push_back(std::move(f));
  return out;
}

fs::path same_file_as(const fs::path& output, const std::vector<fs::path>& inputs) {
  struct stat o {};
  if (output.empty() || ::stat(output.c_str(), &o) != 0) return {};
  for (const auto& in : inputs) {
    struct stat i {};
    if (!in.empty() && ::stat(in.c_str(), &i) == 0 && i.st_dev == o.st_dev && i.st_ino == o.st_ino) return in;
  }
  return {};
}

}  // namespace csrbf::io
