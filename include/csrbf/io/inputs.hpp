// Which files a command reads, and whether an output would be one of them (csrbf never writes an
// input: not by its name, a symbolic link or a hard link to it).
#pragma once

#include <filesystem>
#include "csrbf/units.hpp"
#include <string>
#include <vector>

namespace csrbf::io {

/// A csrbf JSON document (a scene, a deformation, a motion file) and the files it names, resolved
/// against its folder: the document first, then meshes, textures, deformation, controls and
/// displacement files, for each JSON among them the files it names (three levels at most), and a
/// .gltf mesh's buffers and images. Reads only the JSON documents (each bounded as read_json_file
/// bounds it); a document that cannot be read contributes nothing more, as its reader reports it.
/// memory_limit_bytes (--memory-limit): a document is parsed only where it takes at most an eighth of
/// what the process leaves of the limit (its tree takes about 7 times its text: a 50 MB deformation
/// peaked at 357 MB before the limit of 0.1 GiB refused it); a larger one is left to its reader.
std::vector<std::filesystem::path> referenced_files(const std::filesystem::path& json,
                                                    double memory_limit_bytes = 4.0 * kGiB);

/// An eighth of what the process leaves of a whole-process limit: the most JSON text it parses (a
/// JSON tree takes about 7 times its text).
double json_bytes_within(double memory_limit_bytes) noexcept;

/// The files a mesh file reads besides itself: a .gltf's buffers and images named by a relative or
/// absolute URI (not data: URIs); nothing for other formats, or when the file cannot be read.
std::vector<std::filesystem::path> mesh_side_files(const std::filesystem::path& mesh,
                                                   double memory_limit_bytes = 4.0 * kGiB);

/// The first input that is the same file as output (the same device and inode once links are
/// followed), or empty. An output that does not exist yet is no input.
std::filesystem::path same_file_as(const std::filesystem::path& output,
                                   const std::vector<std::filesystem::path>& inputs);

}  // namespace csrbf::io
