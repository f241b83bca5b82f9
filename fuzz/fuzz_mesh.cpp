// libFuzzer target: one mesh reader (scripts/fuzz.sh), chosen at build time by CSRBF_FUZZ_EXT (the
// file extension: .obj, .ply, .off, .xyz, or .stl / .glb for the assimp path). A mesh that loads
// must have finite positions and faces that index them; written back in its own format and read
// again, it must keep its vertices and faces.
#include "csrbf/io/error.hpp"
#include "csrbf/io/mesh.hpp"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace fs = std::filesystem;

namespace {
const fs::path& folder() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("csrbf-fuzz-mesh-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fs::path in = folder() / ("in" CSRBF_FUZZ_EXT), out = folder() / ("out" CSRBF_FUZZ_EXT);
  {
    std::ofstream f(in, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  try {
    // 64 MiB: a file that claims more is refused by the reader, not by the fuzzer's memory limit.
    auto mesh = csrbf::io::MeshDocument::load(in, 64.0 * (1 << 20));
    const auto& p = mesh.positions();
    for (const auto& v : p)
      if (!v.allFinite()) __builtin_trap();
    for (const auto& f : mesh.faces()) {
      if (f.size() < 3) __builtin_trap();
      for (auto i : f)
        if (i >= p.size()) __builtin_trap();
    }
    const std::size_t nv = p.size(), nf = mesh.faces().size();
    try {
      mesh.save(out);
    } catch (const csrbf::io::FileError&) {
      return 0;  // e.g. glTF of a mesh without faces
    }
    const auto again = csrbf::io::MeshDocument::load(out, 64.0 * (1 << 20));
    // csrbf's own readers keep vertices and faces exactly. Through assimp, STL joins equal vertices
    // on read, and assimp may join a glTF's equal vertices and drop its degenerate faces: there
    // neither count may grow.
    const std::string ext = CSRBF_FUZZ_EXT;
    const bool assimp = ext == ".stl" || ext == ".glb";
    if (!assimp && (again.positions().size() != nv || again.faces().size() != nf)) __builtin_trap();
    if (assimp && (again.positions().size() > nv || again.faces().size() > nf)) __builtin_trap();
  } catch (const csrbf::io::FileError&) {
  }
  return 0;
}
