// The motion file of `csrbf morph`: what each named patch of a volume mesh does (docs/morphing.md).
//
//   {"radius": 2.0, "kernel": "c2", "polynomial": "none",
//    "patches": {"wing": {"rotate": {"axis": [0, 0, 1], "degrees": 5, "origin": [0.25, 0, 0]}},
//                "inlet": "fixed",
//                "lower": {"translate": [0, 0.02, 0]},
//                "flap": {"displacements": "flap.txt"}}}
//
// flap.txt: one line a point, "point_id dx dy dz" in the mesh's point numbering (Gmsh: node tags);
// '#' comments. A VTK mesh's patches are the values of an integer data array: "patch_array": "NAME".
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/types.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::morph {

struct PatchMotion {
  enum class Kind { Fixed, Translate, Rotate, Displacements };
  std::string patch;
  std::string where;  ///< "motion.json: patches.wing", for messages
  Kind kind = Kind::Fixed;
  Vec3 translation = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();  ///< unit
  double degrees = 0;
  Vec3 origin = Vec3::Zero();
  /// Displacements: the file, and its (point id, displacement, line) in file order.
  std::filesystem::path file;
  struct Given {
    std::uint64_t point;
    Vec3 d;
    std::size_t line;
  };
  std::vector<Given> given;

  /// The rigid motion's displacement of x (translate, rotate; zero when fixed).
  Vec3 displacement(const Vec3& x) const;
};

struct Motion {
  std::string file;
  std::optional<double> radius;
  std::optional<Kernel> kernel;
  std::optional<Polynomial> polynomial;
  /// VTK meshes: the integer point or cell data array whose values name the patches.
  std::string patch_array;
  std::vector<PatchMotion> patches;  ///< by name
};

/// Reads and checks a motion file; displacement files are read relative to its folder. Errors name
/// the file and the JSON path (or the line of a displacement file) and the value. Throws
/// io::FileError.
Motion read_motion(const std::filesystem::path& path);

}  // namespace csrbf::morph
