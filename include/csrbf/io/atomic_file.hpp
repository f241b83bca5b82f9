// Writing outputs so that a failure never leaves a half-written file or clobbers an existing one:
// everything is written to a temporary name in the target's folder and renamed over the target
// only once complete.
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>

namespace csrbf::io {

/// Throws FileError when the target's folder does not exist or is not a folder.
void check_output_path(const std::filesystem::path& target);

/// Calls write(stream) on a temporary file beside target, then renames it to target. On any
/// exception the temporary file is removed and target is untouched.
void write_atomically(const std::filesystem::path& target, const std::function<void(std::ostream&)>& write);

/// For writers that need a path of their own (and may write side files, like glTF's .bin): calls
/// write(path) with path = a fresh temporary folder / target's file name, then moves every file the
/// writer made there into target's folder. On failure nothing is moved and the folder is removed.
void write_atomically_via_folder(const std::filesystem::path& target,
                                 const std::function<void(const std::filesystem::path&)>& write);

}  // namespace csrbf::io
