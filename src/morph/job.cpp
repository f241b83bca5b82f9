#include "csrbf/morph/job.hpp"
#include "csrbf/morph/openfoam.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/memory.hpp"

#include "csrbf/io/controls.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/volume_file.hpp"
#include "csrbf/names.hpp"
#include "volume_formats.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cctype>
#include <exception>
#include <limits>
#include <numbers>
#include <optional>
#include <thread>
#include <vector>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <sstream>

namespace fs = std::filesystem;

namespace csrbf::morph {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

nlohmann::json quality_json(const MeshQuality& m) {
  nlohmann::json j = nlohmann::json::object();
  j["inverted_cells"] = m.inverted_cells();
  if (m.cells) {
    const CellQuality& c = *m.cells;
    j["cells"] = {{"measured", c.cells},
                  {"tetrahedra", c.tetrahedra},
                  {"hexahedra", c.hexahedra},
                  {"prisms", c.prisms},
                  {"pyramids", c.pyramids},
                  {"triangles", c.triangles},
                  {"quads", c.quads},
                  {"min_scaled_jacobian", c.min_scaled_jacobian},
                  {"mean_scaled_jacobian", c.mean_scaled_jacobian},
                  {"min_volume_ratio", c.min_volume_ratio},
                  {"inverted_cells", c.inverted_cells}};
  }
  if (!m.poly) return j;
  const PolyQuality& q = *m.poly;
  j["polyhedra"] = {{"cells", q.cells},
                    {"faces", q.faces},
                    {"max_non_orthogonality", q.max_non_orthogonality},
                    {"mean_non_orthogonality", q.mean_non_orthogonality},
                    {"max_skewness", q.max_skewness},
                    {"negative_volumes", q.negative_volumes},
                    {"bad_face_pyramids", q.bad_pyramids},
                    {"inverted_cells", q.inverted_cells},
                    {"min_volume", q.min_volume},
                    {"min_volume_ratio", q.min_volume_ratio},
                    {"min_determinant", q.min_determinant},
                    {"mean_determinant", q.mean_determinant},
                    {"total_volume", q.total_volume}};
  return j;
}

std::string quality_table(const MeshQuality& qa, const MeshQuality& qb) {
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
    const CellQuality &a = *qa.cells, &b = *qb.cells;
    row("min scaled Jacobian", num(a.min_scaled_jacobian, "%.4f"), num(b.min_scaled_jacobian, "%.4f"));
    row("mean scaled Jacobian", num(a.mean_scaled_jacobian, "%.4f"), num(b.mean_scaled_jacobian, "%.4f"));
    row("inverted cells", std::to_string(a.inverted_cells), std::to_string(b.inverted_cells));
    row("min volume after/before", "", num(b.min_volume_ratio, "%.4f"));
  }
  if (!qa.poly || !qb.poly) return s.str();
  const PolyQuality &a = *qa.poly, &b = *qb.poly;
  row("max non-orthogonality", num(a.max_non_orthogonality, "%.3f deg"), num(b.max_non_orthogonality, "%.3f deg"));
  row("mean non-orthogonality", num(a.mean_non_orthogonality, "%.3f deg"), num(b.mean_non_orthogonality, "%.3f deg"));
  row("max skewness", num(a.max_skewness, "%.4f"), num(b.max_skewness, "%.4f"));
  row("negative volumes", std::to_string(a.negative_volumes), std::to_string(b.negative_volumes));
  row("bad face pyramids", std::to_string(a.bad_pyramids), std::to_string(b.bad_pyramids));
  row("inverted cells", std::to_string(a.inverted_cells), std::to_string(b.inverted_cells));
  row("min cell volume", num(a.min_volume, "%.6g"), num(b.min_volume, "%.6g"));
  row("min volume after/before", "", num(b.min_volume_ratio, "%.4f"));
  row("min cell determinant", num(a.min_determinant, "%.4g"), num(b.min_determinant, "%.4g"));
  return s.str();
}

