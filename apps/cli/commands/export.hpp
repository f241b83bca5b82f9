#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace csrbf::cli {

struct ExportOptions {
  std::string scene, out, bake = "auto", html;
  double memory_limit_gib = 4.0;  ///< --memory-limit: the scene's meshes and fits, baked frames
  std::optional<double> fps;
  bool json = false;
  bool html_given = false;     ///< --html was on the command line (an empty name is an error)
  std::string compact;         ///< --compact's value: empty (the fallback kept) or "only"
  bool compact_given = false;  ///< --compact was on the command line
  bool meshopt = false;        ///< --meshopt: EXT_meshopt_compression
  bool quantize = false;       ///< --quantize: KHR_mesh_quantization
};

/// `csrbf export`: the scene as glTF 2.0 (and, with --html, a page that plays it). Returns the exit
/// status; throws for bad input (UsageError: exit 2).
int run_export(const ExportOptions& o);

/// `csrbf export` and its options, into o.
CLI::App* add_export_command(CLI::App& app, ExportOptions& o);

}  // namespace csrbf::cli
