#pragma once

#include <CLI/CLI.hpp>

#include "csrbf/errors.hpp"

#include <optional>
#include <stdexcept>
#include <string>

namespace csrbf::cli {

/// A bad option value found after parsing (its message names the option): exit status 2. csrbf's
/// one usage error (csrbf/errors.hpp).
using csrbf::UsageError;

struct AnimateOptions {
  std::string scene, out;
  double memory_limit_gib = 4.0;  ///< --memory-limit: the scene's meshes and fits, the frames
  std::optional<double> fps, from, to;
  std::string size = "640x480";
  bool private_display = false;  ///< start a private Xvfb even when DISPLAY is set
};

/// `csrbf animate`: renders the scene to a movie. Returns the exit status (0, 1 on failure, 128 + the
/// signal when interrupted); throws for bad input (the caller prints it and exits 1, or 2 for a
/// UsageError).
int run_animate(const AnimateOptions& o);

/// `csrbf animate` and its options, into o.
CLI::App* add_animate_command(CLI::App& app, AnimateOptions& o);

}  // namespace csrbf::cli