/// The quality of every part of a decomposed mesh (the part's own where alone). Faces between
/// parts are boundary faces of each: their non-orthogonality is not counted, their skewness is
/// measured as a boundary face's.
MeshQuality combine(MorphBackend& b, MeshQuality q) {
  if (!b.part()) return q;
  // The same reductions on every part, whether it has cells of a kind or none (an empty processor).
  const auto sum = [&](std::size_t v) { return std::size_t(b.sum(double(v))); };
  const auto min = [&](double v) { return -b.max(-v); };
  const bool has_poly = b.max(q.poly ? 1.0 : 0.0) > 0, has_cells = b.max(q.cells ? 1.0 : 0.0) > 0;
  if (has_poly) {
    PolyQuality p = q.poly.value_or(PolyQuality{});
    const bool mine = q.poly.has_value() && p.cells > 0;
    const double internal = b.sum(double(p.internal_faces));
    const double cos_sum =
        b.sum(std::cos(p.mean_non_orthogonality * std::numbers::pi / 180.0) * double(p.internal_faces));
    p.cells = sum(p.cells);
    p.faces = sum(p.faces);
    p.internal_faces = std::size_t(internal);
    p.max_non_orthogonality = b.max(p.max_non_orthogonality);
    p.mean_non_orthogonality =
        internal > 0 ? std::acos(std::clamp(cos_sum / internal, -1.0, 1.0)) * 180.0 / std::numbers::pi : 0.0;
    p.max_skewness = b.max(p.max_skewness);
    p.negative_volumes = sum(p.negative_volumes);
    p.bad_pyramids = sum(p.bad_pyramids);
    p.inverted_cells = sum(p.inverted_cells);
    p.min_volume = min(mine ? p.min_volume : std::numeric_limits<double>::infinity());
    p.min_volume_ratio = min(mine ? p.min_volume_ratio : std::numeric_limits<double>::infinity());
    p.mean_determinant =
        p.cells > 0 ? b.sum(mine ? p.mean_determinant * double(q.poly->cells) : 0.0) / double(p.cells) : 0.0;
    p.min_determinant = min(mine ? p.min_determinant : std::numeric_limits<double>::infinity());
    if (!std::isfinite(p.min_determinant)) p.min_determinant = 0;
    p.total_volume = b.sum(p.total_volume);
    q.poly = p;
  }
  if (has_cells) {
    CellQuality c = q.cells.value_or(CellQuality{});
    const bool mine = q.cells.has_value() && c.cells > 0;
    const double n = b.sum(double(c.cells));
    const double mean_sum = b.sum(mine ? c.mean_scaled_jacobian * double(c.cells) : 0.0);
    c.cells = std::size_t(n);
    c.tetrahedra = sum(c.tetrahedra);
    c.hexahedra = sum(c.hexahedra);
    c.prisms = sum(c.prisms);
    c.pyramids = sum(c.pyramids);
    c.triangles = sum(c.triangles);
    c.quads = sum(c.quads);
    c.min_scaled_jacobian = min(mine ? c.min_scaled_jacobian : 1.0);
    c.min_volume_ratio = min(mine ? c.min_volume_ratio : 1.0);
    c.mean_scaled_jacobian = n > 0 ? mean_sum / n : 1.0;
    c.inverted_cells = sum(c.inverted_cells);
    q.cells = c;
  }
  return q;
}

// The progress bars' predictions where the work is not counted (measured on 2 cores: ASCII
// OpenFOAM files read at about 100 MB/s, checkMesh's measures at 3.2e-7 s a cell).
constexpr double kReadBytesPerSecond = 1e8;
constexpr double kQualitySecondsPerCell = 3.2e-7;
constexpr double kWriteSecondsPerPoint = 5e-7;

/// The bytes a mesh's reader goes through: a file's, or an OpenFOAM case's polyMesh files (a
/// gzipped one counted 5 times: what it inflates to, about).
double input_bytes(const fs::path& mesh) {
  std::error_code ec;
  if (!fs::is_directory(mesh, ec)) {
    const auto size = fs::file_size(mesh, ec);
    return ec ? 0.0 : double(size);
  }
  fs::path poly = mesh / "constant" / "polyMesh";
  if (!fs::is_directory(poly, ec)) poly = mesh;
  double bytes = 0;
  for (fs::directory_iterator it(poly, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    const auto size = it->file_size(ec);
    if (!ec) bytes += double(size) * (it->path().extension() == ".gz" ? 5.0 : 1.0);
  }
  return bytes;
}

std::string motion_summary(const Motion& m) {
  std::string s;
  for (const auto& p : m.patches) {
    static const char* kinds[] = {"fixed", "translate", "rotate", "displacements", "slip", "free"};
    s += (s.empty() ? "" : ", ") + p.patch + " " + kinds[int(p.kind)];
  }
  return s;
}

}  // namespace

