#include "morph.hpp"

#include "animate.hpp"
#include "commands.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "csrbf/morph/quality.hpp"
#include "csrbf/names.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

namespace fs = std::filesystem;

namespace csrbf::cli {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

nlohmann::json quality_json(const morph::PolyQuality& q) {
  return {{"cells", q.cells},
          {"faces", q.faces},
          {"max_non_orthogonality", q.max_non_orthogonality},
          {"mean_non_orthogonality", q.mean_non_orthogonality},
          {"max_skewness", q.max_skewness},
          {"negative_volumes", q.negative_volumes},
          {"bad_face_pyramids", q.bad_pyramids},
          {"inverted_cells", q.inverted_cells},
          {"min_volume", q.min_volume},
          {"total_volume", q.total_volume}};
}

std::string quality_table(const morph::PolyQuality& a, const morph::PolyQuality& b) {
  std::ostringstream s;
  char line[160];
  const auto row = [&](const char* name, const std::string& x, const std::string& y) {
    std::snprintf(line, sizeof line, "  %-26s %14s %14s\n", name, x.c_str(), y.c_str());
    s << line;
  };
  const auto num = [](double v, const char* fmt) {
    char b[48];
    std::snprintf(b, sizeof b, fmt, v);
    return std::string(b);
  };
  row("quality", "before", "after");
  row("max non-orthogonality", num(a.max_non_orthogonality, "%.3f deg"), num(b.max_non_orthogonality, "%.3f deg"));
  row("mean non-orthogonality", num(a.mean_non_orthogonality, "%.3f deg"), num(b.mean_non_orthogonality, "%.3f deg"));
  row("max skewness", num(a.max_skewness, "%.4f"), num(b.max_skewness, "%.4f"));
  row("negative volumes", std::to_string(a.negative_volumes), std::to_string(b.negative_volumes));
  row("bad face pyramids", std::to_string(a.bad_pyramids), std::to_string(b.bad_pyramids));
  row("inverted cells", std::to_string(a.inverted_cells), std::to_string(b.inverted_cells));
  row("min cell volume", num(a.min_volume, "%.6g"), num(b.min_volume, "%.6g"));
  return s.str();
}

std::string motion_summary(const morph::Motion& m) {
  std::string s;
  for (const auto& p : m.patches) {
    static const char* kinds[] = {"fixed", "translate", "rotate", "displacements"};
    s += (s.empty() ? "" : ", ") + p.patch + " " + kinds[int(p.kind)];
  }
  return s;
}

}  // namespace

