// The readers and writers behind open_volume (private to csrbf::morph).
#pragma once

#include "csrbf/morph/volume_file.hpp"

namespace csrbf::morph::detail {

/// path's extension in lower case (".msh"), which picks the format.
std::string lower_extension(const std::filesystem::path& path);

/// Throws io::FileError unless out can take a copy of in: a new name with in's extension.
void check_copy_target(const std::filesystem::path& in, const std::filesystem::path& out);

std::unique_ptr<VolumeFile> open_openfoam(const std::filesystem::path& path, const OpenOptions& o);
std::unique_ptr<VolumeFile> open_vtk(const std::filesystem::path& path, const OpenOptions& o);
std::unique_ptr<VolumeFile> open_gmsh(const std::filesystem::path& path, const OpenOptions& o);
std::unique_ptr<VolumeFile> open_cgns(const std::filesystem::path& path, const OpenOptions& o);

}  // namespace csrbf::morph::detail
