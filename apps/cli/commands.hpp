#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "csrbf/estimate.hpp"
#include "csrbf/folds.hpp"
#include "csrbf/space_map.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <string>

namespace csrbf::cli {

/// Refuses (UsageError, exit 2) an output that is one of the command's inputs: the same file by
/// device and inode once links are followed, so that a symbolic or hard link to an input is that
/// input too. Checked before anything large is read. option names the output ("-o").
void check_not_an_input(const std::string& option, const std::filesystem::path& output,
                        const std::vector<std::filesystem::path>& inputs);

/// --solver's choices: the serial solvers, and "mumps" (the distributed one, under mpirun).
std::vector<std::string> solver_choices();
/// The serial solver a --solver names; "mumps" is a usage error on one process.
Solver serial_solver(const std::string& name);

/// A finite number in [lo, hi]; NaN and infinities are refused (CLI::Range lets NaN through).
CLI::Validator finite_in(double lo, double hi, const std::string& what);

/// The stats of a fit as JSON (keys named as in FitStats; times in microseconds).
nlohmann::json stats_json(const SpaceMap& map);
/// The stats as aligned "name  value" lines.
std::string stats_text(const SpaceMap& map);
/// A fit's estimate (`csrbf info --estimate`) as JSON, and `csrbf info`'s answer without a fit
/// (radius, controls, neighbours asked for, the estimate) as aligned lines.
nlohmann::json estimate_json(const FitEstimate& e);
std::string estimate_text(const nlohmann::json& j);
/// A fold report (`csrbf info --check-folds`) as JSON and as text.
nlohmann::json folds_json(const FoldReport& r);
std::string folds_text(const FoldReport& r);

}  // namespace csrbf::cli
