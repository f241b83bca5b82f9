// csrbf::io: a deformation file written and read back.
#include <csrbf/io/deformation.hpp>

#include <filesystem>
#include <iostream>

int main() {
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 0.5;
  spec.sources = {csrbf::Vec3(0, 0, 0)};
  spec.destinations = {csrbf::Vec3(0, 0, 0.1)};
  const auto path = std::filesystem::temp_directory_path() / "csrbf-consumer-io.json";
  csrbf::io::write_deformation(path, spec);
  const auto back = csrbf::io::read_deformation(path);
  std::filesystem::remove(path);
  const bool ok = back.destinations == spec.destinations && back.options.radius == 0.5;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