void check_job(const MorphJob& job) {
  if (job.write && job.out.empty() && !job.in_place)
    throw JobError("give an output (a new case folder or file) or in place");
  if (job.write && !job.out.empty() && job.in_place) throw JobError("give an output or in place, not both");
  if (job.radius && !(*job.radius > 0 && std::isfinite(*job.radius)))
    throw JobError("the radius must be a finite number > 0, got " + io::format_number(*job.radius));
  if (!(job.phase >= 0 && job.phase <= 1))
    throw JobError("the phase must be in [0, 1], got " + io::format_number(job.phase));
  if (job.greedy && !(*job.greedy > 0 && *job.greedy <= 1))
    throw JobError("the greedy tolerance must be in (0, 1], got " + io::format_number(*job.greedy));
  if (!(job.greedy_budget >= 0 && job.greedy_budget <= 1e6))
    throw JobError("the greedy budget must be in [0, 1e6], got " + io::format_number(job.greedy_budget));
  if (job.levels < 0 || job.levels > 2)
    throw JobError("levels must be auto (0), 1 or 2, got " + std::to_string(job.levels));
  if (job.levels == 2 && job.greedy)
    throw JobError("two levels and greedy exclude each other (greedy chooses its own controls): give one");
  if (!(job.memory_limit_bytes > 0)) throw JobError("the memory limit must be > 0");
  if (job.write && !job.out.empty()) {
    std::error_code ec;
    if (fs::symlink_status(job.out, ec).type() != fs::file_type::not_found)
      throw io::FileError("cannot write '" + job.out.string() +
                          "': it exists (csrbf morph writes a new case folder or file; --in-place rewrites the input)");
    io::must_be_new(job.out);  // never replaced, even by a copy another morph finishes first
    const fs::path parent = job.out.has_parent_path() ? job.out.parent_path() : fs::path(".");
    if (!fs::is_directory(parent, ec))
      throw io::FileError("cannot write '" + job.out.string() + "': folder '" + parent.string() + "' does not exist");
    if (!fs::is_directory(job.mesh, ec) && detail::lower_extension(job.out) != detail::lower_extension(job.mesh))
      throw JobError("output " + job.out.string() +
                     ": the output is written in the input's format, so it needs the extension '" +
                     detail::lower_extension(job.mesh) + "'");
  }
}

namespace {}  // namespace

MorphOptions morph_options(const MorphJob& job, const Motion& motion) {
  MorphOptions opt;
  if (job.radius)
    opt.fit.radius = *job.radius;
  else if (!job.radius_auto && motion.radius)
    opt.fit.radius = *motion.radius;
  else
    opt.radius_auto = true;
  opt.progress = job.progress;
  opt.fit.kernel = job.kernel.value_or(motion.kernel.value_or(Kernel::C2));
  opt.fit.polynomial = job.polynomial.value_or(motion.polynomial.value_or(Polynomial::None));
  opt.fit.solver = job.solver;
  opt.fit.memory_limit_bytes = job.memory_limit_bytes;
  opt.phase = job.phase;
  opt.greedy = job.greedy.value_or(0.0);
  opt.greedy_budget = job.greedy_budget;
  opt.levels = job.levels;
  if (opt.levels == 2 && opt.fit.polynomial != Polynomial::None)
    throw JobError("two levels need polynomial none (a polynomial moves the whole space; its fit is one level), got " +
                   std::string(polynomial_name(opt.fit.polynomial)) +
                   (job.polynomial ? std::string(" (--polynomial)") : " (\"polynomial\" in " + motion.file + ")"));
  return opt;
}

namespace {}  // namespace

