#pragma once

#include <optional>
#include <string>

namespace csrbf::cli {

struct AnimateOptions {
  std::string scene, out;
  std::optional<double> fps, from, to;
  std::string size = "640x480";
  bool private_display = false;  ///< start a private Xvfb even when DISPLAY is set
};

/// `csrbf animate`: renders the scene to a movie. Returns the exit status (0, 1 on failure, 130
/// when interrupted); throws for bad input (the caller prints it and exits 1).
int run_animate(const AnimateOptions& o);

}  // namespace csrbf::cli
