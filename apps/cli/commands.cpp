#include "commands.hpp"

#include "commands/animate.hpp"
#include "csrbf/io/inputs.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace csrbf::cli {

void check_not_an_input(const std::string& option, const std::filesystem::path& output,
                        const std::vector<std::filesystem::path>& inputs) {
  const std::filesystem::path same = io::same_file_as(output, inputs);
  if (!same.empty())
    throw UsageError(option + " '" + output.string() + "' is the input '" + same.string() +
                     "' (the same file, by name or through a link); csrbf never writes an input: choose another name");
  // A .gltf output writes its buffer beside it, NAME.bin: that must not be an input either.
  if (output.extension() == ".gltf") {
    std::filesystem::path bin = output;
    bin.replace_extension(".bin");
    const std::filesystem::path side = io::same_file_as(bin, inputs);
    if (!side.empty())
      throw UsageError(option + " '" + output.string() + "' would write its buffer '" + bin.string() +
                       "', which is the input '" + side.string() +
                       "'; csrbf never writes an input: choose another name");
  }
}

std::vector<std::string> solver_choices() {
  std::vector<std::string> v = names<Solver>();
  v.push_back("mumps");
  return v;
}

Solver serial_solver(const std::string& name) {
  if (const auto s = parse_name<Solver>(name)) return *s;
  throw UsageError("--solver " + name +
                   ": MUMPS is the distributed solver (mpirun -np K with K > 1); on one process "
                   "the solvers are " +
                   names_text<Solver>());
}

/// A finite number in [lo, hi]; NaN and infinities are refused (CLI::Range lets NaN through).
CLI::Validator finite_in(double lo, double hi, const std::string& what) {
  std::ostringstream range;
  range << "[" << lo << ", " << hi << "]";
  return CLI::Validator(
      [lo, hi, what, r = range.str()](std::string& s) -> std::string {
        double v = 0;
        const char* b = s.data();
        const char* e = s.data() + s.size();
        if (b != e && *b == '+') ++b;
        const auto res = std::from_chars(b, e, v);
        if (res.ptr != e || (res.ec != std::errc() && res.ec != std::errc::result_out_of_range))
          return what + " must be a number, got '" + s + "'";
        if (res.ec == std::errc::result_out_of_range || !std::isfinite(v) || v < lo || v > hi)
          return what + " must be a finite number in " + r + ", got '" + s + "'";
        return {};
      },
      "in " + range.str());
}

namespace {
nlohmann::json profile_json(const Profile& p) { return {{"bandwidth", p.bandwidth}, {"envelope_entries", p.envelope}}; }
double us(double s) { return s * 1e6; }

/// The fit's statistics with the four orderings' profiles, for the report: a fit compares them
/// only for the envelope solver, so here they are computed from its matrix where it did not. For
/// the solvers that order the matrix themselves, the envelope figures are those of the smallest
/// envelope (what the paper's solver would have had).
FitStats report_stats(const SpaceMap& map) {
  FitStats s = map.stats();
  if (s.orderings_compared) return s;
  const OrderingChoice c = choose_ordering(map.matrix().pattern(), Ordering::Auto);
  s.identity = c.identity;
  s.breadth_first = c.breadth_first;
  s.reverse_breadth_first = c.reverse_breadth_first;
  s.reverse_cuthill_mckee = c.reverse_cuthill_mckee;
  if (s.envelope_work == 0) s.envelope_work = envelope_work(envelope_first_columns(map.matrix().pattern(), c.order));
  if (s.bandwidth == 0 && s.envelope_entries == 0) {
    const Profile& p = profile_of(c, c.chosen);
    s.bandwidth = p.bandwidth;
    s.envelope_entries = p.envelope;
    s.envelope_bytes = 4 * (s.controls + p.envelope) + 4 * s.controls;
  }
  return s;
}
}  // namespace

