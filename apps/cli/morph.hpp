#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace csrbf::cli {

struct MorphArgs {
  std::string mesh, out, motion;
  std::optional<double> radius, greedy;
  std::string kernel, polynomial, solver = "auto";
  double phase = 1.0;
  double memory_limit_gib = 4.0;
  bool json = false, force = false, in_place = false;
};

/// Adds `csrbf morph` and its options to app.
CLI::App* add_morph_command(CLI::App& app, MorphArgs& a);

/// `csrbf morph`: returns the exit status; throws for bad input (the caller prints it and exits 1,
/// or 2 for a UsageError).
int run_morph(const MorphArgs& a);

}  // namespace csrbf::cli
