#include "morph.hpp"

#include "animate.hpp"
#include "commands.hpp"
#include "progress.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
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
  auto* motion = cmd->add_option("--motion", a.motion, "Motion JSON: what each patch does (docs/morphing.md)");
  auto* series = cmd->add_option(
      "--motion-series", a.motion_series,
      "OpenFOAM: a folder of motion files named by time (0.1.json, 0.2.json, ...), each from the mesh read; each "
      "time's moved points go into that time's polyMesh, one matrix factorised for all where R and the controls "
      "stay the same");
  motion->excludes(series);
  cmd->add_option("--radius,-r", a.radius,
                  "Radius of support R, or auto: chosen from the motion's largest displacement, the boundary's "
                  "spacing and --memory-limit, and the report says why (auto is the default where the motion "
                  "file gives no radius; R overrides the motion file's)")
      ->check(CLI::IsMember({"auto"}) | finite_in(1e-150, 1e150, "--radius"));
  cmd->add_option("--kernel,-k", a.kernel, "Wendland kernel c0, c2, c4, c6 (overrides the motion file's; default c2)")
      ->transform(CLI::IsMember(csrbf::names<csrbf::Kernel>(), CLI::ignore_case));
  cmd->add_option("--polynomial,-p", a.polynomial,
                  "Polynomial part none, constant, linear (overrides the motion file's; default none)")
      ->transform(CLI::IsMember(csrbf::names<csrbf::Polynomial>(), CLI::ignore_case));
  cmd->add_option("--greedy", a.greedy,
                  "Greedy reduction: use the fewest boundary points as controls that interpolate every one within "
                  "TOL x the largest displacement (e.g. 1e-3)")
      ->check(finite_in(1e-15, 1.0, "--greedy"));
  auto* greedy_budget =
      cmd->add_option(
             "--greedy-budget", a.greedy_budget,
             "Greedy's rounds may take this fraction of the plain fit and evaluation's predicted time (at least "
             "0.1 s); past it greedy stops and every control is fitted, so greedy never costs more than about "
             "1 + this times the plain morph")
          ->check(finite_in(0.0, 1e6, "--greedy-budget"))
          ->capture_default_str();
  greedy_budget->needs(cmd->get_option("--greedy"));
  cmd->add_option("--levels", a.levels,
                  "The fit's levels: 1, every control at R; 2, a coarse fit at R of controls R/4 apart, then every "
                  "control's remainder at about 1.75 x the boundary's spacing (a fraction of the time at a large R; "
                  "polynomial none, one process); auto, two where one level would pass its memory budget, or is "
                  "predicted to take 10 s or more and 4 x the two levels' time (the report says why)")
      ->check(CLI::IsMember({"auto", "1", "2"}))
      ->capture_default_str();
  cmd->add_option("--phase,-t", a.phase, "Fraction of the motion applied, in [0, 1]")
      ->check(finite_in(0.0, 1.0, "--phase"))
      ->capture_default_str();
  cmd->add_option("--solver", a.solver, "Solver of the fit: auto, envelope, eigen, cholmod, cg")
      ->transform(CLI::IsMember(solver_choices(), CLI::ignore_case))
      ->capture_default_str();
  cmd->add_option(
         "--memory-limit", a.memory_limit_gib,
         "The most memory csrbf may hold, in GiB: fits that would need more than what the program and the mesh "
         "leave of it are refused")
      ->check(finite_in(1e-6, 1e6, "--memory-limit"))
      ->capture_default_str();
  cmd->add_option("--time", a.time,
                  "OpenFOAM: morph the mesh of this time folder, latest or a time (0.5), and write the moved "
                  "points there; a time without its own polyMesh has the latest earlier time's, else constant's, as "
                  "OpenFOAM reads it. Also "
                  "spelled -time T and -latestTime, as OpenFOAM's utilities take them")
      ->check(CLI::Validator(
          [](std::string& v) {
            return v.empty() ? std::string("--time: give a time (0.5) or latest, not nothing") : std::string();
          },
          "TIME"));
  cmd->add_flag("--json", a.json, "Print the report as one JSON object");
  cmd->add_flag("--quiet,-q", a.quiet,
                "No progress on the terminal (bars of the phases longer than a second, the radius chosen, the "
                "prediction); the report is printed all the same");
  cmd->add_flag("--force", a.force, "Write the mesh even if the morph inverts cells");
  return cmd;
}

