// csrbf::anim: a Kochanek-Bartels track passes through its keys.
#include <csrbf/anim/tracks.hpp>

#include <iostream>

int main() {
  const csrbf::anim::PositionTrack t(
      {{0.0, csrbf::Vec3(0, 0, 0)}, {1.0, csrbf::Vec3(1, 2, 3)}, {2.0, csrbf::Vec3(2, 0, 0)}});
  const bool ok = (t.position(1.0) - csrbf::Vec3(1, 2, 3)).norm() < 1e-12;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
