#include "export.hpp"
#include "commands.hpp"
#include "fit_input.hpp"

#include "animate.hpp"
#include "commands.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/io/scene.hpp"
#include "csrbf/render/gltf_export.hpp"
#include "csrbf/units.hpp"
#include "page_html.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>

namespace csrbf::cli {
namespace {

namespace fs = std::filesystem;

/// Where the page's script is (three-csrbf.js: three.js from npm, its GLTFLoader and
/// web/csrbf_deformation.js, bundled when csrbf is built): CSRBF_WEB_DIR, else the build's.
fs::path web_dir() {
  if (const char* d = std::getenv("CSRBF_WEB_DIR"); d && *d) return d;
  return CSRBF_WEB_DIR;
}

constexpr const char* kWebMissing =
    "the page needs three.js: run scripts/install-deps.sh (npm three and esbuild into build/npm), then rebuild; "
    "or set CSRBF_WEB_DIR";

/// Writes p (new, in the page's partial folder) with write(stream); the size written is checked.
void write_file(const fs::path& p, const std::function<void(std::ostream&)>& write) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  write(out);
  const auto written = std::uint64_t(out.tellp());
  out.close();
  std::error_code ec;
  if (!out || fs::file_size(p, ec) != written)
    throw io::FileError(p.string() + ": could not be written completely (disk full?)");
}

void write_file(const fs::path& p, const std::string& bytes) {
  write_file(p, [&](std::ostream& s) { s.write(bytes.data(), std::streamsize(bytes.size())); });
}

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw io::FileError(p.string() + ": cannot be read; " + kWebMissing);
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw io::FileError(p.string() + ": could not be read");
  return s.str();
}

std::string replace_all(std::string s, const std::string& what, const std::string& with) {
  for (std::size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + with.size()))
    s.replace(at, what.size(), with);
  return s;
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (const char c : s) {
    if (c == '<')
      o += "&lt;";
    else if (c == '>')
      o += "&gt;";
    else if (c == '&')
      o += "&amp;";
    else if (c == '"')
      o += "&quot;";
    else
      o += c;
  }
  return o;
}

std::string kib(std::size_t bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f KiB", double(bytes) / 1024.0);
  return b;
}

}  // namespace

