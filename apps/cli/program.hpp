// What every csrbf program does around its command (csrbf-cli, csrbf-cli-mpi, csrbf-morph): its
// start, OpenFOAM's option spellings, parse errors and the errors a command throws, each printed
// as "csrbf: error: ..." with the exit status of docs (2 usage, 1 bad data or failure).
#pragma once

#include <CLI/CLI.hpp>

#include <functional>

namespace csrbf::cli {

/// Standard streams held, OpenBLAS and OpenMP single-threaded under an address-space or process
/// limit (the program runs again with them set), SIGXFSZ ignored (a write past ulimit -f fails and
/// its partial file is removed), and partial files removed on signals.
void start_program(char** argv);

/// --time-limit SECONDS: a command still running then ends with exit 1 and writes nothing.
void add_time_limit(CLI::App* cmd, double& seconds);

/// OpenFOAM's spellings, which CLI11 would read as bundled short flags: -time T and -latestTime.
void openfoam_spellings(int argc, char** argv);

/// Prints a parse error (or --help) as csrbf prints every error, unless quiet; the exit status.
int parse_failed(CLI::App& app, const CLI::ParseError& e, bool quiet);

/// Replaces this process with the csrbf program `name` in this program's own folder (libexec/csrbf),
/// with argv. Returns only where it cannot: 1, having said why on stderr.
int run_sibling(const char* name, char** argv);

/// Runs a command: its status, or 2 for a UsageError and 1 for any other error, printed.
int run_command(const std::function<int()>& command);

}  // namespace csrbf::cli
