// Units and numbers as csrbf's limits, reports and messages state them: one GiB (2^30 bytes), the
// unit of --memory-limit and of every memory figure, and the few ways a number is written.
#pragma once

#include <string>

namespace csrbf {

/// 2^30 bytes, as a double (memory limits and figures are doubles of bytes).
inline constexpr double kGiB = 1073741824.0;

/// v with `digits` significant digits, as printf's %g writes it ("0.3", "1.5e+07").
std::string format_significant(double v, int digits);
/// bytes in GiB with `digits` significant digits and the unit ("0.25 GiB").
std::string format_gib(double bytes, int digits = 3);
/// The shortest text that reads back as v exactly (std::to_chars): "0.1", "1e+300".
std::string format_shortest(double v);

}  // namespace csrbf
