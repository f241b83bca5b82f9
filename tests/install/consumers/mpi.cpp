// csrbf::mpi: a fit spread over the ranks of this process's MPI job (one rank when started alone),
// checked against the serial SpaceMap.
#include <csrbf/mpi/distributed.hpp>
#include <csrbf/mpi/runtime.hpp>
#include <csrbf/space_map.hpp>

#include <cmath>
#include <iostream>
#include <vector>

int main(int argc, char** argv) {
  csrbf::mpi::Runtime rt(&argc, &argv);
  std::vector<csrbf::Vec3> s, d;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) {
      s.emplace_back(0.25 * i, 0.25 * j, 0.1 * std::sin(double(i + j)));
      d.push_back(s.back() + csrbf::Vec3(0.01 * j, 0.0, 0.02 * i));
    }
  csrbf::FitOptions o;
  o.radius = 0.6;
  auto map = csrbf::mpi::DistributedMap::fit(rt.comm(), s, d, o);
  std::vector<csrbf::Vec3> x{{0.3, 0.4, 0.0}, {0.9, 0.1, 0.05}}, out(2), want(2);
  map.apply(x, out);
  csrbf::SpaceMap::fit(s, d, o).apply(x, want);
  const bool ok = (out[0] - want[0]).norm() < 1e-12 && (out[1] - want[1]).norm() < 1e-12;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
