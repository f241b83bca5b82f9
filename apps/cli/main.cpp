// csrbf: the command-line program. Exit 0 on success, 2 on a usage error, 1 on bad data or failure.
#include "animate.hpp"
#include "export.hpp"
#include "bench.hpp"
#include "commands.hpp"
#include "program.hpp"
#include "morph.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/estimate.hpp"
#include "csrbf/folds.hpp"
#include "csrbf/names.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/version.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#ifdef CSRBF_WITH_MPI
#include "csrbf/mpi/backends.hpp"
#include "csrbf/mpi/runtime.hpp"
#include "csrbf/units.hpp"
#endif

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>
#include <csignal>
#include <chrono>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <sstream>

namespace {

using csrbf::cli::finite_in;

struct FitArgs {
  std::string controls, deformation;
  double radius = 0;
  std::string kernel = "c2", polynomial = "none", ordering = "auto", solver = "auto";
  double memory_limit_gib = 4.0;
  double reserve_bytes = 0;  ///< of the limit, kept from the fit for what follows it (assimp's writer)
};

/// The files deform reads: the mesh, the controls or the deformation and the files it names.
std::vector<std::filesystem::path> deform_inputs(const FitArgs& a, const std::string& mesh) {
  std::vector<std::filesystem::path> in{mesh};
  for (auto& f : csrbf::io::mesh_side_files(mesh, a.memory_limit_gib * csrbf::kGiB)) in.push_back(std::move(f));
  if (!a.controls.empty()) in.emplace_back(a.controls);
  if (!a.deformation.empty())
    for (auto& f : csrbf::io::referenced_files(a.deformation, a.memory_limit_gib * csrbf::kGiB))
      in.push_back(std::move(f));
  return in;
}

CLI::Validator positive_finite(const char* what) {
  // The radius is limited as SpaceMap::fit limits it, so that a bad value is a usage error (2).
  return finite_in(1e-150, 1e150, what);
}

/// --memory-limit of the commands that read a scene: its meshes, deformation files and fits.
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

struct Fitted {
  csrbf::io::Controls controls;
  csrbf::SpaceMap map;
  std::optional<csrbf::io::ActiveArea> area;  // the deformation file's active area, if any
  std::optional<double> phase;                // the deformation file's phase, if any
};

struct FitInput {
  csrbf::io::Controls controls;
  csrbf::FitOptions options;
  std::optional<csrbf::io::ActiveArea> area;
  std::optional<double> phase;  // the deformation file's
};

/// The controls or deformation file and the fit's options; a deformation's active area is checked
/// against `mesh` (when given) before the fit, which may take long.
FitInput read_fit_input(const FitArgs& a, const csrbf::io::MeshDocument* mesh, const std::string& mesh_name,
                        bool distributed = false) {
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
    throw csrbf::cli::UsageError("--ordering " + a.ordering + ": solver '" + a.solver +
                                 "' orders the matrix itself; --ordering applies to the envelope solver and cg");
  return {std::move(controls), o, std::move(area), phase};
}

/// The fit of the controls or deformation file.
Fitted fit(const FitArgs& a, const csrbf::io::MeshDocument* mesh = nullptr, const std::string& mesh_name = {}) {
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

struct DeformArgs {
  std::string mesh_in, mesh_out;
  double phase = 1.0;
  bool phase_given = false;  // else a deformation file's phase, where it has one
  bool json = false;
};

#ifdef CSRBF_WITH_MPI
/// `mpirun -np K csrbf deform` (K > 1): rank 0 reads the mesh and the controls, the fit and the
/// evaluation are spread over the ranks (csrbf::mpi::ScatterBackend), rank 0 writes. The other
/// ranks serve until rank 0 is done, and exit with its status.
int deform_distributed(csrbf::mpi::Runtime& rt, const FitArgs& fa, const DeformArgs& da) {
  namespace mpi = csrbf::mpi;
  if (rt.rank() != 0) return mpi::serve(rt.comm());
  const auto solver = mpi::parse_distributed_solver(fa.solver);
  mpi::ScatterBackend backend(rt.comm(), solver.value_or(mpi::DistributedSolver::Auto));
  int code = 0;
  try {
    csrbf::io::check_output_path(csrbf::io::resolve_output(da.mesh_out));
    csrbf::cli::check_not_an_input("-o", da.mesh_out, deform_inputs(fa, da.mesh_in));
    csrbf::io::must_be_new(csrbf::io::resolve_output(da.mesh_out));
    if (csrbf::io::format_for(da.mesh_out) == csrbf::io::MeshFormat::Assimp)
      throw csrbf::cli::UsageError("-o: unknown output format '" +
                                   std::filesystem::path(da.mesh_out).extension().string() +
                                   "' (use .obj, .ply, .off, .xyz, .stl, .gltf or .glb)");
    const auto t0 = std::chrono::steady_clock::now();
    auto mesh = csrbf::io::MeshDocument::load(da.mesh_in, fa.memory_limit_gib * csrbf::kGiB);
    FitInput in = read_fit_input(fa, &mesh, da.mesh_in, true);
    const double phase = !da.phase_given && in.phase ? *in.phase : da.phase;
    auto& p = mesh.positions();
    std::vector<csrbf::Vec3> part;  // the active area's vertices, or all
    if (in.area)
      for (const auto v : in.area->vertices) part.push_back(p.at(v));
    std::span<const csrbf::Vec3> evaluated =
        in.area ? std::span<const csrbf::Vec3>(part) : std::span<const csrbf::Vec3>(p);
    backend.balance(evaluated);
    std::vector<std::uint64_t> ids(in.controls.sources.size());
    for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = in.controls.lines.empty() ? i : in.controls.lines[i];
    auto mapping = backend.fit(in.controls.sources, in.controls.destinations, in.options, ids);
    std::vector<csrbf::Vec3> moved(evaluated.size());
    mapping->apply(evaluated, moved, phase);
    std::size_t count = 0;
    for (std::size_t i = 0; i < moved.size(); ++i) {
      const std::size_t v = in.area ? in.area->vertices[i] : i;
      count += p[v] != moved[i];
      p[v] = moved[i];
    }
    const auto t1 = std::chrono::steady_clock::now();
    mesh.save(da.mesh_out);
    const auto ranks = backend.rank_stats();
    const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
    if (da.json) {
      nlohmann::json j{{"vertices", p.size()},
                       {"moved", count},
                       {"controls", backend.stats().controls},
                       {"ranks", ranks.size()},
                       {"solver", mpi::distributed_solver_name(backend.stats().solver)},
                       {"iterations", backend.stats().iterations},
                       {"residual_relative", backend.stats().residual_relative},
                       {"ms", ms},
                       {"per_rank", csrbf::cli::rank_stats_json(ranks)}};
      std::cout << j.dump(2) << '\n';
    } else {
      std::cout << "csrbf deform: " << p.size() << " vertices (" << count << " moved) of "
                << csrbf::printable(da.mesh_in) << " by " << backend.stats().controls << " controls on " << ranks.size()
                << " ranks (" << mpi::distributed_solver_name(backend.stats().solver) << "), R = " << in.options.radius
                << ", phase " << phase << " -> " << csrbf::printable(da.mesh_out) << " (" << ms << " ms)\n";
    }
  } catch (const csrbf::cli::UsageError& e) {
    std::cerr << "csrbf: error: " << csrbf::printable(e.what()) << '\n';
    code = 2;
  } catch (const mpi::Failure& e) {
    std::cerr << "csrbf: error: " << csrbf::printable(e.what())
              << (e.rank() ? " (rank " + std::to_string(e.rank()) + ")" : "") << '\n';
    code = e.exit_code();
  } catch (const std::bad_alloc&) {
    std::cerr << "csrbf: error: out of memory on rank 0 (it holds the whole mesh: docs/DISTRIBUTED.md)\n";
    code = 1;
  } catch (const std::exception& e) {
    std::cerr << "csrbf: error: " << csrbf::printable(e.what()) << '\n';
    code = 1;
  }
  backend.finish(code);
  return code;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  csrbf::cli::start_program(argv);
  CLI::App app{"csrbf: real-time 3D deformation by compactly supported radial basis functions (Wendland CSRBF)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("csrbf ") + csrbf::kVersion);

  FitArgs deform_args;
  DeformArgs da;
  std::string& mesh_in = da.mesh_in;
  std::string& mesh_out = da.mesh_out;
  double& phase = da.phase;
  auto* deform = app.add_subcommand("deform", "Deform a mesh by the space mapping the controls define");
  deform->add_option("--mesh,-m", mesh_in, "Input mesh: .obj .ply .off .xyz (order kept), .stl .gltf .glb (assimp)")
      ->required();
  add_fit_options(deform, deform_args);
  deform->add_option("--phase,-t", phase, "Phase t in [0, 1]: each point moves to x + t d(x)")
      ->check(finite_in(0.0, 1.0, "--phase"))
      ->capture_default_str();
  deform->add_option("-o,--output", mesh_out, "Output mesh; its extension sets the format")->required();
  deform->add_flag("--json", da.json, "Print one JSON object (with each MPI rank's figures under mpirun)");

  csrbf::cli::BenchOptions bench_opts;
  auto* bench = app.add_subcommand("bench", "Run a benchmark scenario and print medians (docs/PERFORMANCE.md)");
  std::vector<std::string> scenario_names = csrbf::cli::bench_scenarios();
  scenario_names.push_back("all");
  bench->add_option("--scenario,-s", bench_opts.scenario, "fish, face, ball, scale, solvers, peers or all")
      ->required()
      ->check(CLI::IsMember(scenario_names));
  bench->add_flag("--json", bench_opts.json, "One JSON object a line");
  bench->add_flag("--quick", bench_opts.quick, "Smaller sweeps (scale, solvers, peers)");
  bench
      ->add_option("--controls", bench_opts.controls,
                   "solvers: only these N (e.g. --controls 1e5), default 1e3 ... 1e6")
      ->check(CLI::Range(10.0, 1e7));
  bench->add_option("--geometry", bench_opts.geometry, "solvers: only 'sphere' or 'cube' (default both)")
      ->check(CLI::IsMember({"sphere", "cube"}));
  bench
      ->add_option("--threads", bench_opts.threads,
                   "Threads (default: 1 for fish/face/ball, all for scale/solvers/peers)")
      ->check(CLI::Range(1, 1024));
  bench->add_option("--seconds", bench_opts.seconds, "Time spent on each measured quantity")
      ->check(finite_in(0.0, 60.0, "--seconds"))
      ->capture_default_str();
  bench
      ->add_option("--loop", bench_opts.loop, "Evaluation loop: auto, portable or avx512 (each row names the one used)")
      ->check(CLI::IsMember({"auto", "portable", "avx512"}))
      ->capture_default_str();
  bench->add_option("--data", bench_opts.data_dir,
                    "Folder with fish.obj, face.obj and their .controls (default: bundled)");

  csrbf::cli::ExportOptions export_opts;
  auto* exporter = app.add_subcommand(
      "export", "Write a scene as glTF 2.0 for game engines, Blender and web pages (docs/export.md)");
  exporter->add_option("scene", export_opts.scene, "Scene JSON file")->required();
  exporter->add_option("-o,--output", export_opts.out, "OUT.glb (binary) or OUT.gltf (one JSON file)")->required();
  exporter->add_option("--fps", export_opts.fps, "Sampling rate of what is sampled or baked (default: the scene's)")
      ->check(finite_in(0.1, 1000.0, "--fps"));
  exporter
      ->add_option("--bake", export_opts.bake,
                   "auto: bake what morph targets cannot hold exactly; always: every deforming part; never: refuse")
      ->capture_default_str();
  exporter->add_option("--html", export_opts.html,
                       "Also write a new folder DIR with index.html, the .glb and three.js: a page that plays it");
  exporter
      ->add_option("--compact", export_opts.compact,
                   "Also write each exactly held deformation as CSRBF_deformation (docs/gltf/CSRBF_deformation.md): "
                   "--compact keeps the morph targets as fallback, --compact=only replaces them")
      ->expected(0, 1);
  exporter->add_flag("--meshopt", export_opts.meshopt,
                     "Compress vertex, index and animation data with meshoptimizer (EXT_meshopt_compression, "
                     "required: three.js, Babylon.js and gltfpack read it, Blender 3.4 does not)");
  exporter->add_flag("--quantize", export_opts.quantize,
                     "Positions and displacements as 16-bit, normals as 8-bit integers (KHR_mesh_quantization, "
                     "required); not with --compact");
  exporter->add_flag("--json", export_opts.json, "Print the report as one JSON object");
  add_scene_memory_limit(exporter, export_opts.memory_limit_gib);

  FitArgs info_args;
  bool json = false;
  csrbf::cli::AnimateOptions anim_opts;
  auto* animate =
      app.add_subcommand("animate", "Render a scene file to a movie, without a display (docs/scene-format.md)");
  animate->add_option("scene", anim_opts.scene, "Scene JSON file")->required();
  animate
      ->add_option("-o,--output", anim_opts.out,
                   "Movie: .mp4 (H.264), .avi (full uncompressed frames) or a folder of numbered PNG frames")
      ->required();
  animate->add_option("--fps", anim_opts.fps, "Frames per second (default: the scene's)")
      ->check(finite_in(0.1, 1000.0, "--fps"));
  animate->add_option("--size", anim_opts.size, "Frame size WIDTHxHEIGHT")->capture_default_str();
  animate->add_option("--from", anim_opts.from, "Start time in seconds (default 0)")
      ->check(finite_in(-1e6, 1e6, "--from"));
  animate->add_option("--to", anim_opts.to, "End time in seconds (default: the scene's duration)")
      ->check(finite_in(-1e6, 1e6, "--to"));
  animate->add_flag("--private-display", anim_opts.private_display,
                    "Render on a private Xvfb even when DISPLAY is set (one is started anyway when it is not)");
  add_scene_memory_limit(animate, anim_opts.memory_limit_gib);

  auto* info = app.add_subcommand("info", "Fit the controls and print the solver's statistics");
  add_fit_options(info, info_args);
  info->add_flag("--json", json, "Print one JSON object");
  std::string info_mesh;
  bool check_folds = false;
  double info_phase = 1.0;
  info->add_option("--mesh", info_mesh, "Mesh to check for folds (with --check-folds)");
  auto* folds_flag = info->add_flag("--check-folds", check_folds,
                                    "Report det(dT/dx) over the mesh's vertices and points inside its triangles: "
                                    "the minimum, where it is <= 0, and the largest fold-free phase");
  info->add_option("--phase", info_phase, "Phase at which folds are counted (default 1)")
      ->check(finite_in(-1e6, 1e6, "--phase"));
  bool info_estimate = false;
  double info_neighbours = 0;
  auto* estimate_flag = info->add_flag(
      "--estimate", info_estimate,
      "Do not fit: print what the fit would cost (neighbours, non-zeros, each solver's memory and time)");
  auto* neighbours_opt =
      info->add_option("--neighbours", info_neighbours,
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

  csrbf::cli::MorphArgs morph_args;
  auto* morph = csrbf::cli::add_morph_command(app, morph_args);
  double time_limit = 0;
  for (CLI::App* cmd : {deform, info, morph, exporter, animate}) csrbf::cli::add_time_limit(cmd, time_limit);

#ifdef CSRBF_WITH_MPI
  // Under mpirun with more than one rank: MPI starts first; every rank parses, rank 0 alone speaks,
  // and the others wait for it before they leave (else mpirun may end rank 0 before it has spoken).
  std::optional<csrbf::mpi::Runtime> rt;
  if (csrbf::mpi::launched_ranks() > 1) rt.emplace(&argc, &argv);
  const bool quiet = rt && rt->rank() != 0;
  const auto leave = [&](int code) {
    if (rt) MPI_Barrier(rt->comm());
    return code;
  };
#else
  const bool quiet = false;
  const auto leave = [](int code) { return code; };
#endif
  csrbf::cli::openfoam_spellings(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return leave(csrbf::cli::parse_failed(app, e, quiet));
  }
  csrbf::io::limit_time(time_limit, !quiet);
#ifdef CSRBF_WITH_MPI
  if (rt) {
    if (!*deform && !*morph) {
      if (!quiet)
        std::cerr << "csrbf: error: " << app.get_subcommands().front()->get_name()
                  << " runs on one process; under mpirun with more than one rank, csrbf runs deform and morph\n";
      return leave(2);
    }
    da.phase_given = deform->count("--phase") > 0;
    return leave(*deform ? deform_distributed(*rt, deform_args, da)
                         : csrbf::cli::run_morph_distributed(morph_args, *rt));
  }
#endif

  return csrbf::cli::run_command([&]() -> int {
    if (*deform) {
      csrbf::io::check_output_path(csrbf::io::resolve_output(mesh_out));
      csrbf::cli::check_not_an_input("-o", mesh_out, deform_inputs(deform_args, mesh_in));
      csrbf::io::must_be_new(csrbf::io::resolve_output(mesh_out));
      if (csrbf::io::format_for(mesh_out) == csrbf::io::MeshFormat::Assimp)
        throw csrbf::cli::UsageError("-o: unknown output format '" +
                                     std::filesystem::path(mesh_out).extension().string() +
                                     "' (use .obj, .ply, .off, .xyz, .stl, .gltf or .glb)");
      const auto t0 = std::chrono::steady_clock::now();
      auto mesh = csrbf::io::MeshDocument::load(mesh_in, deform_args.memory_limit_gib * csrbf::kGiB);
      {
        // assimp's writers build the scene again and copy it (measured, 500k vertices and 1M
        // faces, and 1M and 200k: glTF 290 bytes a vertex and 270 a face, STL 25 and 210), with a
        // tenth more: kept from the fit, and refused where the limit cannot hold them.
        const auto out_format = csrbf::io::format_for(mesh_out);
        const double v = double(mesh.positions().size()), fc = double(mesh.faces().size());
        const double write = out_format == csrbf::io::MeshFormat::Stl ? 1.1 * (25 * v + 210 * fc)
                             : out_format == csrbf::io::MeshFormat::Gltf || out_format == csrbf::io::MeshFormat::Glb
                                 ? 1.1 * (290 * v + 270 * fc)
                                 : 0.0;
        const double limit = deform_args.memory_limit_gib * csrbf::kGiB;
        if (write > 0 && write > csrbf::io::memory_left(limit)) {
          std::ostringstream m;
          m.precision(3);
          m << csrbf::printable(mesh_out) << ": writing " << mesh.positions().size() << " vertices and "
            << mesh.faces().size() << " faces as " << csrbf::io::format_name(out_format) << " takes about "
            << write / csrbf::kGiB << " GiB (assimp's copies of the mesh), more than --memory-limit "
            << deform_args.memory_limit_gib << " GiB leaves after the mesh; give --memory-limit "
            << std::ceil(100 * (write + csrbf::io::resident_bytes()) / csrbf::kGiB) / 100
            << " or more, or write .ply or .obj";
          throw csrbf::io::FileError(m.str());
        }
        deform_args.reserve_bytes = write;
      }
      Fitted f = fit(deform_args, &mesh, mesh_in);
      if (deform->count("--phase") == 0 && f.phase) phase = *f.phase;  // as it was seen in the Picker
      auto& p = mesh.positions();
      const std::vector<csrbf::Vec3> before = p;
      csrbf::io::apply_deformation(f.map, f.area, p, phase);
      const auto t1 = std::chrono::steady_clock::now();
      mesh.save(mesh_out);
      std::size_t moved = 0;
      for (std::size_t i = 0; i < p.size(); ++i) moved += p[i] != before[i];
      if (da.json) {
        nlohmann::json j{{"vertices", p.size()},
                         {"moved", moved},
                         {"controls", f.map.size()},
                         {"ranks", 1},
                         {"ms", std::chrono::duration<double, std::milli>(t1 - t0).count()},
                         {"fit", csrbf::cli::stats_json(f.map)}};
        std::cout << j.dump(2) << '\n';
        return 0;
      }
      std::cout << "csrbf deform: " << p.size() << " vertices (" << moved << " moved) of " << csrbf::printable(mesh_in)
                << " by " << f.map.size() << " controls, R = " << f.map.radius() << ", kernel "
                << csrbf::kernel_name(f.map.kernel()) << ", polynomial " << csrbf::polynomial_name(f.map.polynomial())
                << ", phase " << phase
                << (f.area ? ", active area of " + std::to_string(f.area->vertices.size()) + " vertices"
                           : std::string())
                << " -> " << csrbf::printable(mesh_out) << " ("
                << std::chrono::duration<double, std::milli>(t1 - t0).count() << " ms)\n";
    } else if (*morph) {
      return csrbf::cli::run_morph(morph_args);
    } else if (*animate) {
      return csrbf::cli::run_animate(anim_opts);
    } else if (*exporter) {
      export_opts.html_given = exporter->count("--html") > 0;
      export_opts.compact_given = exporter->count("--compact") > 0;
      return csrbf::cli::run_export(export_opts);
    } else if (*bench) {
      csrbf::cli::run_bench(bench_opts);
    } else if (*info) {
      if (info_args.deformation.empty() && (info_args.radius > 0) == (info_neighbours > 0))
        throw csrbf::cli::UsageError("info: give --controls with --radius or with --neighbours");
      if (info_neighbours > 0 || info_estimate) {
        if (info_neighbours > 0) info_args.radius = 1.0;  // replaced below
        auto input = read_fit_input(info_args, nullptr, {});
        const std::span<const csrbf::Vec3> s = input.controls.sources;
        if (info_neighbours > 0) {
          if (!(info_neighbours < double(s.size()) - 1))
            throw csrbf::cli::UsageError("--neighbours: " + csrbf::io::format_number(info_neighbours) +
                                         " is not below " + std::to_string(s.size()) + " controls less one");
          input.options.radius = csrbf::suggest_radius(s, info_neighbours);
        }
        nlohmann::json j{{"radius", input.options.radius}, {"controls", s.size()}};
        if (info_neighbours > 0) j["neighbours_asked"] = info_neighbours;
        if (info_estimate)
          j["estimate"] = csrbf::cli::estimate_json(csrbf::estimate(s, input.options.radius, input.options));
        if (json)
          std::cout << j.dump(2) << '\n';
        else
          std::cout << csrbf::cli::estimate_text(j);
        return 0;
      }
      std::optional<csrbf::io::MeshDocument> mesh;
      if (check_folds) mesh.emplace(csrbf::io::MeshDocument::load(info_mesh, info_args.memory_limit_gib * csrbf::kGiB));
      Fitted f = fit(info_args, mesh ? &*mesh : nullptr, info_mesh);
      std::optional<csrbf::FoldReport> folds;
      if (check_folds) {
        if (f.area) {  // the vertices the deformation moves, and the triangles across the area's edge
          folds = csrbf::check_folds_in_area(f.map, mesh->positions(), mesh->faces(), f.area->vertices, info_phase);
        } else {
          folds = csrbf::check_folds(f.map, mesh->positions(), mesh->faces(), info_phase);
        }
      }
      if (json) {
        auto j = csrbf::cli::stats_json(f.map);
        if (folds) j["folds"] = csrbf::cli::folds_json(*folds);
        std::cout << j.dump(2) << '\n';
      } else {
        std::cout << csrbf::cli::stats_text(f.map);
        if (folds) std::cout << csrbf::cli::folds_text(*folds);
      }
    }
    return 0;
  });
}
