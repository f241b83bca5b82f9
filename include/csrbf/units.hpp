// Units and numbers as csrbf's limits, reports and messages state them: one GiB (2^30 bytes), the
// unit of --memory-limit and of every memory figure, the seconds of every report, and the few ways a
// number is written.
#pragma once

#include <chrono>
#include <string>

namespace csrbf {

/// 2^30 bytes, as a double (memory limits and figures are doubles of bytes).
inline constexpr double kGiB = 1073741824.0;

/// The clock of the durations reports give (a result never depends on it: only --time-limit acts).
using Clock = std::chrono::steady_clock;
/// Seconds on Clock since t.
inline double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// v with `digits` significant digits, as printf's %g writes it ("0.3", "1.5e+07").
std::string format_significant(double v, int digits);
/// bytes in GiB with `digits` significant digits and the unit ("0.25 GiB").
std::string format_gib(double bytes, int digits = 3);
/// The shortest text that reads back as v exactly (std::to_chars): "0.1", "1e+300".
std::string format_shortest(double v);

}  // namespace csrbf