MorphOutcome run_job(const MorphJob& job) {
  MorphBackend& b = job.backend ? *job.backend : local_backend();
  const auto t0 = Clock::now();
  MorphOutcome o;
  o.mesh = job.mesh.string();
  o.motion = job.motion.string();
  Motion motion;
  std::unique_ptr<VolumeFile> file;
  auto t_read = Clock::now();
  b.agree(caught([&] {
    check_job(job);
    motion = job.motion_given ? *job.motion_given : read_motion(job.motion);
    o.options = morph_options(job, motion);
    o.motion_summary = motion_summary(motion);

    t_read = Clock::now();
    ProgressPhase reading(job.progress, "read", 0, input_bytes(b.mesh_path(job.mesh)) / kReadBytesPerSecond);
    OpenOptions open;
    open.patch_array = motion.patch_array;
    open.max_file_bytes = job.memory_limit_bytes;  // a mesh file, uncompressed, within --memory-limit
    open.time = job.time;
    file = open_volume(b.mesh_path(job.mesh), open);
    if (file->foam()) o.time = file->foam()->time;
    const VolumeMesh& mesh = file->mesh();
    if (!motion.patch_array.empty() && file->format() != "vtu" && file->format() != "vtk")
      throw io::FileError(o.motion + ": patch_array: names a VTK data array, but " + o.mesh + " is " + file->format() +
                          ", whose patches are its own");
    o.format = file->format();
    o.encoding = file->encoding();
    o.points = mesh.points.size();
    o.cells = mesh.poly.faces() ? mesh.poly.cells : mesh.cells.size();  // refined below: the measured cells
    o.patches = mesh.patches.size();
    if (mesh.patches.empty())
      throw io::FileError(o.mesh + ": the mesh has no patches" +
                          (o.format == "vtu" || o.format == "vtk"
                               ? std::string(": name an integer point or cell data array as \"patch_array\" in ") +
                                     o.motion + file->patch_hint()
                               : std::string()));
  }));
  const VolumeMesh& mesh = file->mesh();
  const MorphOptions& opt = o.options;
  o.ms_read = ms_since(t_read);
  auto t_q = Clock::now();
  QualityMeter meter(mesh);
  const double cells_here = double(mesh.poly.faces() ? mesh.poly.cells : mesh.cells.size());
  // On one process a polyhedral mesh's measure as read runs beside the morph, whose fit is about
  // half serial (windAroundBuildings: 0.35 s -> 0.29 s a morph). Its buffers (quality_buffers.hpp:
  // per face its centre, area, cosine, skewness and two entries of the cell-to-face index; per cell
  // six figures; per point a flag) are taken from what the fit may hold, and where they would take
  // half of it the measure runs first, as on more processes.
  const double measure_bytes =
      72.0 * double(mesh.poly.faces()) + 64.0 * double(mesh.poly.cells) + 2.0 * double(mesh.points.size());
  double fit_bytes = 0;
  const bool beside =
      !b.part() && mesh.poly.faces() > 0 && measure_bytes < 0.5 * (fit_bytes = io::memory_left(job.memory_limit_bytes));
  MeshQuality before_here;
  std::exception_ptr before_failed;
  std::thread before_thread;
  struct Joined {
    std::thread& t;
    ~Joined() {
      if (t.joinable()) t.join();
    }
  } joined{before_thread};
  if (beside) {
    before_thread = std::thread([&] {
      try {
        before_here = meter.measure(mesh.points);
      } catch (...) {
        before_failed = std::current_exception();
      }
    });
  } else {
    ProgressPhase measuring(job.progress, "quality", 0, cells_here * kQualitySecondsPerCell);
    o.before = combine(b, meter.measure(mesh.points));
  }
  if (o.before.cells)
    o.cells = o.before.cells->cells;  // the volume cells, not the boundary faces a file also holds
  else if (b.part() && o.before.poly)
    o.cells = o.before.poly->cells;  // every part's (combine)
  if (o.cells == 0) throw io::FileError(o.mesh + ": no cells (truncated, or not a volume mesh)");
  o.ms_quality = ms_since(t_q);
  // --memory-limit bounds the whole process: the fit gets what the program and the mesh leave of it.
  o.options.fit.memory_limit_bytes = beside ? fit_bytes - measure_bytes : io::memory_left(job.memory_limit_bytes);
  try {
    o.result = morph(mesh, motion, opt, &b);
  } catch (const DuplicateSource& e) {
    throw io::FileError(o.mesh + ": two prescribed points are at the same place (controls " +
                        std::to_string(e.first()) + " and " + std::to_string(e.second()) + "): " + e.what());
  } catch (const io::FileError&) {
    throw;
  } catch (const ResourceLimit& e) {
    throw io::FileError(o.mesh + ": " + e.what() +
                        io::memory_share(job.memory_limit_bytes, o.options.fit.memory_limit_bytes));
  } catch (const Error& e) {
    throw io::FileError(o.mesh + ": " + e.what());
  }
  t_q = Clock::now();
  if (beside) {  // the wait for it counts as the quality's time
    before_thread.join();
    if (before_failed) std::rethrow_exception(before_failed);
    o.before = combine(b, before_here);
    o.ms_quality = 0;
  }
  {
    ProgressPhase measuring(job.progress, "quality", 0, cells_here * kQualitySecondsPerCell);
    o.after = combine(b, meter.measure(o.result.points));
  }
  o.ms_quality += ms_since(t_q);
  o.inverts = o.after.inverted_cells() > o.before.inverted_cells();
  o.safe_phase = job.phase;
  // The bisection measures the mesh about 14 times.
  std::optional<ProgressPhase> bisecting;
  if (o.inverts) bisecting.emplace(job.progress, "safe phase", 0, 14 * cells_here * kQualitySecondsPerCell);
  if (o.inverts && !b.part())
    o.safe_phase = largest_safe_phase(mesh, o.result.points, job.phase, o.before.inverted_cells());
  if (o.inverts && b.part()) {  // the bisection of largest_safe_phase, counting every part's cells
    std::vector<Vec3> at(mesh.points.size());
    double lo = 0, hi = job.phase;
    while (hi - lo > 1e-4 * std::abs(job.phase)) {
      const double mid = 0.5 * (lo + hi), w = mid / job.phase;
      for (std::size_t i = 0; i < at.size(); ++i) at[i] = mesh.points[i] + w * (o.result.points[i] - mesh.points[i]);
      const double inverted = b.sum(double(meter.measure(at).inverted_cells()));
      (inverted <= double(o.before.inverted_cells()) ? lo : hi) = mid;
    }
    o.safe_phase = lo;
  }
  bisecting.reset();
  if (job.write && (!o.inverts || job.force)) {
    const auto t_w = Clock::now();
    ProgressPhase writing(job.progress, "write", 0, double(mesh.points.size()) * kWriteSecondsPerPoint);
    if (job.in_place)
      b.write_in_place(*file, o.result.points);
    else
      b.write_copy(*file, o.result.points, job.out);
    o.ms_write = ms_since(t_w);
    o.written = true;
    o.output = job.in_place ? o.mesh : job.out.string();
  }
  o.ms_total = ms_since(t0);
  return o;
}

