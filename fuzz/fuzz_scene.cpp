// libFuzzer target: the scene JSON reader, and evaluation of what it reads (scripts/fuzz.sh). Paths in
// the scene are relative to examples/, so the seeds' meshes load.
#include "csrbf/io/scene.hpp"

#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto scene = csrbf::io::read_scene_text(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json",
                                                  CSRBF_FUZZ_BASE);
    csrbf::anim::Player player(scene);
    for (const double t : {0.0, scene.duration / 3, scene.duration}) {
      player.evaluate(t);
      for (std::size_t o = 0; o < scene.objects.size(); ++o)
        for (const auto& p : player.positions(o))
          if (!p.allFinite()) __builtin_trap();
    }
  } catch (const csrbf::io::FileError&) {
  } catch (const csrbf::InvalidInput&) {
  } catch (const csrbf::NotPositiveDefinite&) {
  }
  return 0;
}
