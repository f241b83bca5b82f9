// libFuzzer target: the controls text parser (scripts/fuzz.sh).
#include "csrbf/io/controls.hpp"

#include <cstdint>
#include <sstream>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const auto c = csrbf::io::parse_controls(in, "fuzz");
    if (c.sources.size() != c.destinations.size() || c.sources.size() != c.lines.size()) __builtin_trap();
    for (std::size_t i = 0; i < c.sources.size(); ++i)
      if (!c.sources[i].allFinite() || !c.destinations[i].allFinite()) __builtin_trap();
  } catch (const csrbf::io::FileError&) {
  }
  return 0;
}