std::string outcome_json(const MorphOutcome& o) {
  const MorphReport& rep = o.result.report;
  nlohmann::json j{
      {"case", o.mesh},
      {"format", o.format},
      {"encoding", o.encoding},
      {"output", o.output},
      {"written", o.written},
      {"points", o.points},
      {"cells", o.cells},
      {"patch_count", o.patches},
      {"prescribed", rep.prescribed},
      {"moving", rep.moving},
      {"fixed", rep.fixed},
      {"slip", rep.slip},
      {"controls", rep.controls},
      {"greedy_rounds", rep.greedy_rounds},
      {"greedy_stopped", rep.greedy_stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(rep.greedy_stopped)},
      {"max_displacement", rep.max_displacement},
      {"max_boundary_error", rep.max_boundary_error},
      {"radius", rep.radius},
      {"radius_why", rep.radius_why},
      {"levels", rep.levels},
      {"levels_why", rep.levels_why},
      {"predicted",
       {{"neighbours_per_control", rep.predicted.neighbours_per_control},
        {"neighbours_per_point", rep.predicted.neighbours_per_point},
        {"bytes", rep.predicted.bytes},
        {"seconds_fit", rep.predicted.seconds_fit},
        {"seconds_evaluate", rep.predicted.seconds_evaluate}}},
      {"kernel", kernel_name(o.options.fit.kernel)},
      {"polynomial", polynomial_name(o.options.fit.polynomial)},
      {"solver", rep.controls ? std::string(name_of(rep.fit.solver)) : std::string("none")},
      {"phase", o.options.phase},
      {"quality", {{"before", quality_json(o.before)}, {"after", quality_json(o.after)}}},
      {"ms",
       {{"read", o.ms_read},
        {"fit", rep.seconds_fit * 1e3},
        {"evaluate", rep.seconds_evaluate * 1e3},
        {"quality", o.ms_quality},
        {"write", o.ms_write},
        {"total", o.ms_total}}}};
  if (o.inverts) j["safe_phase"] = o.safe_phase;
  // Points this far or farther from every moving control keep their coordinates bit for bit (null:
  // a polynomial moves the whole space); staying controls farther than R from every moving one.
  j["reach"] = std::isfinite(rep.reach) ? nlohmann::json(rep.reach) : nlohmann::json(nullptr);
  j["far_fixed"] = rep.far_fixed;
  // Two levels: the coarse level's controls and spacing, the fine level's R; with levels auto, the
  // two predicted fit times it weighed.
  if (rep.levels == 2)
    j["two_levels"] = {{"coarse_controls", rep.coarse_controls},
                       {"coarse_spacing", rep.coarse_spacing},
                       {"fine_radius", rep.fine_radius}};
  // The two fits levels auto weighed (null where no two-level plan was made: one level asked for,
  // a polynomial, greedy, mpirun). With two levels, "predicted"'s other figures are one level's.
  const bool weighed = rep.seconds_plain_predicted > 0;
  j["predicted"]["seconds_fit_one_level"] =
      weighed ? nlohmann::json(rep.seconds_plain_predicted) : nlohmann::json(nullptr);
  j["predicted"]["seconds_fit_two_levels"] =
      weighed ? nlohmann::json(rep.seconds_two_levels_predicted) : nlohmann::json(nullptr);
  j["time"] = o.time.empty() ? nlohmann::json("constant") : nlohmann::json(o.time);
  // Every patch: what it did (moving, fixed, slip or free) and why (listed, group, type, planar...).
  j["patches"] = nlohmann::json::array();
  for (const auto& p : rep.patches) j["patches"].push_back({{"name", p.name}, {"kind", p.kind}, {"why", p.why}});
  return j.dump(2);
}

