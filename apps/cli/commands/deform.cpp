#include "deform.hpp"

#include "commands.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <iostream>
#include <sstream>

namespace csrbf::cli {

CLI::App* add_deform_command(CLI::App& app, DeformArgs& a) {
  auto* deform = app.add_subcommand("deform", "Deform a mesh by the space mapping the controls define");
  deform->add_option("--mesh,-m", a.mesh_in, "Input mesh: .obj .ply .off .xyz (order kept), .stl .gltf .glb (assimp)")
      ->required();
  add_fit_options(deform, a.fit);
  deform->add_option("--phase,-t", a.phase, "Phase t in [0, 1]: each point moves to x + t d(x)")
      ->check(finite_in(0.0, 1.0, "--phase"))
      ->capture_default_str();
  deform->add_option("-o,--output", a.mesh_out, "Output mesh; its extension sets the format")->required();
  deform->add_flag("--json", a.json, "Print one JSON object (with each MPI rank's figures under mpirun)");
  deform->parse_complete_callback([&a, deform] { a.phase_given = deform->count("--phase") > 0; });
  return deform;
}

void check_deform_output(const DeformArgs& a) {
  io::check_output_path(io::resolve_output(a.mesh_out));
  check_not_an_input("-o", a.mesh_out, deform_inputs(a.fit, a.mesh_in));
  io::must_be_new(io::resolve_output(a.mesh_out));
  if (io::format_for(a.mesh_out) == io::MeshFormat::Assimp)
    throw UsageError("-o: unknown output format '" + std::filesystem::path(a.mesh_out).extension().string() +
                     "' (use .obj, .ply, .off, .xyz, .stl, .gltf or .glb)");
}

namespace {

/// assimp's writers build the scene again and copy it (measured, 500k vertices and 1M faces, and 1M
/// and 200k: glTF 290 bytes a vertex and 270 a face, STL 25 and 210), with a tenth more: kept from
/// the fit, and refused where the limit cannot hold them. Returns the bytes kept.
double writer_reserve(const DeformArgs& a, const io::MeshDocument& mesh) {
  const auto out_format = io::format_for(a.mesh_out);
  const double v = double(mesh.positions().size()), fc = double(mesh.faces().size());
  const double write = out_format == io::MeshFormat::Stl ? 1.1 * (25 * v + 210 * fc)
                       : out_format == io::MeshFormat::Gltf || out_format == io::MeshFormat::Glb
                           ? 1.1 * (290 * v + 270 * fc)
                           : 0.0;
  const double limit = a.fit.memory_limit_gib * kGiB;
  if (write > 0 && write > io::memory_left(limit)) {
    std::ostringstream m;
    m.precision(3);
    m << printable(a.mesh_out) << ": writing " << mesh.positions().size() << " vertices and " << mesh.faces().size()
      << " faces as " << io::format_name(out_format) << " takes about " << write / kGiB
      << " GiB (assimp's copies of the mesh), more than --memory-limit " << a.fit.memory_limit_gib
      << " GiB leaves after the mesh; give --memory-limit "
      << std::ceil(100 * (write + io::resident_bytes()) / kGiB) / 100 << " or more, or write .ply or .obj";
    throw io::FileError(m.str());
  }
  return write;
}

}  // namespace

int run_deform(DeformArgs& a) {
  check_deform_output(a);
  const auto t0 = std::chrono::steady_clock::now();
  auto mesh = io::MeshDocument::load(a.mesh_in, a.fit.memory_limit_gib * kGiB);
  a.fit.reserve_bytes = writer_reserve(a, mesh);
  Fitted f = fit(a.fit, &mesh, a.mesh_in);
  const double phase = !a.phase_given && f.phase ? *f.phase : a.phase;  // as it was seen in the Picker
  auto& p = mesh.positions();
  const std::vector<Vec3> before = p;
  io::apply_deformation(f.map, f.area, p, phase);
  const auto t1 = std::chrono::steady_clock::now();
  mesh.save(a.mesh_out);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < p.size(); ++i) moved += p[i] != before[i];
  const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  if (a.json) {
    nlohmann::json j{{"vertices", p.size()}, {"moved", moved}, {"controls", f.map.size()},
                     {"ranks", 1},           {"ms", ms},       {"fit", stats_json(f.map)}};
    std::cout << j.dump(2) << '\n';
    return 0;
  }
  std::cout << "csrbf deform: " << p.size() << " vertices (" << moved << " moved) of " << printable(a.mesh_in) << " by "
            << f.map.size() << " controls, R = " << f.map.radius() << ", kernel " << kernel_name(f.map.kernel())
            << ", polynomial " << polynomial_name(f.map.polynomial()) << ", phase " << phase
            << (f.area ? ", active area of " + std::to_string(f.area->vertices.size()) + " vertices" : std::string())
            << " -> " << printable(a.mesh_out) << " (" << ms << " ms)\n";
  return 0;
}

}  // namespace csrbf::cli
