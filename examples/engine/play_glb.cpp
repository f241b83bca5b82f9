// Plays a glb that `csrbf export --compact` (or `--compact=only`) wrote, from the file alone, as an
// engine plays it on the CPU: each mesh's weights at time t from the file's animation, then its
// CSRBF_deformation evaluated into an interleaved float vertex buffer (x y z nx ny nz), what an
// engine uploads to the GPU each frame. For the GPU, web/csrbf_deformation.glsl does the same.
//
//   csrbf-play-glb FILE.glb [--fps N] [--obj OUT.obj --time T]
//
// Prints, for each mesh with the extension, its vertices, the frames played, the median time a
// frame, and where the file also holds the morph targets (--compact), the largest difference
// between the extension's vertices and the targets', relative to the mesh's size. --obj writes
// those meshes at time T (past the animation's end: its last key). Meshes without the extension
// (rigid ones) are left out; a file without any is an error.
#include <csrbf/io/atomic_file.hpp>
#include <csrbf/gltf/runtime.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

namespace {

int usage(const char* why) {
  std::cerr << "csrbf-play-glb: " << why << "\nusage: csrbf-play-glb FILE.glb [--fps N] [--obj OUT.obj --time T]\n";
  return 2;
}

/// Positions and normals interleaved in float, as a vertex buffer holds them.
void fill(const std::vector<csrbf::Vec3>& p, const std::vector<csrbf::Vec3>& n, std::vector<float>& buffer) {
  buffer.resize(6 * p.size());
  for (std::size_t i = 0; i < p.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      buffer[6 * i + std::size_t(k)] = float(p[i][k]);
      buffer[6 * i + 3 + std::size_t(k)] = float(n[i][k]);
    }
}

}  // namespace