nlohmann::json stats_json(const SpaceMap& map) {
  const FitStats s = report_stats(map);
  nlohmann::json j;
  j["controls"] = s.controls;
  j["radius"] = map.radius();
  j["kernel"] = std::string(kernel_name(map.kernel()));
  j["polynomial"] = std::string(polynomial_name(map.polynomial()));
  j["neighbor_pairs"] = s.neighbor_pairs;
  j["mean_neighbors"] = s.mean_neighbors;
  j["ordering"] = s.solver == Solver::Cholmod ? "nested-dissection"
                  : s.solver == Solver::Eigen ? "amd"
                                              : std::string(ordering_name(s.ordering));
  j["orderings"] = {{"identity", profile_json(s.identity)},
                    {"breadth_first", profile_json(s.breadth_first)},
                    {"reverse_breadth_first", profile_json(s.reverse_breadth_first)},
                    {"reverse_cuthill_mckee", profile_json(s.reverse_cuthill_mckee)}};
  j["bandwidth"] = s.bandwidth;
  j["envelope_entries"] = s.envelope_entries;
  j["envelope_bytes"] = s.envelope_bytes;
  j["dense_bytes"] = s.dense_bytes;
  j["solver"] = std::string(solver_name(s.solver));
  j["envelope_work"] = s.envelope_work;
  j["factor_nonzeros"] = s.factor_nonzeros;
  j["iterations"] = s.iterations;
  j["solver_residual"] = s.solver_residual;
  j["fell_back"] = s.fell_back;
  j["residual_max"] = s.residual_max;
  j["residual_relative"] = s.residual_relative;
  j["time_us"] = {{"index", us(s.seconds_index)},
                  {"graph", us(s.seconds_graph)},
                  {"ordering", us(s.seconds_ordering)},
                  {"assembly", us(s.seconds_assembly)},
                  {"factorization", us(s.seconds_factorization)},
                  {"solve", us(s.seconds_solve)},
                  {"residual", us(s.seconds_residual)},
                  {"total", us(s.seconds_total())}};
  j["condition_estimate"] = map.condition_estimate();
  return j;
}

nlohmann::json estimate_json(const FitEstimate& e) {
  nlohmann::json solvers = nlohmann::json::array();
  for (const SolverEstimate& s : e.solvers) {
    nlohmann::json r{{"solver", std::string(solver_name(s.solver))},
                     {"bytes", s.bytes},
                     {"within_limit", s.within_limit},
                     {"note", s.note}};
    const auto number = [](double v) {
      return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
    };  // null: unknown
    r["seconds"] = number(s.seconds);
    r["factor_entries"] = number(s.factor_entries);
    r["work"] = number(s.work);
    solvers.push_back(r);
  }
  return {{"mean_neighbors", e.mean_neighbors},
          {"max_neighbors", e.max_neighbors},
          {"nonzeros", e.nonzeros},
          {"exact", e.exact},
          {"auto_starts_with", std::string(solver_name(e.chosen))},
          {"solvers", solvers}};
}

std::string estimate_text(const nlohmann::json& j) {
  std::ostringstream o;
  char buf[512];
  auto line = [&](const std::string& name, const std::string& value) {
    o << name << std::string(name.size() < 19 ? 19 - name.size() : 1, ' ') << value << '\n';
  };
  line("controls", std::to_string(j["controls"].get<std::size_t>()));
  std::snprintf(buf, sizeof buf, "%.6g%s", j["radius"].get<double>(),
                j.contains("neighbours_asked") ? "  (for the neighbours asked)" : "");
  line("radius", buf);
  if (!j.contains("estimate")) return o.str();
  const auto& e = j["estimate"];
  std::snprintf(buf, sizeof buf, "%.2f per control, at most %.0f%s", e["mean_neighbors"].get<double>(),
                e["max_neighbors"].get<double>(),
                e["exact"].get<bool>() || e["counted"].get<bool>() ? "" : " (of a sample of 256 controls)");
  line("neighbours", buf);
  std::snprintf(buf, sizeof buf, "%.4g", e["nonzeros"].get<double>());
  line("non-zeros of A", buf);
  line("auto starts with", e["auto_starts_with"].get<std::string>());
  for (const auto& s : e["solvers"]) {
    const std::string secs = s["seconds"].is_null() ? std::string("unknown") : [&] {
      std::snprintf(buf, sizeof buf, "%.3g s", s["seconds"].get<double>());
      return std::string(buf);
    }();
    std::snprintf(buf, sizeof buf, "%.3g GiB, %s%s; %s", s["bytes"].get<double>() / kGiB, secs.c_str(),
                  s["within_limit"].get<bool>() ? "" : " (beyond --memory-limit)",
                  s["note"].get<std::string>().c_str());
    line(s["solver"].get<std::string>(), buf);
  }
  return o.str();
}