std::string outcome_text(const MorphOutcome& o) {
  const MorphReport& rep = o.result.report;
  std::ostringstream s;
  s << "csrbf morph: " << o.mesh << (o.time.empty() ? "" : " at time " + o.time) << " (" << o.format << ", "
    << o.encoding << "): " << o.points << " points, " << o.cells << " cells, " << o.patches << " patches\n"
    << "  motion " << o.motion << ": " << o.motion_summary << "\n"
    << "  " << rep.prescribed << " prescribed points (" << rep.moving << " moving, " << rep.fixed << " fixed, "
    << rep.slip << " slip), " << rep.controls << " controls";
  if (rep.greedy_rounds && rep.greedy_stopped.empty()) s << " chosen in " << rep.greedy_rounds << " greedy rounds";
  if (!rep.greedy_stopped.empty()) s << " (greedy stopped " << rep.greedy_stopped << ")";
  s << "; largest displacement " << rep.max_displacement << ", largest boundary error " << rep.max_boundary_error
    << " before exact placement\n"
    << "  R = " << rep.radius << (o.options.radius_auto ? " (auto: " + rep.radius_why + ")" : std::string())
    << ", kernel " << kernel_name(o.options.fit.kernel) << ", polynomial " << polynomial_name(o.options.fit.polynomial)
    << ", phase " << o.options.phase << "\n";
  if (rep.levels == 2)
    s << "  two levels: " << rep.coarse_controls << (rep.coarse_controls == 1 ? " coarse control" : " coarse controls")
      << " spaced " << rep.coarse_spacing << " at R = " << rep.radius
      << ", then every control at R = " << rep.fine_radius << " (" << rep.levels_why << ")\n";
  // The patches the motion left unlisted, and what each did (the listed ones are in the motion line).
  std::string unlisted;
  for (const auto& p : rep.patches)
    if (p.why != "listed")
      unlisted += (unlisted.empty() ? "" : ", ") + printable(p.name) + " " + p.kind + " (" + p.why + ")";
  if (!unlisted.empty()) s << "  other patches: " << unlisted << "\n";
  if (rep.moving == 0 || rep.max_displacement == 0 || o.options.phase == 0)
    s << "  nothing moves: every point keeps its coordinates bit for bit\n";
  else if (std::isfinite(rep.reach))
    s << "  reach " << rep.reach << ": a point this far or farther from every moving point keeps its coordinates "
      << "bit for bit (" << rep.far_fixed << " staying points farther than R from every moving one were left "
      << "out of the fit, and stay)\n";
  else
    s << "  reach: the whole mesh (polynomial " << polynomial_name(o.options.fit.polynomial)
      << " moves every point; polynomial none keeps points 2R from every moving one bit for bit)\n";
  s << quality_table(o.before, o.after) << "  time: read " << o.ms_read << " ms, fit " << rep.seconds_fit * 1e3
    << " ms, evaluate " << rep.seconds_evaluate * 1e3 << " ms, quality " << o.ms_quality << " ms, write " << o.ms_write
    << " ms, total " << o.ms_total << " ms\n";
  if (o.written)
    s << "  -> " << o.output << (o.inverts ? " (written with --force: it has inverted cells)" : "") << "\n";
  return s.str();
}

}  // namespace csrbf::morph

namespace csrbf::morph {

namespace {

/// The motion files of a series folder, in increasing time: (time as named, path).
std::vector<std::pair<std::string, fs::path>> series_files(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw io::FileError("motion series '" + dir.string() +
                        "': not a folder (give a folder of motion files named by "
                        "time: 0.1.json, 0.2.json, ...)");
  std::vector<std::tuple<double, std::string, fs::path>> found;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() != ".json") continue;
    const std::string stem = p.stem().string();
    if (!it->is_regular_file(ec))
      throw io::FileError("motion series '" + dir.string() + "': '" + p.filename().string() +
                          "' is not a regular file");
    char* stop = nullptr;
    errno = 0;
    const double t = std::strtod(stem.c_str(), &stop);
    if (stem.empty() || stop != stem.c_str() + stem.size() || !std::isfinite(t) || t < 0 || errno == ERANGE ||
        stem.find_first_not_of("0123456789.eE+-") != std::string::npos)
      throw io::FileError("motion series '" + dir.string() + "': '" + p.filename().string() +
                          "' is not named by a time (0.1.json, 2.json, 1e-3.json)");
    found.emplace_back(t, stem, p);
  }
  if (ec) throw io::FileError("motion series '" + dir.string() + "': cannot list it: " + ec.message());
  if (found.empty())
    throw io::FileError("motion series '" + dir.string() +
                        "': no motion files named by time (0.1.json, 0.2.json, ...)");
  std::sort(found.begin(), found.end());
  for (std::size_t k = 1; k < found.size(); ++k)
    if (std::get<0>(found[k]) == std::get<0>(found[k - 1]))
      throw io::FileError("motion series '" + dir.string() + "': '" + std::get<2>(found[k - 1]).filename().string() +
                          "' and '" + std::get<2>(found[k]).filename().string() + "' name the same time");
  std::vector<std::pair<std::string, fs::path>> out;
  for (auto& [t, name, p] : found) out.emplace_back(name, p);
  return out;
}

}  // namespace

