#include "info.hpp"

#include "commands.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/estimate.hpp"
#include "csrbf/folds.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/units.hpp"

#include <nlohmann/json.hpp>

#include <iostream>
#include <optional>
#include <span>

namespace csrbf::cli {

CLI::App* add_info_command(CLI::App& app, InfoArgs& a) {
  auto* info = app.add_subcommand("info", "Fit the controls and print the solver's statistics");
  add_fit_options(info, a.fit);
  info->add_flag("--json", a.json, "Print one JSON object");
  info->add_option("--mesh", a.mesh, "Mesh to check for folds (with --check-folds)");
  auto* folds_flag = info->add_flag("--check-folds", a.check_folds,
                                    "Report det(dT/dx) over the mesh's vertices and points inside its triangles: "
                                    "the minimum, where it is <= 0, and the largest fold-free phase");
  info->add_option("--phase", a.phase, "Phase at which folds are counted (default 1)")
      ->check(finite_in(-1e6, 1e6, "--phase"));
  auto* estimate_flag = info->add_flag(
      "--estimate", a.estimate,
      "Do not fit: print what the fit would cost (neighbours, non-zeros, each solver's memory and time)");
  auto* neighbours_opt =
      info->add_option("--neighbours", a.neighbours,
                       "Instead of --radius: print the R that gives each control this many neighbours on average, "
                       "without fitting (with --estimate, also what a fit at that R would cost)")
          ->check(positive_finite("--neighbours"));
  info->get_option("--controls")->remove_needs(info->get_option("--radius"));
  info->get_option("--radius")->remove_needs(info->get_option("--controls"));
  neighbours_opt->excludes(info->get_option("--radius"))->excludes(info->get_option("--deformation"));
  estimate_flag->excludes(folds_flag);
  neighbours_opt->excludes(folds_flag);
  folds_flag->needs(info->get_option("--mesh"));
  info->get_option("--mesh")->needs(folds_flag);  // a mesh is read only to check it for folds
  return info;
}

namespace {

/// --neighbours and --estimate: the radius and what a fit would cost, without fitting.
int run_estimate(InfoArgs& a) {
  if (a.neighbours > 0) a.fit.radius = 1.0;  // replaced below
  auto input = read_fit_input(a.fit, nullptr, {});
  const std::span<const Vec3> s = input.controls.sources;
  if (a.neighbours > 0) {
    if (!(a.neighbours < double(s.size()) - 1))
      throw UsageError("--neighbours: " + io::format_number(a.neighbours) + " is not below " +
                       std::to_string(s.size()) + " controls less one");
    input.options.radius = suggest_radius(s, a.neighbours);
  }
  nlohmann::json j{{"radius", input.options.radius}, {"controls", s.size()}};
  if (a.neighbours > 0) j["neighbours_asked"] = a.neighbours;
  if (a.estimate) j["estimate"] = estimate_json(csrbf::estimate(s, input.options.radius, input.options));
  if (a.json)
    std::cout << j.dump(2) << '\n';
  else
    std::cout << estimate_text(j);
  return 0;
}

}  // namespace

int run_info(InfoArgs& a) {
  if (a.fit.deformation.empty() && (a.fit.radius > 0) == (a.neighbours > 0))
    throw UsageError("info: give --controls with --radius or with --neighbours");
  if (a.neighbours > 0 || a.estimate) return run_estimate(a);
  std::optional<io::MeshDocument> mesh;
  if (a.check_folds) mesh.emplace(io::MeshDocument::load(a.mesh, a.fit.memory_limit_gib * kGiB));
  Fitted f = fit(a.fit, mesh ? &*mesh : nullptr, a.mesh);
  std::optional<FoldReport> folds;
  if (a.check_folds) {
    if (f.area)  // the vertices the deformation moves, and the triangles across the area's edge
      folds = check_folds_in_area(f.map, mesh->positions(), mesh->faces(), f.area->vertices, a.phase);
    else
      folds = csrbf::check_folds(f.map, mesh->positions(), mesh->faces(), a.phase);
  }
  if (a.json) {
    auto j = stats_json(f.map);
    if (folds) j["folds"] = folds_json(*folds);
    std::cout << j.dump(2) << '\n';
  } else {
    std::cout << stats_text(f.map);
    if (folds) std::cout << folds_text(*folds);
  }
  return 0;
}

}  // namespace csrbf::cli