CLI::App* add_morph_command(CLI::App& app, MorphArgs& a) {
  auto* cmd =
      app.add_subcommand("morph",
                         "Move the patches of a volume mesh as a motion file says and carry every other point along "
                         "(docs/morphing.md)");
  cmd->add_option("case", a.mesh, "An OpenFOAM case folder, or its constant/polyMesh")->required();
  auto* out = cmd->add_option("-o,--output", a.out, "A new case folder: a copy of the case with the moved points");
  auto* in_place = cmd->add_flag("--in-place", a.in_place, "Rewrite the case's points file alone (atomically)");
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
  const auto t0 = Clock::now();
  if (a.out.empty() && !a.in_place) throw UsageError("morph: give -o OUT (a new case folder) or --in-place");
  if (!a.out.empty()) {
    std::error_code ec;
    if (fs::symlink_status(a.out, ec).type() != fs::file_type::not_found)
      throw io::FileError("cannot write '" + a.out +
                          "': it exists (csrbf morph writes a new case folder; "
                          "--in-place rewrites the input's points alone)");
    const fs::path parent = fs::path(a.out).has_parent_path() ? fs::path(a.out).parent_path() : fs::path(".");
    if (!fs::is_directory(parent, ec))
      throw io::FileError("cannot write '" + a.out + "': folder '" + parent.string() + "' does not exist");
  }
  if (!morph::is_openfoam(a.mesh))
    throw io::FileError(a.mesh + ": not an OpenFOAM case (a folder with constant/polyMesh, or a polyMesh folder)");
  const morph::Motion motion = morph::read_motion(a.motion);
  morph::MorphOptions o;
  if (a.radius)
    o.fit.radius = *a.radius;
  else if (motion.radius)
    o.fit.radius = *motion.radius;
  else
    throw UsageError("morph: no radius: give --radius, or \"radius\" in " + a.motion);
  o.fit.kernel = !a.kernel.empty() ? *parse_name<Kernel>(a.kernel) : motion.kernel.value_or(Kernel::C2);
  o.fit.polynomial =
      !a.polynomial.empty() ? *parse_name<Polynomial>(a.polynomial) : motion.polynomial.value_or(Polynomial::None);
  o.fit.solver = *parse_name<Solver>(a.solver);
  o.fit.memory_limit_bytes = a.memory_limit_gib * double(1ull << 30);
  o.phase = a.phase;
  o.greedy = a.greedy.value_or(0.0);

  const auto t_read = Clock::now();
  const morph::FoamCase c = morph::read_openfoam(a.mesh);
  const double read_ms = ms_since(t_read);
  const auto t_q = Clock::now();
  const morph::PolyQuality before = morph::poly_quality(c.mesh.poly, c.mesh.points);
  double quality_ms = ms_since(t_q);
  morph::MorphResult r;
  try {
    r = morph::morph(c.mesh, motion, o);
  } catch (const DuplicateSource& e) {
    throw io::FileError(a.mesh + ": two prescribed points are at the same place (sources " + std::to_string(e.first()) +
                        " and " + std::to_string(e.second()) + " of the controls): " + e.what());
  } catch (const io::FileError&) {
    throw;
  } catch (const Error& e) {
    throw io::FileError(a.mesh + ": " + e.what());
  }
  const auto t_q2 = Clock::now();
  const morph::PolyQuality after = morph::poly_quality(c.mesh.poly, r.points);
  quality_ms += ms_since(t_q2);
  const bool inverts = after.inverted_cells > before.inverted_cells;
  double safe_phase = a.phase;
  if (inverts) safe_phase = morph::largest_safe_phase(c.mesh, r.points, a.phase, before.inverted_cells);
  const bool write = !inverts || a.force;
  double write_ms = 0;
  if (write) {
    const auto t_w = Clock::now();
    if (a.in_place)
      morph::write_openfoam_in_place(c, r.points);
    else
      morph::write_openfoam_copy(c, r.points, a.out);
    write_ms = ms_since(t_w);
  }
  const double total_ms = ms_since(t0);
  const morph::MorphReport& rep = r.report;
  const std::string target = a.in_place ? c.points_file.path.string() : a.out;
  if (a.json) {
    nlohmann::json j{{"case", a.mesh},
                     {"format", "openfoam"},
                     {"encoding", c.points_file.binary ? "binary" : "ascii"},
                     {"gzip", c.points_file.gzip},
                     {"output", target},
                     {"written", write},
                     {"points", c.mesh.points.size()},
                     {"cells", c.mesh.poly.cells},
                     {"prescribed", rep.prescribed},
                     {"moving", rep.moving},
                     {"fixed", rep.fixed},
                     {"controls", rep.controls},
                     {"greedy_rounds", rep.greedy_rounds},
                     {"max_displacement", rep.max_displacement},
                     {"max_boundary_error", rep.max_boundary_error},
                     {"radius", o.fit.radius},
                     {"kernel", kernel_name(o.fit.kernel)},
                     {"polynomial", polynomial_name(o.fit.polynomial)},
                     {"solver", rep.controls ? std::string(name_of(rep.fit.solver)) : std::string("none")},
                     {"phase", a.phase},
                     {"quality", {{"before", quality_json(before)}, {"after", quality_json(after)}}},
                     {"ms",
                      {{"read", read_ms},
                       {"fit", rep.seconds_fit * 1e3},
                       {"evaluate", rep.seconds_evaluate * 1e3},
                       {"quality", quality_ms},
                       {"write", write_ms},
                       {"total", total_ms}}}};
    if (inverts) j["safe_phase"] = safe_phase;
    std::cout << j.dump(2) << '\n';
  } else {
    std::cout << "csrbf morph: " << a.mesh << " (OpenFOAM, " << (c.points_file.binary ? "binary" : "ascii")
              << (c.points_file.gzip ? ", gzip" : "") << "): " << c.mesh.points.size() << " points, "
              << c.mesh.poly.cells << " cells\n"
              << "  motion " << a.motion << ": " << motion_summary(motion) << "\n"
              << "  " << rep.prescribed << " prescribed points (" << rep.moving << " moving, " << rep.fixed
              << " fixed), " << rep.controls << " controls";
    if (rep.greedy_rounds) std::cout << " chosen in " << rep.greedy_rounds << " greedy rounds";
    std::cout << "; largest displacement " << rep.max_displacement << ", largest boundary error "
              << rep.max_boundary_error << " before exact placement\n"
              << "  R = " << o.fit.radius << ", kernel " << kernel_name(o.fit.kernel) << ", polynomial "
              << polynomial_name(o.fit.polynomial) << ", phase " << a.phase << "\n"
              << quality_table(before, after) << "  time: read " << read_ms << " ms, fit " << rep.seconds_fit * 1e3
              << " ms, evaluate " << rep.seconds_evaluate * 1e3 << " ms, quality " << quality_ms << " ms, write "
              << write_ms << " ms, total " << total_ms << " ms\n";
    if (write)
      std::cout << "  -> " << target << (inverts ? " (written with --force: it has inverted cells)" : "") << "\n";
  }
  if (!write) {
    std::cerr << "csrbf: error: the morph inverts " << after.inverted_cells - before.inverted_cells << " cells ("
              << after.inverted_cells << " inverted, " << before.inverted_cells
              << " before); the largest phase <= " << a.phase << " that inverts none is " << safe_phase
              << "; nothing written (--force writes anyway)\n";
    return 1;
  }
  return 0;
}

}  // namespace csrbf::cli