namespace {

/// The exporter's options from the command's.
render::GltfOptions gltf_options(const ExportOptions& o) {
  render::GltfOptions go;
  go.memory_limit_bytes = o.memory_limit_gib * kGiB;
  if (o.bake == "auto")
    go.bake = render::Bake::Auto;
  else if (o.bake == "always")
    go.bake = render::Bake::Always;
  else if (o.bake == "never")
    go.bake = render::Bake::Never;
  else
    throw UsageError("--bake: expected auto, always or never, got '" + o.bake + "'");
  go.meshopt = o.meshopt;
  go.quantize = o.quantize;
  if (o.quantize && o.compact_given)
    throw UsageError(
        "--quantize with --compact: CSRBF_deformation carries the deformation in float coordinates; quantize the "
        "morph targets (--quantize) or write the extension (--compact), not both");
  if (o.compact_given) {
    if (o.compact.empty() || o.compact == "fallback")
      go.compact = render::Compact::WithFallback;
    else if (o.compact == "only")
      go.compact = render::Compact::Only;
    else
      throw UsageError("--compact: expected no value (the morph targets kept as fallback) or 'only', got '" +
                       o.compact + "'");
  }
  if (o.fps) go.fps = *o.fps;
  return go;
}

/// --html's new folder (empty without --html), checked before the scene is read.
fs::path page_folder(const ExportOptions& o) {
  fs::path page;
  if (o.html_given && o.html.empty()) throw UsageError("--html: the folder name is empty");
  if (!o.html.empty()) {
    page = fs::path(o.html);
    if (page.filename().empty()) page = page.parent_path();
    std::error_code ec;
    if (fs::exists(fs::symlink_status(page, ec)))
      throw UsageError("--html: '" + o.html +
                       "' exists; the page is written into a new folder (csrbf replaces nothing it did not write)");
    const fs::path parent = page.has_parent_path() ? page.parent_path() : fs::path(".");
    if (!fs::is_directory(parent, ec)) throw UsageError("--html: the folder '" + parent.string() + "' does not exist");
    for (const char* f : {"three-csrbf.js", "LICENSE-three.js.txt"})
      if (!fs::is_regular_file(web_dir() / f, ec))
        throw io::FileError((web_dir() / f).string() + ": not found; " + kWebMissing);
  }
  return page;
}

/// -o is not the scene's texture.
void check_textures(const ExportOptions& o, const fs::path& out, const anim::Scene& scene) {
  std::error_code ec;
  for (const auto& obj : scene.objects)
    for (const anim::Material* m : [&] {
           std::vector<const anim::Material*> v{&obj.material};
           for (const auto& p : obj.parts) v.push_back(&p.material);
           return v;
         }())
      if (!m->texture.empty() && fs::equivalent(out, m->texture, ec))
        throw UsageError("-o '" + o.out + "' is the scene's texture '" + m->texture + "'");
}

/// The .glb or .gltf, and with --html the page's folder: all or nothing.
void write_outputs(const ExportOptions& o, const std::vector<unsigned char>& glb, const fs::path& out,
                   const fs::path& page, render::GltfReport& r) {
  std::error_code ec;
  if (page.empty()) {
    r.bytes = render::write_gltf(glb, out);
  } else {
    // The page in a partial folder; then the file in its partial, checked; then the page renamed to
    // DIR and, at once, the file to its name. A file that then fails to be renamed takes the page
    // (which this run made) with it: all or nothing (only SIGKILL between the two renames, a few
    // microseconds, can leave the page alone and the file's complete partial).
    io::Partial partial(page, io::Partial::Kind::Folder);
    const std::string glb_name = out.stem().string() + ".glb";
    std::string html = kPageHtml;
    html = replace_all(html, "@TITLE@", html_escape(fs::path(o.scene).filename().string()));
    html = replace_all(html, "@GLB@", html_escape(glb_name));
    write_file(partial.path() / "index.html", html);
    write_file(partial.path() / glb_name, [&](std::ostream& s) {
      s.write(reinterpret_cast<const char*>(glb.data()), std::streamsize(glb.size()));
    });
    write_file(partial.path() / "scene.glb.js", [&](std::ostream& s) {
      s << "window.CSRBF_GLB = \"";
      render::write_base64(s, glb.data(), glb.size());
      s << "\";\n";
    });
    write_file(partial.path() / "three-csrbf.js", read_all(web_dir() / "three-csrbf.js"));
    write_file(partial.path() / "LICENSE-three.js.txt", read_all(web_dir() / "LICENSE-three.js.txt"));
    bool page_committed = false;
    try {
      r.bytes = render::write_gltf(glb, out, [&] {
        partial.commit_new(page);
        page_committed = true;
      });
    } catch (...) {
      if (page_committed) fs::remove_all(page, ec);
      throw;
    }
  }
}

nlohmann::json report_json(const ExportOptions& o, const render::GltfReport& r, const fs::path& page) {
  nlohmann::json j;
  j["output"] = o.out;
  j["bytes"] = r.bytes;
  j["frames"] = r.frames;
  j["fps"] = r.fps;
  j["scene_size"] = r.scene_size;
  j["frame_vertex_bytes"] = r.frame_bytes;
  j["csrbf_bytes"] = r.csrbf_bytes;
  j["targets"] = r.targets;
  j["max_active_targets"] = r.max_active;
  j["shared_targets"] = r.shared_targets;
  for (const auto& ob : r.objects)
    j["objects"].push_back({{"name", ob.name},
                            {"vertices", ob.vertices},
                            {"targets", ob.targets},
                            {"max_active_targets", ob.max_active},
                            {"rotation_deviation_deg", ob.rotation_deviation_deg},
                            {"max_deviation", ob.max_deviation},
                            {"quantization_error", ob.quantization_error},
                            {"normal_error_deg", ob.normal_error_deg},
                            {"normal_error_endpoint_deg", ob.normal_error_endpoint_deg}});
  if (o.compact_given) {
    j["compact"] = {{"replaced_target_bytes", r.replaced_target_bytes},
                    {"compact_bytes", r.compact_bytes},
                    {"left_as_targets", r.compact_left_out}};
    for (std::size_t k = 0; k < r.objects.size(); ++k)
      j["objects"][k]["compact"] = {{"deformations", r.objects[k].compact_deformations},
                                    {"groups", r.objects[k].groups},
                                    {"max_error", r.objects[k].compact_error}};
  }
  j["parts"] = nlohmann::json::array();
  for (const auto& p : r.parts)
    j["parts"].push_back(
        {{"object", p.object}, {"part", p.part}, {"targets", p.targets}, {"baked", p.baked}, {"why", p.why}});
  if (!page.empty()) j["html"] = (page / "index.html").string();
  return j;
}

void report_text(const ExportOptions& o, const render::GltfOptions& go, const render::GltfReport& r,
                 const fs::path& page) {
  std::cout << "csrbf export: " << printable(o.scene) << " -> " << printable(o.out) << " (" << kib(r.bytes) << "), "
            << r.frames << " frames at " << r.fps << " fps\n";
  for (const auto& ob : r.objects) {
    std::printf("  object '%s': %zu vertices, %zu morph target%s, at most %zu active at once",
                printable(ob.name).c_str(), ob.vertices, ob.targets, ob.targets == 1 ? "" : "s", ob.max_active);
    if (ob.rotation_deviation_deg > 0) std::printf(", squad sampled (%.3g deg at most)", ob.rotation_deviation_deg);
    std::printf(", largest vertex deviation %.3g (%.2g of the scene)\n", ob.max_deviation,
                r.scene_size > 0 ? ob.max_deviation / r.scene_size : 0.0);
  }
  for (const auto& p : r.parts)
    std::cout << "  part '" << printable(p.object) << "/" << printable(p.part) << "': "
              << (p.baked ? "baked into " + std::to_string(p.targets) + " frame target" + (p.targets == 1 ? "" : "s") +
                                " (" + printable(p.why) + ")"
                          : std::to_string(p.targets) + " exact morph target" + (p.targets == 1 ? "" : "s"))
              << "\n";
  if (r.max_active > go.max_active)
    std::cout << "  warning: " << r.max_active << " morph targets are active at once; many engines play only "
              << go.max_active << " (three.js 8) — --bake auto keeps within that\n";
  std::cout << "  sizes: glTF " << kib(r.bytes) << "; every frame's vertices " << kib(r.frame_bytes)
            << "; csrbf's deformations " << kib(r.csrbf_bytes) << "\n";
  if (o.compact_given) {
    std::cout << "  CSRBF_deformation: " << kib(r.compact_bytes)
              << " of sources, coefficients and vertex groups in place of " << kib(r.replaced_target_bytes)
              << " of morph targets"
              << (go.compact == render::Compact::Only ? " (the targets left empty; the extension is required)\n"
                                                      : " (kept as fallback)\n");
    for (const auto& name : r.compact_left_out)
      std::cout << "    left as a morph target: '" << printable(name)
                << "' (its float sources and coefficients err by more than 1e-5 of the object's size: controls "
                   "nearly on top of each other?)\n";
    for (const auto& ob : r.objects)
      if (ob.compact_deformations > 0)
        std::printf(
            "    object '%s': %zu deformation%s, %zu vertex group%s, largest error %.3g (float sources and "
            "coefficients against the exact displacement)\n",
            printable(ob.name).c_str(), ob.compact_deformations, ob.compact_deformations == 1 ? "" : "s", ob.groups,
            ob.groups == 1 ? "" : "s", ob.compact_error);
  }
  if (!page.empty()) std::cout << "  page: " << printable((page / "index.html").string()) << "\n";
}

}  // namespace

