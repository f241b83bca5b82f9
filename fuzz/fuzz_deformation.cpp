// libFuzzer target: the deformation JSON reader and the fit of what it reads (scripts/fuzz.sh).
#include "csrbf/io/deformation.hpp"

#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto spec = csrbf::io::read_deformation_text(std::string(reinterpret_cast<const char*>(data), size),
                                                       "fuzz.json", CSRBF_FUZZ_BASE);
    if (spec.sources.size() > 2000) return 0;  // a fit that large is a benchmark, not a parser test
    const auto map = spec.fit();
    const csrbf::Vec3 y = map.map(spec.sources.front());
    if (!y.allFinite()) __builtin_trap();  // a fit that succeeds never gives NaN
  } catch (const csrbf::io::FileError&) {
  } catch (const csrbf::InvalidInput&) {
  } catch (const csrbf::NotPositiveDefinite&) {
  }
  return 0;
}