SeriesOutcome run_series(const MorphJob& job) {
  const auto t0 = Clock::now();
  SeriesOutcome s;
  s.mesh = job.mesh.string();
  s.series = job.motion_series.string();
  check_job(job);
  auto files = series_files(job.motion_series);
  std::vector<Motion> motions;
  for (const auto& f : files) motions.push_back(read_motion(f.second));
  const auto t_read = Clock::now();
  std::unique_ptr<VolumeFile> file;
  {
    ProgressPhase reading(job.progress, "read", 0, input_bytes(job.mesh) / kReadBytesPerSecond);
    OpenOptions open;
    open.max_file_bytes = job.memory_limit_bytes;
    open.time = job.time;
    file = open_volume(job.mesh, open);
  }
  const FoamCase* foam = file->foam();
  std::error_code ec;
  if (!foam || !fs::is_directory(foam->root / "constant", ec))
    throw JobError("--motion-series writes one moved mesh a time into the time folders of an OpenFOAM case; " + s.mesh +
                   " is " + (foam ? "a polyMesh folder, not a case" : "a " + file->format() + " file"));
  if (job.write && !job.in_place) check_openfoam_copy_target(*foam, job.out);
  // A time the case has already is matched by value, as OpenFOAM matches times: 0.50.json writes
  // into the case's 0.5.
  for (const std::string& have : foam_times(foam->root))
    for (auto& f : files)
      if (std::strtod(have.c_str(), nullptr) == std::strtod(f.first.c_str(), nullptr)) f.first = have;
  for (const auto& f : files)
    if (!foam->time.empty() && std::strtod(f.first.c_str(), nullptr) <= std::strtod(foam->time.c_str(), nullptr))
      throw io::FileError(f.second.string() + ": time " + f.first + " is not after the time read, " + foam->time);
  const VolumeMesh& mesh = file->mesh();
  s.ms_read = ms_since(t_read);
  // Auto's R from the series' largest displacement: one R, one matrix for every step.
  double largest = 0;
  for (const Motion& m : motions) largest = std::max(largest, largest_displacement(mesh, m));
  QualityMeter meter(mesh);
  const MeshQuality before = meter.measure(mesh.points);
  SeriesBackend backend;
  std::optional<io::Partial> partial;
  // In place: each time's points staged in a partial file of csrbf's own (removed if not
  // committed, and on a signal), and the folders staging made (removed only where empty).
  std::vector<std::pair<std::unique_ptr<io::Partial>, std::string>> staged;
  std::vector<fs::path> made;
  const auto discard = [&] {
    staged.clear();
    for (auto it = made.rbegin(); it != made.rend(); ++it) {
      std::error_code e;
      fs::remove(*it, e);  // an empty folder only: fs::remove does not remove what is in one
    }
  };
  try {
    for (std::size_t k = 0; k < files.size(); ++k) {
      if (job.progress) job.progress->note("time " + files[k].first + " (" + files[k].second.filename().string() + ")");
      MorphOutcome o;
      o.mesh = s.mesh;
      o.motion = files[k].second.string();
      o.time = files[k].first;
      o.format = file->format();
      o.encoding = file->encoding();
      o.points = mesh.points.size();
      o.cells = mesh.poly.cells;
      o.patches = mesh.patches.size();
      o.motion_summary = motion_summary(motions[k]);
      o.options = morph_options(job, motions[k]);
      o.options.auto_displacement = largest;
      // --memory-limit bounds the whole process: each step's fit gets what the program, the mesh and
      // the factorisations the series keeps for the next steps leave of it.
      o.options.fit.memory_limit_bytes = io::memory_left(job.memory_limit_bytes);
      const auto t_step = Clock::now();
      const std::size_t factorised = backend.factorisations();
      try {
        o.result = morph(mesh, motions[k], o.options, &backend);
      } catch (const io::FileError&) {
        throw;
      } catch (const Error& e) {
        throw io::FileError(o.motion + ": " + e.what());
      }
      s.reused.push_back(backend.factorisations() == factorised && o.result.report.controls > 0);
      const auto t_q = Clock::now();
      o.before = before;
      {
        ProgressPhase measuring(job.progress, "quality", 0, double(mesh.poly.cells) * kQualitySecondsPerCell);
        o.after = meter.measure(o.result.points);
      }
      o.ms_quality = ms_since(t_q);
      o.inverts = o.after.inverted_cells() > before.inverted_cells();
      o.safe_phase = job.phase;
      if (o.inverts) {
        o.safe_phase = largest_safe_phase(mesh, o.result.points, job.phase, before.inverted_cells());
        if (!job.force) {
          s.steps.push_back(std::move(o));
          discard();
          s.ms_total = ms_since(t0);
          return s;  // written stays false: the caller reports the step
        }
      }
      if (job.write) {
        const auto t_w = Clock::now();
        ProgressPhase writing(job.progress, "write", 0, double(mesh.points.size()) * kWriteSecondsPerPoint);
        if (job.in_place) {
          const fs::path folder = foam->root / o.time;
          for (const fs::path& d : {folder, folder / "polyMesh"})
            if (!fs::exists(fs::symlink_status(d, ec))) made.push_back(d);
          staged.emplace_back(stage_openfoam_points(*foam, o.result.points, o.time), o.time);
        } else {
          if (!partial) {
            partial.emplace(job.out, io::Partial::Kind::Folder);
            copy_openfoam_case(*foam, partial->path(), job.out);
          }
          write_openfoam_points_into(*foam, o.result.points, partial->path(), o.time);
        }
        o.ms_write = ms_since(t_w);
        s.ms_write += o.ms_write;
      }
      o.ms_total = ms_since(t_step);
      o.result.points = {};  // written: each step's points are not kept
      s.steps.push_back(std::move(o));
    }
    if (job.write) {
      if (job.in_place) {
        for (auto& st : staged) commit_openfoam_points(*foam, *st.first, st.second);
        staged.clear();
      } else {
        partial->commit_new(job.out);
      }
      s.written = true;
      s.output = job.in_place ? s.mesh : job.out.string();
    }
  } catch (...) {
    discard();
    throw;
  }
  s.factorisations = backend.factorisations();
  s.solves_reused = backend.reused();
  s.ms_total = ms_since(t0);
  return s;
}