int run_export(const ExportOptions& o) {
  const render::GltfOptions go = gltf_options(o);
  const fs::path out = o.out;
  const std::string ext = out.extension().string();
  if (ext != ".glb" && ext != ".gltf")
    throw UsageError("-o: the output must end in .glb or .gltf, got '" + o.out + "'");
  // Check the targets before the (slow) scene load, so that a typo fails at once.
  io::check_output_path(out);
  const fs::path page = page_folder(o);
  check_not_an_input("-o", out, io::referenced_files(o.scene, o.memory_limit_gib * kGiB));
  io::must_be_new(io::resolve_output(out));
  if (!page.empty() && fs::absolute(page).lexically_normal() == fs::absolute(out).lexically_normal())
    throw UsageError("--html '" + o.html + "' and -o name the same path");
  const anim::Scene scene = io::read_scene(o.scene, o.memory_limit_gib * kGiB);
  check_textures(o, out, scene);
  render::GltfReport r;
  const std::vector<unsigned char> glb = render::gltf_binary(scene, go, r);
  write_outputs(o, glb, out, page, r);
  if (o.json)
    std::cout << report_json(o, r, page).dump(2) << "\n";
  else
    report_text(o, go, r, page);
  return 0;
}

CLI::App* add_export_command(CLI::App& app, ExportOptions& o) {
  auto* exporter = app.add_subcommand(
      "export", "Write a scene as glTF 2.0 for game engines, Blender and web pages (docs/export.md)");
  exporter->add_option("scene", o.scene, "Scene JSON file")->required();
  exporter->add_option("-o,--output", o.out, "OUT.glb (binary) or OUT.gltf (one JSON file)")->required();
  exporter->add_option("--fps", o.fps, "Sampling rate of what is sampled or baked (default: the scene's)")
      ->check(finite_in(0.1, 1000.0, "--fps"));
  exporter
      ->add_option("--bake", o.bake,
                   "auto: bake what morph targets cannot hold exactly; always: every deforming part; never: refuse")
      ->capture_default_str();
  exporter->add_option("--html", o.html,
                       "Also write a new folder DIR with index.html, the .glb and three.js: a page that plays it");
  exporter
      ->add_option("--compact", o.compact,
                   "Also write each exactly held deformation as CSRBF_deformation (docs/gltf/CSRBF_deformation.md): "
                   "--compact keeps the morph targets as fallback, --compact=only replaces them")
      ->expected(0, 1);
  exporter->add_flag("--meshopt", o.meshopt,
                     "Compress vertex, index and animation data with meshoptimizer (EXT_meshopt_compression, "
                     "required: three.js, Babylon.js and gltfpack read it, Blender 3.4 does not)");
  exporter->add_flag("--quantize", o.quantize,
                     "Positions and displacements as 16-bit, normals as 8-bit integers (KHR_mesh_quantization, "
                     "required); not with --compact");
  exporter->add_flag("--json", o.json, "Print the report as one JSON object");
  add_scene_memory_limit(exporter, o.memory_limit_gib);
  exporter->parse_complete_callback([&o, exporter] {
    o.html_given = exporter->count("--html") > 0;
    o.compact_given = exporter->count("--compact") > 0;
  });
  return exporter;
}

}  // namespace csrbf::cli
