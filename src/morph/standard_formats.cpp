// The standard formats' table (detail::StandardFormats): the VTK, Gmsh and CGNS readers and the
// standard cells' measure. Alone in its file, so that a program defining its own table links none
// of them (the archive's member that holds this one is then never pulled in).
#include "csrbf/morph/volume_file.hpp"
#include "volume_formats.hpp"

namespace csrbf::morph::detail {

const StandardFormats& standard_formats() {
  static const StandardFormats formats{&open_vtk, &open_gmsh, &open_cgns, &cell_quality};
  return formats;
}

}  // namespace csrbf::morph::detail