morph::MorphJob job_of(const MorphArgs& a, bool distributed) {
  morph::MorphJob job;
  job.mesh = a.mesh;
  job.motion = a.motion;
  job.motion_series = a.motion_series;
  if (a.motion.empty() && a.motion_series.empty())
    throw UsageError("morph: give --motion FILE (or --motion-series DIR, a motion a time)");
  if (distributed && !a.motion_series.empty())
    throw UsageError("morph: --motion-series runs in one process: run it without mpirun");
  job.out = a.out;
  job.in_place = a.in_place;
  if (a.out.empty() && !a.in_place) throw UsageError("morph: give -o OUT (a new case folder or file) or --in-place");
  if (a.radius == "auto")
    job.radius_auto = true;
  else if (!a.radius.empty())
    job.radius = std::stod(a.radius);
  if (!a.kernel.empty()) job.kernel = *parse_name<Kernel>(a.kernel);
  if (!a.polynomial.empty()) job.polynomial = *parse_name<Polynomial>(a.polynomial);
  job.greedy = a.greedy;
  job.greedy_budget = a.greedy_budget;
  job.levels = a.levels == "auto" ? 0 : std::stoi(a.levels);
  if (distributed && job.levels == 2)
    throw UsageError(
        "morph: --levels 2 runs in one process (under mpirun a later fit replaces the ranks' mapping): "
        "run it without mpirun");
  job.solver = distributed && a.solver == "mumps" ? Solver::Auto : serial_solver(a.solver);
  job.phase = a.phase;
  job.memory_limit_bytes = a.memory_limit_gib * kGiB;
  job.force = a.force;
  job.time = a.time;
  return job;
}

int report_inversion(const MorphArgs& a, const morph::MorphOutcome& o, bool speak) {
  if (o.inverts && !o.written) {
    if (speak)
      std::cerr << "csrbf: error: the morph inverts " << o.after.inverted_cells() - o.before.inverted_cells()
                << " cells (" << o.after.inverted_cells() << " inverted, " << o.before.inverted_cells()
                << " before); the largest phase <= " << a.phase << " that inverts none is " << o.safe_phase
                << "; nothing written (--force writes anyway"
                << (o.result.report.levels == 2 ? "; the fit took two levels, whose cells beside the walls are poorer: "
                                                  "--levels 1 may invert none"
                                                : "")
                << ")\n";
    return 1;
  }
  return 0;
}

int run_morph(const MorphArgs& a) {
  const morph::MorphJob job = job_of(a, false);
  {
    std::error_code ec;
    if (std::filesystem::is_directory(std::filesystem::path(a.mesh) / "processor0", ec))
      std::cerr << "csrbf: warning: " << csrbf::printable(a.mesh)
                << " is decomposed (processor folders): one process morphs its constant/polyMesh and "
                   "leaves the processor folders as they are; mpirun -np PROCESSORS csrbf morph morphs them\n";
  }
  TerminalProgress progress(!a.quiet && TerminalProgress::terminal());
  morph::MorphJob job_shown = job;
  job_shown.progress = &progress;
  if (!job.motion_series.empty()) {
    const morph::SeriesOutcome s = usage_errors([&] { return morph::run_series(job_shown); });
    progress.end();
    std::cout << (a.json ? morph::series_json(s) + "\n" : csrbf::printable(morph::series_text(s), true));
    if (!s.steps.empty() && s.steps.back().inverts && !s.written) {
      const morph::MorphOutcome& o = s.steps.back();
      std::cerr << "csrbf: error: time " << o.time << " (" << o.motion << "): the morph inverts "
                << o.after.inverted_cells() - o.before.inverted_cells() << " cells; the largest phase <= " << a.phase
                << " that inverts none is " << o.safe_phase << "; no time written (--force writes anyway)\n";
      return 1;
    }
    return 0;
  }
  const morph::MorphOutcome o = usage_errors([&] { return morph::run_job(job_shown); });
  progress.end();
  std::cout << (a.json ? morph::outcome_json(o) + "\n" : csrbf::printable(morph::outcome_text(o), true));
  return report_inversion(a, o, true);
}

}  // namespace csrbf::cli
