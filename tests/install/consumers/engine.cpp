// A game engine's use of csrbf::core, compiled with -fno-exceptions: csrbf/engine.hpp only, a vertex
// buffer of interleaved positions, normals and texture coordinates deformed in place, failures as
// status codes. `engine --time` times a frame (the add_subdirectory build against Release).
#include <csrbf/engine.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <vector>

namespace {

struct Vertex {
  float position[3];
  float normal[3];
  float uv[2];
};

/// m vertices on the unit sphere (Fibonacci lattice) with their normals.
std::vector<Vertex> sphere(std::size_t m) {
  std::vector<Vertex> v(m);
  const double golden = 3.14159265358979 * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < m; ++i) {
    const double y = 1.0 - 2.0 * (double(i) + 0.5) / double(m), r = std::sqrt(1.0 - y * y), a = golden * double(i);
    const float p[3] = {float(r * std::cos(a)), float(y), float(r * std::sin(a))};
    for (int k = 0; k < 3; ++k) v[i].position[k] = v[i].normal[k] = p[k];
    v[i].uv[0] = v[i].uv[1] = 0.25f;
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  const bool timing = argc > 1 && std::strcmp(argv[1], "--time") == 0;
  const std::size_t controls = timing ? 4000 : 200, vertices = timing ? 400000 : 5000;
  // Controls on the sphere, pushed out along it by a smooth bump.
  std::vector<double> s, d;
  for (const Vertex& v : sphere(controls))
    for (int k = 0; k < 3; ++k) {
      s.push_back(v.position[k]);
      d.push_back(v.position[k] * (1.0 + 0.05 * std::sin(5.0 * v.position[0])));
    }
  csrbf::engine::Settings settings;
  settings.radius = std::sqrt(4.0 * 25.0 / double(controls));
  csrbf::engine::Deformer deformer;
  if (const auto r = csrbf::engine::Deformer::fit(s.data(), d.data(), controls, settings, deformer); !r) {
    std::printf("fit failed: %s\n", r.message);
    return 1;
  }
  const std::vector<Vertex> rest = sphere(vertices);
  std::vector<Vertex> frame = rest;
  const csrbf::engine::VertexBuffer in{const_cast<Vertex*>(rest.data()),
                                       rest.size(),
                                       sizeof(Vertex),
                                       offsetof(Vertex, position),
                                       offsetof(Vertex, normal),
                                       csrbf::engine::Scalar::Float32};
  csrbf::engine::VertexBuffer out = in;
  out.base = frame.data();
  double best = 1e300;
  for (int f = 0; f < (timing ? 7 : 1); ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    if (const auto r = deformer.deform(in, out, 0.5); !r) {
      std::printf("deform failed: %s\n", r.message);
      return 1;
    }
    best = std::min(best, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  // The vertices moved outwards by about half the bump, the normals stayed unit, the uv untouched.
  double worst = 0;
  for (std::size_t i = 0; i < vertices; ++i) {
    const float* p = frame[i].position;
    const float* n = frame[i].normal;
    const double want = 1.0 + 0.5 * 0.05 * std::sin(5.0 * rest[i].position[0]);
    worst =
        std::max(worst, std::abs(std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]) - want));
    if (std::abs(std::sqrt(double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2]) - 1.0) > 1e-5 ||
        frame[i].uv[0] != 0.25f) {
      std::printf("vertex %zu: normal not unit or uv changed\n", i);
      return 1;
    }
  }
  // A failure is a status and a message, not an exception.
  csrbf::engine::VertexBuffer bad = out;
  bad.stride = 4;
  const auto r = deformer.deform(in, bad, 0.5);
  const bool ok = worst < 0.01 && r.status == csrbf::engine::Status::InvalidInput && std::strstr(r.message, "stride");
  if (timing)
    std::printf("frame_ms %.3f (%zu vertices with normals, %zu controls)\n", best, vertices, controls);
  else
    std::printf("%s (largest error %.2g; bad stride: %s)\n", ok ? "ok" : "wrong", worst, r.message);
  return ok ? 0 : 1;
}
