// csrbf::morph_formats: the VTK, Gmsh and CGNS readers and the standard cells' measure, registered
// in csrbf::morph's table (detail::StandardFormats) as the program starts. The target's link
// options name csrbf_morph_formats_registered (--undefined), so that the linker takes this object
// from the archive whether or not the program calls anything of it: linking the target registers.
#include "csrbf/morph/quality.hpp"
#include "csrbf/morph/volume_file.hpp"
#include "volume_formats.hpp"

namespace csrbf::morph::detail {

namespace {
const StandardFormats kStandardFormats{&open_vtk, &open_gmsh, &open_cgns, &cell_quality};
}  // namespace

}  // namespace csrbf::morph::detail

extern "C" {
extern const int csrbf_morph_formats_registered;
const int csrbf_morph_formats_registered =
    (csrbf::morph::detail::register_standard_formats(csrbf::morph::detail::kStandardFormats), 1);
}
