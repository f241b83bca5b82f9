#include "morph.hpp"

#include "animate.hpp"
#include "commands.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/morph/volume_file.hpp"
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

nlohmann::json quality_json(const morph::MeshQuality& m) {
  nlohmann::json j = nlohmann::json::object();
  j["inverted_cells"] = m.inverted_cells();
  if (m.cells) {
    const morph::CellQuality& c = *m.cells;
    j["cells"] = {{"measured", c.cells},
                  {"tetrahedra", c.tetrahedra},
                  {"hexahedra", c.hexahedra},
                  {"prisms", c.prisms},
                  {"pyramids", c.pyramids},
                  {"triangles", c.triangles},
                  {"quads", c.quads},
                  {"min_scaled_jacobian", c.min_scaled_jacobian},
                  {"mean_scaled_jacobian", c.mean_scaled_jacobian},
                  {"inverted_cells", c.inverted_cells}};
  }
  if (!m.poly) return j;
  const morph::PolyQuality& q = *m.poly;
  j["polyhedra"] = {{"cells", q.cells},
                    {"faces", q.faces},
                    {"max_non_orthogonality", q.max_non_orthogonality},
                    {"mean_non_orthogonality", q.mean_non_orthogonality},
                    {"max_skewness", q.max_skewness},
                    {"negative_volumes", q.negative_volumes},
                    {"bad_face_pyramids", q.bad_pyramids},
                    {"inverted_cells", q.inverted_cells},
                    {"min_volume", q.min_volume},
                    {"total_volume", q.total_volume}};
  return j;
}

std::string quality_table(const morph::MeshQuality& qa, const morph::MeshQuality& qb) {
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
  if (qa.cells && qb.cells) {
    const morph::CellQuality &a = *qa.cells, &b = *qb.cells;
    row("min scaled Jacobian", num(a.min_scaled_jacobian, "%.4f"), num(b.min_scaled_jacobian, "%.4f"));
    row("mean scaled Jacobian", num(a.mean_scaled_jacobian, "%.4f"), num(b.mean_scaled_jacobian, "%.4f"));
    row("inverted cells", std::to_string(a.inverted_cells), std::to_string(b.inverted_cells));
  }
  if (!qa.poly || !qb.poly) return s.str();
  const morph::PolyQuality &a = *qa.poly, &b = *qb.poly;
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
  cmd->add_option("mesh", a.mesh,
                  "An OpenFOAM case folder (or its constant/polyMesh), a .vtu or .vtk unstructured grid, a Gmsh .msh "
                  "(2.2 or 4.1) or a .cgns file")
      ->required();
  auto* out = cmd->add_option("-o,--output", a.out,
                              "A new case folder (OpenFOAM: a copy of the case with the moved points) or a new file of "
                              "the input's format");
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
  if (a.out.empty() && !a.in_place) throw UsageError("morph: give -o OUT (a new case folder or file) or --in-place");
  if (!a.out.empty()) {
    std::error_code ec;
    if (fs::symlink_status(a.out, ec).type() != fs::file_type::not_found)
      throw io::FileError("cannot write '" + a.out +
                          "': it exists (csrbf morph writes a new case folder or file; --in-place rewrites the input's "
                          "points alone)");
    const fs::path parent = fs::path(a.out).has_parent_path() ? fs::path(a.out).parent_path() : fs::path(".");
    if (!fs::is_directory(parent, ec))
      throw io::FileError("cannot write '" + a.out + "': folder '" + parent.string() + "' does not exist");
    std::error_code e1, e2;
    const bool in_folder = fs::is_directory(a.mesh, e1);
    if (!in_folder) {
      const auto ext = [](const std::string& p) {
        std::string e = fs::path(p).extension().string();
        for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
        return e;
      };
      if (ext(a.out) != ext(a.mesh))
        throw UsageError("morph: -o " + a.out +
                         ": the output is written in the input's format, so it needs the extension '" + ext(a.mesh) +
                         "'");
    }
  }
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
  morph::OpenOptions open;
  open.patch_array = motion.patch_array;
  const auto file = morph::open_volume(a.mesh, open);
  const morph::VolumeMesh& mesh = file->mesh();
  if (mesh.patches.empty())
    throw io::FileError(
        a.mesh + ": the mesh has no patches" +
        (file->format() == "vtu" || file->format() == "vtk"
             ? std::string(": name an integer point or cell data array as \"patch_array\" in ") + a.motion
             : std::string()));
  const double read_ms = ms_since(t_read);
  const auto t_q = Clock::now();
  const morph::MeshQuality before = morph::mesh_quality(mesh, mesh.points);
  double quality_ms = ms_since(t_q);
  morph::MorphResult r;
  try {
    r = morph::morph(mesh, motion, o);
  } catch (const DuplicateSource& e) {
    throw io::FileError(a.mesh + ": two prescribed points are at the same place (sources " + std::to_string(e.first()) +
                        " and " + std::to_string(e.second()) + " of the controls): " + e.what());
  } catch (const io::FileError&) {
    throw;
  } catch (const Error& e) {
    throw io::FileError(a.mesh + ": " + e.what());
  }
  const auto t_q2 = Clock::now();
  const morph::MeshQuality after = morph::mesh_quality(mesh, r.points);
  quality_ms += ms_since(t_q2);
  const bool inverts = after.inverted_cells() > before.inverted_cells();
  double safe_phase = a.phase;
  if (inverts) safe_phase = morph::largest_safe_phase(mesh, r.points, a.phase, before.inverted_cells());
  const bool write = !inverts || a.force;
  double write_ms = 0;
  if (write) {
    const auto t_w = Clock::now();
    if (a.in_place)
      file->write_in_place(r.points);
    else
      file->write_copy(r.points, a.out);
    write_ms = ms_since(t_w);
  }
  const double total_ms = ms_since(t0);
  const morph::MorphReport& rep = r.report;
  const std::string target = a.in_place ? a.mesh : a.out;
  const std::size_t cells = mesh.poly.faces() ? mesh.poly.cells : mesh.cells.size();
  if (a.json) {
    nlohmann::json j{{"case", a.mesh},
                     {"format", file->format()},
                     {"encoding", file->encoding()},
                     {"output", target},
                     {"written", write},
                     {"points", mesh.points.size()},
                     {"cells", cells},
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
    std::cout << "csrbf morph: " << a.mesh << " (" << file->format() << ", " << file->encoding()
              << "): " << mesh.points.size() << " points, " << cells << " cells, " << mesh.patches.size()
              << " patches\n"
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
    std::cerr << "csrbf: error: the morph inverts " << after.inverted_cells() - before.inverted_cells() << " cells ("
              << after.inverted_cells() << " inverted, " << before.inverted_cells()
              << " before); the largest phase <= " << a.phase << " that inverts none is " << safe_phase
              << "; nothing written (--force writes anyway)\n";
    return 1;
  }
  return 0;
}

}  // namespace csrbf::cli