int main(int argc, char** argv) {
  std::string file, obj;
  double fps = 25, at = 0;
  bool time_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    if (a == "--fps" || a == "--time" || a == "--obj") {
      const char* v = value();
      if (!v) return usage((a + " needs a value").c_str());
      if (a == "--obj") {
        obj = v;
        if (obj.empty()) return usage("--obj: the file name is empty");
        continue;
      }
      char* end = nullptr;
      const double x = std::strtod(v, &end);
      if (end == v || *end || !std::isfinite(x)) return usage((a + ": '" + v + "' is not a number").c_str());
      if (a == "--fps" && !(x >= 0.1 && x <= 1000)) return usage("--fps must be in [0.1, 1000]");
      (a == "--fps" ? fps : at) = x;
      time_given = time_given || a == "--time";
    } else if (file.empty() && !a.empty() && a[0] != '-') {
      file = a;
    } else {
      return usage(("unexpected argument '" + a + "'").c_str());
    }
  }
  if (file.empty()) return usage("no glb given");
  if (!obj.empty() && !time_given) return usage("--obj needs --time");
  if (obj.empty() && time_given) return usage("--time needs --obj (the mesh at that time is written there)");
  if (time_given && at < 0) return usage("--time must be at least 0");
  std::error_code ec;
  if (!obj.empty() && std::filesystem::exists(std::filesystem::symlink_status(obj, ec)))
    return usage(("--obj: '" + obj + "' exists (nothing is replaced)").c_str());
  // A regular file of at most 2 GiB (a glb's size field is 32-bit), read whole.
  const auto size = std::filesystem::is_regular_file(file, ec) ? std::filesystem::file_size(file, ec) : 0;
  if (ec || !std::filesystem::is_regular_file(file, ec) || size > (std::uintmax_t(1) << 31)) {
    std::cerr << "csrbf-play-glb: " << file << ": not a readable regular file of at most 2 GiB\n";
    return 1;
  }
  std::ifstream in(file, std::ios::binary);
  std::vector<unsigned char> glb(size);
  if (!in || !in.read(reinterpret_cast<char*>(glb.data()), std::streamsize(size))) {
    std::cerr << "csrbf-play-glb: " << file << ": cannot be read\n";
    return 1;
  }
  try {
    const csrbf::gltf::GltfRuntime runtime(glb);
    std::size_t compact = 0;
    for (std::size_t m = 0; m < runtime.meshes(); ++m) compact += runtime.compact(m);
    if (compact == 0) {
      std::cerr << "csrbf-play-glb: " << file
                << ": no mesh carries CSRBF_deformation (write it with csrbf export --compact)\n";
      return 1;
    }
    // The OBJ goes to a partial file beside it, renamed to its name (never replacing one) when whole.
    std::optional<csrbf::io::Partial> partial;
    std::ofstream out;
    if (!obj.empty()) {
      partial.emplace(obj, csrbf::io::Partial::Kind::File, ".obj");
      out.open(partial->path(), std::ios::trunc);
      if (!out) {
        std::cerr << "csrbf-play-glb: " << obj << ": cannot be written\n";
        return 1;
      }
    }
    std::size_t written = 0;
    std::vector<csrbf::Vec3> positions, normals, fallback, fallback_normals;
    std::vector<float> buffer;
    for (std::size_t m = 0; m < runtime.meshes(); ++m) {
      if (!runtime.compact(m)) continue;
      const auto rest = runtime.rest(m);
      csrbf::Vec3 lo = rest[0], hi = rest[0];
      for (const auto& p : rest) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      const double size = (hi - lo).norm();
      const double duration = runtime.duration(m);
      if (!(duration >= 0 && duration * fps <= 100000)) {
        std::cerr << "csrbf-play-glb: " << file << ": mesh '" << runtime.name(m) << "' is animated for " << duration
                  << " s: more than 100000 frames at " << fps << " fps\n";
        return 1;
      }
      const auto frames = std::size_t(std::floor(duration * fps + 1e-9)) + 1;
      std::vector<double> ms;
      double worst = 0;
      bool targets_hold_data = true;
      for (std::size_t f = 0; f < frames; ++f) {
        const auto w = runtime.weights(m, double(f) / fps);
        const auto start = std::chrono::steady_clock::now();
        runtime.deform(m, w, positions, normals, true);
        fill(positions, normals, buffer);
        ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
        // The morph targets, where the file holds them (--compact): the same shape.
        runtime.deform(m, w, fallback, fallback_normals, false);
        double moved = 0, differ = 0;
        for (std::size_t i = 0; i < positions.size(); ++i) {
          moved = std::max(moved, (fallback[i] - rest[i]).norm());
          differ = std::max(differ, (positions[i] - fallback[i]).norm());
        }
        if (moved == 0 && differ > 0) targets_hold_data = false;  // --compact=only: empty targets
        worst = std::max(worst, differ / size);
      }
      std::nth_element(ms.begin(), ms.begin() + std::ptrdiff_t(ms.size() / 2), ms.end());
      std::cout << "mesh '" << runtime.name(m) << "': " << rest.size() << " vertices, " << frames << " frames at "
                << fps << " fps, " << ms[ms.size() / 2] << " ms a frame (median)";
      if (targets_hold_data) std::cout << ", largest difference from its morph targets " << worst << " of its size";
      std::cout << "\n";
      if (!obj.empty()) {
        runtime.deform(m, runtime.weights(m, at), positions, normals, true);
        out << "o " << (runtime.name(m).empty() ? "mesh" : runtime.name(m)) << "\n";
        char line[128];
        for (std::size_t i = 0; i < positions.size(); ++i) {
          std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\nvn %.9g %.9g %.9g\n", positions[i].x(), positions[i].y(),
                        positions[i].z(), normals[i].x(), normals[i].y(), normals[i].z());
          out << line;
        }
        const auto tri = runtime.triangles(m);
        for (std::size_t k = 0; k + 2 < tri.size(); k += 3) {
          const std::size_t a = written + tri[k] + 1, b = written + tri[k + 1] + 1, c = written + tri[k + 2] + 1;
          out << "f " << a << "//" << a << ' ' << b << "//" << b << ' ' << c << "//" << c << "\n";
        }
        written += positions.size();
      }
    }
    if (!obj.empty()) {
      out.close();
      if (!out) {
        std::cerr << "csrbf-play-glb: " << obj << ": could not be written completely\n";
        return 1;
      }
      partial->commit_new(obj);
    }
  } catch (const std::exception& e) {
    std::cerr << "csrbf-play-glb: " << file << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}
