#include "morph.hpp"

#include "animate.hpp"
#include "commands.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/names.hpp"

#include <iostream>

namespace csrbf::cli {

CLI::App* add_morph_command(CLI::App& app, MorphArgs& a) {
  auto* cmd =
      app.add_subcommand("morph",
                         "Move the patches of a volume mesh as a motion file says and carry every other point along "
                         "(docs/morphing.md)");
  cmd->add_option("mesh", a.mesh,
                  "An OpenFOAM case folder (or its constant/polyMesh), a .vtu or .vtk unstructured grid, a Gmsh .msh "
                  "(2.2 or 4.1) or a .cgns file")
      ->required();
  auto* out = cmd->add_option("-o,--output", a.out,
                              "A new case folder (OpenFOAM: a copy of the case with the moved points) or a new file of "
                              "the input's format; -o or --in-place is required");
  auto* in_place =
      cmd->add_flag("--in-place", a.in_place,
                    "Rewrite the input with the moved points, atomically (OpenFOAM: its points file alone)");
  out->excludes(in_place);
  cmd->add_option("--motion", a.motion, "Motion JSON: what each patch does (docs/morphing.md)")->required();
  cmd->add_option("--radius,-r", a.radius, "Radius of support R (overrides the motion file's)")
      ->check(finite_in(1e-150, 1e150, "--radius"));
  cmd->add_option("--kernel,-k", a.kernel, "Wendland kernel c0, c2, c4, c6 (overrides the motion file's; default c2)")
      ->transform(CLI::IsMember(csrbf::names<csrbf::Kernel>(), CLI::ignore_case));
  cmd->add_option("--polynomial,-p", a.polynomial,
                  "Polynomial part none, constant, linear (overrides the motion file's; default none)")
      ->transform(CLI::IsMember(csrbf::names<csrbf::Polynomial>(), CLI::ignore_case));
  cmd->add_option("--greedy", a.greedy,
                  "Greedy reduction: use the fewest boundary points as controls that interpolate every one within "
                  "TOL x the largest displacement (e.g. 1e-3)")
      ->check(finite_in(1e-15, 1.0, "--greedy"));
  cmd->add_option("--phase,-t", a.phase, "Fraction of the motion applied, in [0, 1]")
      ->check(finite_in(0.0, 1.0, "--phase"))
      ->capture_default_str();
  cmd->add_option("--solver", a.solver, "Solver of the fit: auto, envelope, eigen, cholmod, cg")
      ->transform(CLI::IsMember(csrbf::names<csrbf::Solver>(), CLI::ignore_case))
      ->capture_default_str();
  cmd->add_option("--memory-limit", a.memory_limit_gib, "Refuse fits that would need more than this many GiB")
      ->check(finite_in(1e-6, 1e6, "--memory-limit"))
      ->capture_default_str();
  cmd->add_flag("--json", a.json, "Print the report as one JSON object");
  cmd->add_flag("--force", a.force, "Write the mesh even if the morph inverts cells");
  return cmd;
}

int run_morph(const MorphArgs& a) {
  morph::MorphJob job;
  job.mesh = a.mesh;
  job.motion = a.motion;
  job.out = a.out;
  job.in_place = a.in_place;
  if (a.out.empty() && !a.in_place) throw UsageError("morph: give -o OUT (a new case folder or file) or --in-place");
  job.radius = a.radius;
  if (!a.kernel.empty()) job.kernel = *parse_name<Kernel>(a.kernel);
  if (!a.polynomial.empty()) job.polynomial = *parse_name<Polynomial>(a.polynomial);
  job.greedy = a.greedy;
  job.solver = *parse_name<Solver>(a.solver);
  job.phase = a.phase;
  job.memory_limit_bytes = a.memory_limit_gib * double(1ull << 30);
  job.force = a.force;
  morph::MorphOutcome o;
  try {
    o = morph::run_job(job);
  } catch (const morph::JobError& e) {
    throw UsageError(std::string("morph: ") + e.what());
  }
  std::cout << (a.json ? morph::outcome_json(o) + "\n" : morph::outcome_text(o));
  if (o.inverts && !o.written) {
    std::cerr << "csrbf: error: the morph inverts " << o.after.inverted_cells() - o.before.inverted_cells()
              << " cells (" << o.after.inverted_cells() << " inverted, " << o.before.inverted_cells()
              << " before); the largest phase <= " << a.phase << " that inverts none is " << o.safe_phase
              << "; nothing written (--force writes anyway)\n";
    return 1;
  }
  return 0;
}

}  // namespace csrbf::cli
