// A whole morph as `csrbf morph` and Python's csrbf.morph run it: open the mesh, read the motion,
// fit, move, measure the quality before and after, and write the result unless it inverts cells.
#pragma once

#include "csrbf/errors.hpp"
#include "csrbf/morph/morph.hpp"
#include "csrbf/morph/motion.hpp"
#include "csrbf/morph/quality.hpp"
#include "csrbf/units.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::morph {

/// A job whose options contradict each other or lack a value (no radius anywhere, an output of
/// another format, neither an output nor in place): csrbf's one usage error, exit status 2.
using JobError = UsageError;

struct MorphJob {
  std::filesystem::path mesh, motion;
  std::filesystem::path motion_series;  ///< run_series: the folder of motions named by time
  /// The motion itself, in place of the file `motion` (Python's dict; `motion` then names it in
  /// the report).
  std::optional<Motion> motion_given;
  std::filesystem::path out;  ///< empty: no output (or in_place)
  bool in_place = false;
  bool write = true;  ///< false: measure only (Python without an output)
  /// Override the motion file's values.
  std::optional<double> radius;
  bool radius_auto = false;  ///< `--radius auto`; also where neither radius nor the motion file gives one
  std::optional<Kernel> kernel;
  std::optional<Polynomial> polynomial;
  std::optional<double> greedy;
  double greedy_budget = 0.2;  ///< MorphOptions::greedy_budget
  int levels = 0;              ///< MorphOptions::levels: 0 auto, 1 or 2
  Solver solver = Solver::Auto;
  double phase = 1.0;
  double memory_limit_bytes = 4.0 * kGiB;
  bool force = false;  ///< write even if cells invert
  /// OpenFOAM: the time whose mesh is morphed ("latest" or a time, as `-time`; empty: constant),
  /// and whose polyMesh gets the moved points (openfoam.hpp).
  std::string time;
  /// Where the mapping is fitted and evaluated, and the mesh read and written (MorphBackend);
  /// null: this process alone.
  MorphBackend* backend = nullptr;
  /// Told of the radius chosen, the prediction and each phase's progress (null: nothing).
  Progress* progress = nullptr;
};

struct MorphOutcome {
  std::string mesh, motion, output;
  std::string format, encoding;
  std::string time;  ///< the OpenFOAM time folder read and written, or empty
  std::size_t points = 0, cells = 0, patches = 0;
  std::string motion_summary;  ///< "wing rotate, inlet fixed"
  MorphOptions options;
  MorphResult result;
  MeshQuality before, after;
  bool inverts = false;     ///< more cells inverted after than before
  double safe_phase = 1.0;  ///< where inverts: the largest phase that inverts none
  bool written = false;
  double ms_read = 0, ms_quality = 0, ms_write = 0, ms_total = 0;
};

/// The job's options and its output, checked before anything is read (run_job and run_series
/// call it). Throws JobError, or io::FileError for an output that exists or a missing folder.
void check_job(const MorphJob& job);

/// The morph's options of a job and its motion: the job's, else the motion's, else the defaults
/// (R: auto).
MorphOptions morph_options(const MorphJob& job, const Motion& motion);

/// Runs the job. Throws JobError for contradicting options, io::FileError for bad files (naming
/// them), other csrbf::Error for a fit that fails. A morph that inverts cells is not an exception:
/// written is false unless force.
MorphOutcome run_job(const MorphJob& job);

/// A series of motions, one a time step (`csrbf morph --motion-series DIR`): DIR's files named by
/// time (`0.1.json`, `0.2.json`: a motion file each, whose displacements are from the mesh read,
/// not from the previous step's), morphed in increasing time, each written into that time's
/// polyMesh (of the -o copy, or of the case with in_place), so a coupled solver finds one moved
/// mesh a time. Every step takes the same R where it can (auto: from the series' largest
/// displacement), so the fits share one matrix and one factorisation and each step solves for
/// its displacements alone. All or nothing: a step that fails or inverts cells (unless force)
/// writes no step. OpenFOAM cases only.
struct SeriesOutcome {
  std::string mesh, series, output;
  std::vector<MorphOutcome> steps;  ///< each: its time (MorphOutcome::time) and motion file
  std::vector<char> reused;         ///< per step: its fits took an earlier step's factorisation
  std::size_t factorisations = 0, solves_reused = 0;
  bool written = false;
  double ms_read = 0, ms_write = 0, ms_total = 0;
};

/// job.motion_series names the folder (job.motion is unused). Throws as run_job does.
SeriesOutcome run_series(const MorphJob& job);
std::string series_json(const SeriesOutcome& s);
std::string series_text(const SeriesOutcome& s);

/// The outcome as one JSON object (the report of `csrbf morph --json`).
std::string outcome_json(const MorphOutcome& o);
/// The outcome as the text report of `csrbf morph`.
std::string outcome_text(const MorphOutcome& o);

}  // namespace csrbf::morph