std::string series_json(const SeriesOutcome& s) {
  nlohmann::json j{{"case", s.mesh},
                   {"motion_series", s.series},
                   {"output", s.output},
                   {"written", s.written},
                   {"factorisations", s.factorisations},
                   {"solves_reused", s.solves_reused},
                   {"ms", {{"read", s.ms_read}, {"write", s.ms_write}, {"total", s.ms_total}}}};
  j["steps"] = nlohmann::json::array();
  for (std::size_t k = 0; k < s.steps.size(); ++k) {
    nlohmann::json step = nlohmann::json::parse(outcome_json(s.steps[k]));
    step["reused_factorisation"] = k < s.reused.size() && s.reused[k];
    j["steps"].push_back(step);
  }
  return j.dump(2);
}

std::string series_text(const SeriesOutcome& s) {
  std::ostringstream o;
  o << "csrbf morph: " << s.mesh << ", motion series " << s.series << ": " << s.steps.size() << " times, "
    << s.factorisations << " factorisation" << (s.factorisations == 1 ? "" : "s") << ", " << s.solves_reused << " solve"
    << (s.solves_reused == 1 ? "" : "s") << " that reused one\n";
  for (std::size_t k = 0; k < s.steps.size(); ++k) {
    const MorphOutcome& st = s.steps[k];
    const MorphReport& r = st.result.report;
    char line[320];
    const double ratio = st.after.poly ? st.after.poly->min_volume_ratio : 1.0;
    const double non_orth = st.after.poly ? st.after.poly->max_non_orthogonality : 0.0;
    std::snprintf(line, sizeof line,
                  "  time %-10s %s: largest displacement %.6g, R = %.6g, %zu controls, fit %.1f ms%s, evaluate %.1f "
                  "ms; max non-orthogonality %.3f deg, min volume after/before %.4f, inverted cells %zu\n",
                  st.time.c_str(), fs::path(st.motion).filename().string().c_str(), r.max_displacement, r.radius,
                  r.controls, r.seconds_fit * 1e3, k < s.reused.size() && s.reused[k] ? " (factorisation reused)" : "",
                  r.seconds_evaluate * 1e3, non_orth, ratio, st.after.inverted_cells());
    o << line;
  }
  o << "  time: read " << s.ms_read << " ms, write " << s.ms_write << " ms, total " << s.ms_total << " ms\n";
  if (s.written) o << "  -> " << s.output << " (TIME/polyMesh/points for each time)\n";
  return o.str();
}

}  // namespace csrbf::morph
