// csrbf::render links with its dependencies (VTK, X11); rendering itself needs a display, which the
// other tests cover.
#include <csrbf/render/movie.hpp>

#include <iostream>

int main() {
  const auto f = &csrbf::render::render_movie;
  const bool ok = f != nullptr;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
