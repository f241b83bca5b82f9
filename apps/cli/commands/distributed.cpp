#include "distributed.hpp"

#include "commands.hpp"
#include "progress.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/mpi/backends.hpp"
#include "csrbf/mpi/distributed.hpp"
#include "csrbf/mpi/runtime.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <iostream>
#include <string>
#include <vector>

namespace csrbf::cli {

namespace {

/// Each MPI rank's figures, for --json under mpirun (deform and morph).
nlohmann::json rank_stats_json(const std::vector<mpi::RankStats>& ranks) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& r : ranks)
    a.push_back({{"rank", r.rank},
                 {"controls_owned", r.controls_owned},
                 {"controls_halo", r.controls_halo},
                 {"controls_shared_dropped", r.controls_dropped},
                 {"eval_halo", r.eval_halo},
                 {"points", r.points},
                 {"matrix_nonzeros", r.matrix_nonzeros},
                 {"peak_bytes", r.peak_bytes},
                 {"bytes_sent", r.bytes_sent},
                 {"seconds",
                  {{"halo", r.seconds_halo},
                   {"assembly", r.seconds_assembly},
                   {"solve", r.seconds_solve},
                   {"residual", r.seconds_residual},
                   {"evaluate", r.seconds_evaluate}}}});
  return a;
}

void print_outcome(const MorphArgs& a, const morph::MorphOutcome& o, const std::vector<mpi::RankStats>& ranks,
                   const mpi::DistributedStats& st, const char* mode) {
  if (a.json) {
    nlohmann::json j = nlohmann::json::parse(morph::outcome_json(o));
    j["controls"] = st.controls;
    j["solver"] = mpi::distributed_solver_name(st.solver);
    j["distributed"] = {{"mode", mode},
                        {"ranks", ranks.size()},
                        {"iterations", st.iterations},
                        {"fell_back", st.fell_back},
                        {"residual_relative", st.residual_relative}};
    j["per_rank"] = rank_stats_json(ranks);
    std::cout << j.dump(2) << '\n';
    return;
  }
  std::cout << csrbf::printable(morph::outcome_text(o), true) << "  distributed (" << mode << ") over " << ranks.size()
            << " ranks: " << st.controls << " controls, solver " << mpi::distributed_solver_name(st.solver) << "\n";
  for (const auto& r : ranks)
    std::cout << "    rank " << r.rank << ": " << r.controls_owned << " controls (+" << r.controls_halo << " halo), "
              << r.points << " points evaluated, peak " << double(r.peak_bytes) / double(1 << 20) << " MiB, sent "
              << double(r.bytes_sent) / double(1 << 20) << " MiB\n";
}

}  // namespace

