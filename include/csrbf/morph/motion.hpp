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

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace csrbf::morph {

struct PatchMotion {
  /// Slip: each point moves only within its patch's surface, as the mapping of the other patches'
  /// motion carries it (a plane stays a plane; a curved patch is projected back onto its faces).
  /// Free: the patch's points are no controls; they move as the mapping carries them (as interior
  /// points do).
  enum class Kind { Fixed, Translate, Rotate, Displacements, Slip, Free };
  std::string patch;
  std::string where;        ///< "motion.json: patches.wing", for messages
  bool by_default = false;  ///< not listed: the kind is the default of its type or shape
  Kind kind = Kind::Fixed;
  Vec3 translation = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();  ///< unit
  double degrees = 0;
  Vec3 origin = Vec3::Zero();
  /// Displacements: the file (empty: rows given in the motion itself), and its (point id,
  /// displacement, line: the file's, or the row's index + 1) in file order.
  std::filesystem::path file;
  struct Given {
    std::uint64_t point;
    Vec3 d;
    std::size_t line;
  };
  std::vector<Given> given;
  /// Where displacements came from, for messages: the file, or "motion: patches.flap.displacements".
  std::string source() const;
  /// "flap.txt:12: " or "motion: patches.flap.displacements[11]: ".
  std::string at(const Given& g) const;

  /// The rigid motion's displacement of x (translate, rotate; zero when fixed).
  Vec3 displacement(const Vec3& x) const;
};

struct Motion {
  std::string file;
  std::optional<double> radius;
  bool radius_auto = false;  ///< "radius": "auto"
  std::optional<Kernel> kernel;
  std::optional<Polynomial> polynomial;
  /// VTK meshes: the integer point or cell data array whose values name the patches.
  std::string patch_array;
  /// By name, group name (OpenFOAM's inGroups) or regular expression (OpenFOAM's "wall.*"), in the
  /// file's order: a patch named exactly takes that entry, else the first group, else the first
  /// expression that matches it in full. Patches no entry names get a default (morph.hpp).
  std::vector<PatchMotion> patches;
};

/// Reads and checks a motion file; displacement files are read relative to its folder. Errors name
/// the file and the JSON path (or the line of a displacement file) and the value. Throws
/// io::FileError.
Motion read_motion(const std::filesystem::path& path);

/// The same from a parsed JSON value (Python's csrbf.morph takes a dict): name stands for the
/// file in messages; displacement files are read relative to base. A patch's "displacements" may
/// also be rows [point_id, dx, dy, dz] in the motion itself.
Motion motion_from_json(const nlohmann::json& j, const std::string& name, const std::filesystem::path& base);

}  // namespace csrbf::morph
