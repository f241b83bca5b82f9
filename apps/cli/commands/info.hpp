// `csrbf info`: fit the controls and print the solver's statistics; --check-folds over a mesh;
// --estimate and --neighbours answer without fitting.
#pragma once

#include "fit_input.hpp"

#include <CLI/CLI.hpp>

#include <string>

namespace csrbf::cli {

struct InfoArgs {
  FitArgs fit;
  bool json = false;
  std::string mesh;
  bool check_folds = false;
  double phase = 1.0;
  bool estimate = false;
  double neighbours = 0;
};

CLI::App* add_info_command(CLI::App& app, InfoArgs& a);
int run_info(InfoArgs& a);

}  // namespace csrbf::cli