std::string stats_text(const SpaceMap& map) {
  const FitStats s = report_stats(map);
  std::ostringstream o;
  char buf[256];
  auto line = [&](const std::string& name, const std::string& value) {
    o << name << std::string(name.size() < 19 ? 19 - name.size() : 1, ' ') << value << '\n';
  };
  auto fmt = [&](const char* f, auto... v) {
    std::snprintf(buf, sizeof buf, f, v...);
    return std::string(buf);
  };
  line("controls", std::to_string(s.controls));
  line("radius", fmt("%g", map.radius()));
  line("kernel", std::string(kernel_name(map.kernel())));
  line("polynomial", std::string(polynomial_name(map.polynomial())));
  line("neighbours", fmt("%zu pairs, %.2f per control", s.neighbor_pairs, s.mean_neighbors));
  line("ordering",
       s.solver == Solver::Cholmod || s.solver == Solver::Eigen
           ? std::string("the solver's own (") + (s.solver == Solver::Cholmod ? "nested dissection" : "AMD") + ")"
           : std::string(ordering_name(s.ordering)));
  // For the solvers that order the matrix themselves, the envelope lines are what the paper's
  // solver would have had, for comparison.
  const bool direct_own = s.solver == Solver::Cholmod || s.solver == Solver::Eigen;
  const std::string envelope_label = direct_own ? " (envelope solver's, for comparison)" : "";
  line("bandwidth" + envelope_label, fmt("%zu  (identity %zu, breadth-first %zu, reverse breadth-first %zu, rcm %zu)",
                                         s.bandwidth, s.identity.bandwidth, s.breadth_first.bandwidth,
                                         s.reverse_breadth_first.bandwidth, s.reverse_cuthill_mckee.bandwidth));
  line("envelope entries" + envelope_label,
       fmt("%zu  (identity %zu, breadth-first %zu, reverse breadth-first %zu, rcm %zu)", s.envelope_entries,
           s.identity.envelope, s.breadth_first.envelope, s.reverse_breadth_first.envelope,
           s.reverse_cuthill_mckee.envelope));
  line("envelope bytes", fmt("%zu  (dense %zu, %.1f%%; 4-byte floats as in the paper)", s.envelope_bytes, s.dense_bytes,
                             100.0 * double(s.envelope_bytes) / double(s.dense_bytes)));
  const std::string handover = !s.fell_back ? std::string()
                               : s.iterations < kCgMaxIterations
                                   ? "; conjugate gradients gave way after " + std::to_string(s.iterations) +
                                         " steps (the direct solve was predicted faster)"
                                   : std::string("; conjugate gradients stagnated, this direct solver took over");
  if (s.solver == Solver::Cg)
    line("solver", fmt("%s  (%zu iterations to a relative residual ||b - Ax|| / ||b|| of %.3g; matrix %zu entries)",
                       std::string(solver_name(s.solver)).c_str(), s.iterations, s.solver_residual, s.factor_nonzeros));
  else
    line("solver",
         fmt(direct_own ? "%s  (factor %zu entries; the envelope solver's work would be %.3g multiply-adds)%s"
                        : "%s  (factor %zu entries; envelope work %.3g multiply-adds)%s",
             std::string(solver_name(s.solver)).c_str(), s.factor_nonzeros, s.envelope_work, handover.c_str()));
  line("residual", fmt("%.3g max, %.3g relative", s.residual_max, s.residual_relative));
  line("condition", fmt("%.3g (estimate of the matrix's 2-norm condition number)", map.condition_estimate()));
  line("time (us)",
       fmt("index %.1f, graph %.1f, ordering %.1f, assembly %.1f, factorization %.1f, solve %.1f, "
           "residual %.1f, total %.1f",
           us(s.seconds_index), us(s.seconds_graph), us(s.seconds_ordering), us(s.seconds_assembly),
           us(s.seconds_factorization), us(s.seconds_solve), us(s.seconds_residual), us(s.seconds_total())));
  return o.str();
}

nlohmann::json folds_json(const FoldReport& r) {
  nlohmann::json j;
  j["phase"] = r.phase;
  j["vertices"] = r.vertices;
  j["samples"] = r.samples;
  j["min_det"] = r.min_det;
  j["min_at"] = {r.min_at.x(), r.min_at.y(), r.min_at.z()};
  j["folded"] = r.folded;
  j["folded_vertices"] = r.folded_vertices.size();
  // JSON has no infinity: null when no checked point ever folds.
  j["fold_free_phase"] = std::isfinite(r.fold_free_phase) ? nlohmann::json(r.fold_free_phase) : nlohmann::json();
  if (r.edge_triangles > 0) {
    j["area_edge_triangles"] = r.edge_triangles;
    j["area_edge_flipped"] = r.edge_flipped;
  }
  return j;
}

std::string folds_text(const FoldReport& r) {
  std::ostringstream o;
  o << "folds (det dT/dx at phase " << r.phase << ", " << r.vertices << " vertices and " << r.samples - r.vertices
    << " points inside triangles):\n";
  o << "  minimum det              " << r.min_det << " at (" << r.min_at.x() << ", " << r.min_at.y() << ", "
    << r.min_at.z() << ")\n";
  o << "  points with det <= 0     " << r.folded << " (" << r.folded_vertices.size() << " vertices)\n";
  if (r.edge_triangles > 0)
    o << "  active area's edge       " << r.edge_flipped << " of " << r.edge_triangles
      << " triangles across it turned over\n";
  if (std::isfinite(r.fold_free_phase))
    o << "  fold-free up to phase    " << r.fold_free_phase
      << (r.fold_free_phase < r.phase ? "  (FOLDS at the phase checked: lower the phase or raise the radius)" : "")
      << "\n";
  else
    o << "  fold-free up to phase    any (no point checked ever folds)\n";
  return o.str();
}

}  // namespace csrbf::cli