int run_morph_distributed(const MorphArgs& a, mpi::Runtime& rt) {
  const auto solver = mpi::parse_distributed_solver(a.solver).value_or(mpi::DistributedSolver::Auto);
  const auto print_error = [&](const std::string& what, int rank) {
    if (rt.rank() == 0)
      std::cerr << "csrbf: error: " << what << (rank > 0 ? " (rank " + std::to_string(rank) + ")" : "") << '\n';
  };
  mpi::Decomposition d;
  try {
    d = mpi::collectively(rt.comm(), [&] { return mpi::find_decomposition(a.mesh); });
  } catch (const mpi::Failure& f) {
    print_error(f.what(), f.rank());
    return f.exit_code();
  }
  if (d.kind != mpi::Decomposition::Kind::None) {
    // A decomposed mesh: every rank its processor folder, or its piece of a .pvtu.
    const int parts = int(d.parts.size());
    const std::string what = d.kind == mpi::Decomposition::Kind::OpenFoam ? " processor folders" : " pieces";
    try {
      mpi::collectively(rt.comm(), [&] {
        if (parts != rt.size())
          throw morph::JobError("morph: " + a.mesh + " is decomposed into " + std::to_string(parts) + what +
                                ": run it with mpirun -np " + std::to_string(parts) + ", not " +
                                std::to_string(rt.size()));
      });
    } catch (const mpi::Failure& f) {
      print_error(f.what(), -1);
      return 2;
    }
    mpi::DecomposedBackend backend(rt.comm(), solver, std::move(d));
    morph::MorphJob job;
    try {
      job = job_of(a, true);  // the same on every rank: its usage errors too
    } catch (const UsageError& e) {
      if (rt.rank() == 0) std::cerr << "csrbf: error: " << csrbf::printable(e.what()) << '\n';
      return 2;
    }
    job.backend = &backend;
    TerminalProgress progress(rt.rank() == 0 && !a.quiet && TerminalProgress::terminal());
    job.progress = &progress;
    try {
      const morph::MorphOutcome local = morph::run_job(job);
      progress.end();
      const auto ranks = backend.rank_stats();
      morph::MorphOutcome o = local;
      o.points = std::size_t(backend.sum(double(local.points)));
      o.result.report.prescribed = std::size_t(backend.sum(double(local.result.report.prescribed)));
      o.result.report.moving = std::size_t(backend.sum(double(local.result.report.moving)));
      o.result.report.fixed = std::size_t(backend.sum(double(local.result.report.fixed)));
      o.result.report.slip = std::size_t(backend.sum(double(local.result.report.slip)));
      o.result.report.controls = backend.stats().controls;  // shared points once
      o.ms_read = backend.max(local.ms_read);
      o.ms_quality = backend.max(local.ms_quality);
      o.ms_write = backend.max(local.ms_write);
      o.ms_total = backend.max(local.ms_total);
      o.result.report.seconds_fit = backend.max(local.result.report.seconds_fit);
      o.result.report.seconds_evaluate = backend.max(local.result.report.seconds_evaluate);
      if (rt.rank() == 0) print_outcome(a, o, ranks, backend.stats(), "decomposed");
      const int code = report_inversion(a, o, rt.rank() == 0);
      return code;
    } catch (const mpi::Failure& f) {
      print_error(f.what(), f.rank());
      return f.exit_code();
    } catch (const std::exception& e) {
      // Not agreed with the other ranks, which may wait for this one: report, and end the job.
      std::cerr << "csrbf: error (rank " << rt.rank() << "): " << csrbf::printable(e.what()) << '\n';
      MPI_Abort(rt.comm(), 1);
    }
  }
  // A single file: rank 0 reads and writes it; the fit and evaluation are spread.
  if (rt.rank() != 0) return mpi::serve(rt.comm());
  mpi::ScatterBackend backend(rt.comm(), solver);
  int code = 0;
  try {
    morph::MorphJob job = job_of(a, true);
    job.backend = &backend;
    TerminalProgress progress(!a.quiet && TerminalProgress::terminal());
    job.progress = &progress;
    const morph::MorphOutcome o = usage_errors([&] { return morph::run_job(job); });
    progress.end();
    const auto ranks = backend.rank_stats();
    print_outcome(a, o, ranks, backend.stats(), "scattered from rank 0");
    code = report_inversion(a, o, true);
  } catch (const UsageError& e) {
    std::cerr << "csrbf: error: " << csrbf::printable(e.what()) << '\n';
    code = 2;
  } catch (const mpi::Failure& f) {
    print_error(f.what(), f.rank());
    code = f.exit_code();
  } catch (const std::exception& e) {
    std::cerr << "csrbf: error: " << csrbf::printable(e.what()) << '\n';
    code = 1;
  }
  backend.finish(code);
  return code;
}

int run_deform_distributed(csrbf::mpi::Runtime& rt, const DeformArgs& da) {
  const FitArgs& fa = da.fit;
  namespace mpi = csrbf::mpi;
  if (rt.rank() != 0) return mpi::serve(rt.comm());
  const auto solver = mpi::parse_distributed_solver(fa.solver);
  mpi::ScatterBackend backend(rt.comm(), solver.value_or(mpi::DistributedSolver::Auto));
  int code = 0;
  try {
    check_deform_output(da);
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
                       {"per_rank", rank_stats_json(ranks)}};
      std::cout << j.dump(2) << '\n';
    } else {
      std::cout << "csrbf deform: " << p.size() << " vertices (" << count << " moved) of "
                << csrbf::printable(da.mesh_in) << " by " << backend.stats().controls << " controls on " << ranks.size()
                << " ranks (" << mpi::distributed_solver_name(backend.stats().solver) << "), R = " << in.options.radius
                << ", phase " << phase << " -> " << csrbf::printable(da.mesh_out) << " (" << ms << " ms)\n";
    }
  } catch (const UsageError& e) {
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

}  // namespace csrbf::cli
