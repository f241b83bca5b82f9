// Units that csrbf's limits and reports use: one GiB (2^30 bytes), the unit of --memory-limit and of
// every memory figure a message states.
#pragma once

namespace csrbf {

/// 2^30 bytes, as a double (memory limits and figures are doubles of bytes).
inline constexpr double kGiB = 1073741824.0;

}  // namespace csrbf
