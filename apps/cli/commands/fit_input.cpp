#include "fit_input.hpp"

#include "commands.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <algorithm>
#include <iostream>

namespace csrbf::cli {

std::vector<std::filesystem::path> deform_inputs(const FitArgs& a, const std::string& mesh) {
  std::vector<std::filesystem::path> in{mesh};
  for (auto& f : csrbf::io::mesh_side_files(mesh, a.memory_limit_gib * csrbf::kGiB)) in.push_back(std::move(f));
  if (!a.controls.empty()) in.emplace_back(a.controls);
  if (!a.deformation.empty())
    for (auto& f : csrbf::io::referenced_files(a.deformation, a.memory_limit_gib * csrbf::kGiB))
      in.push_back(std::move(f));
  return in;
}

CLI::Validator positive_finite(const char* what) { return finite_in(1e-150, 1e150, what); }

void add_scene_memory_limit(CLI::App* cmd, double& gib) {
  cmd->add_option("--memory-limit", gib,
                  "The most memory csrbf may hold, in GiB: the scene's meshes and the fits of its deformations "
                  "that would need more than the program leaves of it are refused")
      ->check(finite_in(1e-6, 1e6, "--memory-limit"))
      ->capture_default_str();
}

void add_fit_options(CLI::App* cmd, FitArgs& a) {
  auto* controls =
      cmd->add_option("--controls", a.controls, "Controls file: one control vector a line, 'sx sy sz dx dy dz'");
  auto* deformation =
      cmd->add_option("--deformation", a.deformation,
                      "Deformation JSON (docs/scene-format.md): controls, radius, kernel and polynomial "
                      "in one file, instead of --controls, --radius, --kernel, --polynomial");
  auto* radius = cmd->add_option("--radius,-r", a.radius, "Radius of support R, in the mesh's units (> 0)")
                     ->check(positive_finite("--radius"));
  auto* kernel =
      cmd->add_option("--kernel,-k", a.kernel, "Wendland kernel: c0 = psi20, c2 = psi31, c4 = psi42, c6 = psi53")
          ->transform(CLI::IsMember(csrbf::names<csrbf::Kernel>(), CLI::ignore_case))
          ->capture_default_str();
  auto* polynomial =
      cmd->add_option("--polynomial,-p", a.polynomial,
                      "Polynomial part: none (strictly local), constant, linear (reproduces affine maps)")
          ->transform(CLI::IsMember(csrbf::names<csrbf::Polynomial>(), CLI::ignore_case))
          ->capture_default_str();
  cmd->add_option("--memory-limit", a.memory_limit_gib,
                  "The most memory csrbf may hold, in GiB: fits that would need more than what the program and its "
                  "inputs leave of it are refused (a radius near the model's size makes the matrix dense)")
      ->check(finite_in(1e-6, 1e6, "--memory-limit"))
      ->capture_default_str();
  deformation->excludes(controls)->excludes(radius)->excludes(kernel)->excludes(polynomial);
  controls->needs(radius);
  radius->needs(controls);
  cmd->callback([a = &a, cmd] {
    if (a->controls.empty() && a->deformation.empty())
      throw CLI::RequiredError(cmd->get_name() + ": give --controls with --radius, or --deformation");
  });
  cmd->add_option("--ordering", a.ordering,
                  "Matrix ordering: auto (smallest envelope), breadth-first (paper Fig. 3), reverse-breadth-first, "
                  "rcm, identity")
      ->transform(CLI::IsMember(csrbf::names<csrbf::Ordering>(), CLI::ignore_case))
      ->capture_default_str();
  cmd->add_option("--solver", a.solver,
                  "Solver: auto (the envelope while small, else conjugate gradients, which give way to the envelope "
                  "or CHOLMOD where those are predicted faster), envelope (paper), eigen, cholmod, cg (conjugate "
                  "gradients; CHOLMOD takes over if they have not converged in 3000 steps)")
      ->transform(CLI::IsMember(csrbf::cli::solver_choices(), CLI::ignore_case))
      ->capture_default_str();
}

FitInput read_fit_input(const FitArgs& a, const csrbf::io::MeshDocument* mesh, const std::string& mesh_name,
                        bool distributed) {
  csrbf::io::Controls controls;
  csrbf::FitOptions o;
  std::optional<csrbf::io::ActiveArea> area;
  std::optional<double> phase;
  if (!a.deformation.empty()) {
    // Parsed JSON takes about 16 times its text: the text within a sixteenth of the memory limit.
    auto spec = csrbf::io::read_deformation(a.deformation, a.memory_limit_gib * csrbf::kGiB / 16.0);
    area = std::move(spec.area);
    phase = spec.phase;
    if (area && mesh) csrbf::io::check_active_area(*area, mesh->positions(), a.deformation, mesh_name);
    controls.sources = spec.sources;
    controls.destinations = spec.destinations;
    controls.name = a.deformation;
    o = spec.options;
  } else {
    // A control's text (about 100 bytes) takes less once parsed: the text within the memory limit.
    controls = csrbf::io::read_controls(a.controls, a.memory_limit_gib * csrbf::kGiB);
    o.radius = a.radius;
    o.kernel = *csrbf::parse_kernel(a.kernel);
    o.polynomial = *csrbf::parse_polynomial(a.polynomial);
  }
  for (const auto& w : controls.warnings) std::cerr << "csrbf: warning: " << csrbf::printable(w) << '\n';
  o.ordering = *csrbf::parse_ordering(a.ordering);
  // --memory-limit bounds the whole process: the fit gets what the program, the mesh and the
  // controls leave of it.
  o.memory_limit_bytes =
      distributed ? a.memory_limit_gib * csrbf::kGiB
                  : std::max(1.0, csrbf::io::memory_left(a.memory_limit_gib * csrbf::kGiB) - a.reserve_bytes);
  o.solver = distributed && a.solver == "mumps" ? csrbf::Solver::Auto : csrbf::cli::serial_solver(a.solver);
  if (o.ordering != csrbf::Ordering::Auto && (o.solver == csrbf::Solver::Eigen || o.solver == csrbf::Solver::Cholmod))
    throw csrbf::UsageError("--ordering " + a.ordering + ": solver '" + a.solver +
                            "' orders the matrix itself; --ordering applies to the envelope solver and cg");
  return {std::move(controls), o, std::move(area), phase};
}

Fitted fit(const FitArgs& a, const csrbf::io::MeshDocument* mesh, const std::string& mesh_name) {
  auto [controls, o, area, phase] = read_fit_input(a, mesh, mesh_name);
  // Where control i came from: "file:line" for controls text, "file: sources[i]" for JSON.
  const bool json_file = !a.deformation.empty();
  const auto where = [&](std::size_t i) {
    return json_file ? controls.name + ": sources[" + std::to_string(i) + "]"
                     : controls.name + ":" + std::to_string(controls.lines[i]);
  };
  const auto which = [&](std::size_t i) {
    return json_file ? "sources[" + std::to_string(i) + "]" : "line " + std::to_string(controls.lines[i]);
  };
  try {
    return {controls, csrbf::SpaceMap::fit(controls.sources, controls.destinations, o), std::move(area), phase};
  } catch (const csrbf::DuplicateSource& e) {
    throw csrbf::io::FileError(where(e.second()) + ": source is the same as on " + which(e.first()));
  } catch (const csrbf::NotPositiveDefinite& e) {
    if (e.row() >= controls.sources.size()) throw csrbf::io::FileError(controls.name + ": " + e.what());
    throw csrbf::io::FileError(
        where(e.row()) + ": the interpolation matrix is not numerically positive definite at this control (pivot " +
        csrbf::io::format_number(e.pivot()) + "); sources too close together for R = " +
        csrbf::io::format_number(o.radius) + ": merge or separate them, or use a smaller radius");
  } catch (const csrbf::ResourceLimit& e) {
    throw csrbf::io::FileError(controls.name + ": " + e.what() +
                               csrbf::io::memory_share(a.memory_limit_gib * csrbf::kGiB, o.memory_limit_bytes));
  } catch (const csrbf::Error& e) {  // bad input
    throw csrbf::io::FileError(controls.name + ": " + e.what());
  }
}

}  // namespace csrbf::cli
