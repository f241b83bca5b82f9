// Running a third-party reader that may crash on a hostile file (VTK, Gmsh) in a child process:
// its crash, its memory blow-up or its hang becomes an error naming the file, never csrbf's own
// (private to csrbf::morph).
#pragma once

#include <filesystem>
#include <functional>
#include <string>

namespace csrbf::morph::detail {

/// Runs work() in a forked child and returns the bytes it returned. work() reports a bad file by
/// throwing (its message becomes the FileError's, after "FILE: LIBRARY cannot read it: "). The
/// child dies with its parent, keeps its address space within its own size now plus
/// memory_limit_bytes (RLIMIT_AS, a back-stop: the readers check counts before this), and may send
/// at most 4 x memory_limit_bytes. A signal, an exit without a reply or a reply too large is a
/// FileError naming file and library. A signal that kills the parent kills the child too.
std::string read_in_child(const std::filesystem::path& file, const std::string& library, double memory_limit_bytes,
                          const std::function<std::string()>& work);

}  // namespace csrbf::morph::detail
