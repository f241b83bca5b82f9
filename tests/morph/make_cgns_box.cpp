// Writes the tests' CGNS box (tests/morph/cgns_box.hpp): make_cgns_box OUT.cgns [N] [single|double] [tets|hexes]
#include "cgns_box.hpp"

#include <cstdlib>
#include <iostream>
#include <string>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: make_cgns_box OUT.cgns [N] [single]\n";
    return 2;
  }
  try {
    const int n = argc > 2 ? std::atoi(argv[2]) : 4;
    csrbf::test::write_cgns_box(argv[1], n, 1.0 / n, argc > 3 && std::string(argv[3]) == "single",
                                argc > 4 && std::string(argv[4]) == "tets");
  } catch (const std::exception& e) {
    std::cerr << e.what() << '\n';
    return 1;
  }
  return 0;
}
