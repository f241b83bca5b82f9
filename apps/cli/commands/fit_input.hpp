// The fit that deform and info share: --controls with --radius, --kernel and --polynomial, or
// --deformation, and --memory-limit, --ordering and --solver; read, checked and fitted with
// messages that name the control's file and line.
#pragma once

#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/space_map.hpp"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::cli {

struct FitArgs {
  std::string controls, deformation;
  double radius = 0;
  std::string kernel = "c2", polynomial = "none", ordering = "auto", solver = "auto";
  double memory_limit_gib = 4.0;
  double reserve_bytes = 0;  ///< of the limit, kept from the fit for what follows it (assimp's writer)
};

/// The fit's options on cmd, into a.
void add_fit_options(CLI::App* cmd, FitArgs& a);
/// A positive finite number, limited as SpaceMap::fit limits the radius (a bad value is exit 2).
CLI::Validator positive_finite(const char* what);
/// --memory-limit of the commands that read a scene: its meshes, deformation files and fits.
void add_scene_memory_limit(CLI::App* cmd, double& gib);

/// The files deform reads: the mesh, the controls or the deformation and the files it names.
std::vector<std::filesystem::path> deform_inputs(const FitArgs& a, const std::string& mesh);

struct FitInput {
  io::Controls controls;
  FitOptions options;
  std::optional<io::ActiveArea> area;
  std::optional<double> phase;  // the deformation file's
};

/// The controls or deformation file and the fit's options; a deformation's active area is checked
/// against `mesh` (when given) before the fit, which may take long.
FitInput read_fit_input(const FitArgs& a, const io::MeshDocument* mesh, const std::string& mesh_name,
                        bool distributed = false);

struct Fitted {
  io::Controls controls;
  SpaceMap map;
  std::optional<io::ActiveArea> area;  // the deformation file's active area, if any
  std::optional<double> phase;         // the deformation file's phase, if any
};

/// The fit of the controls or deformation file; a failure names the control's file and line.
Fitted fit(const FitArgs& a, const io::MeshDocument* mesh = nullptr, const std::string& mesh_name = {});

}  // namespace csrbf::cli
