// A scene as glTF 2.0 (`csrbf export`), for game engines, Blender and web pages: objects as nodes
// with their meshes, parts as primitives with their materials, trajectories as translation
// channels, orientations as rotation channels, and CSRBF deformations as morph targets whose
// weights follow their phase schedules (docs/export.md). Part of csrbf::gltf (the core, anim and
// files): texture coordinates and the image check come from whoever calls it (GltfOptions::textures;
// csrbf::render::export_gltf gives VTK's, as `csrbf export` does).
//
// What is exact and what is sampled:
// - A Kochanek-Bartels trajectory is a cubic Hermite curve in time: written as CUBICSPLINE with each
//   key's in- and out-tangents, it is the same curve.
// - A slerp orientation track is written key for key (glTF's LINEAR rotation is slerp); a squad track
//   is sampled at the frame rate, and the largest angle between squad and the slerp of the samples
//   is reported.
// - A deformation T(x) = x + t d(x) is linear in its phase t: one morph target holding d over the
//   vertices it moves (a sparse accessor), weighted by the phase. Summed deformations are sums of
//   targets, so exact; the weights follow linear schedules exactly and smooth ones sampled at the
//   frame rate (the largest vertex error is reported).
// - Composed deformations (T2 o T1) and contact deformations are not linear in their phases: they are
//   baked, one target a frame holding the part's displacement at that frame, the weights cross-fading
//   from each frame to the next (two active at once).
#pragma once

#include "csrbf/anim/scene.hpp"
#include "csrbf/units.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

namespace csrbf::gltf {

enum class Bake {
  Auto,    ///< bake what is not linear in its weights, and objects over the engine limit
  Always,  ///< bake every deforming part
  Never,   ///< refuse (InvalidInput) a scene that needs baking
};

/// The CSRBF_deformation extension (docs/gltf/CSRBF_deformation.md): each deformation that a morph
/// target holds exactly, written as its sources, coefficients, radius and polynomial.
enum class Compact {
  Off,           ///< morph targets only
  WithFallback,  ///< the extension beside the targets it replaces (extensionsUsed): every viewer plays it
  Only,          ///< the replaced targets hold nothing (extensionsRequired): the extension is needed
};

/// What a textured object needs beyond the core: its texture coordinates (u v a vertex, v up, for the
/// rest shape's vertices and these triangles' corners, by this mapping) and a check that the image
/// decodes (throws io::FileError where it does not). Empty: a textured scene is refused by name.
struct TextureSupport {
  std::function<std::vector<float>(const anim::Object&, const std::vector<std::uint32_t>& faces, anim::TextureMapping)>
      coordinates;
  std::function<void(const std::string& file)> check_decodes;
};

struct GltfOptions {
  double fps = 0;  ///< the sampling rate; 0: the scene's
  Bake bake = Bake::Auto;
  Compact compact = Compact::Off;
  /// EXT_meshopt_compression: every vertex attribute, index and animation buffer view compressed by
  /// meshoptimizer's codecs (the extension required; Blender 3.4 does not read it).
  bool meshopt = false;
  /// KHR_mesh_quantization: positions and displacements as normalized 16-bit integers in each
  /// object's box (its node scales them back), normals as 8-bit; the extension required. Not with
  /// compact (the extension's sources are in float coordinates).
  bool quantize = false;
  std::size_t max_active = 8;  ///< morph targets active at once in an object (three.js: 8)
  /// The whole process's limit (--memory-limit): baked frames are refused beyond what the program
  /// leaves of it.
  double memory_limit_bytes = 4.0 * kGiB;
  TextureSupport textures;  ///< render::export_gltf and render::gltf_binary set VTK's
};

struct GltfPartReport {
  std::string object, part;
  std::size_t targets = 0;
  bool baked = false;
  std::string why;  ///< why baked, or empty
};

struct GltfObjectReport {
  std::string name;
  std::size_t vertices = 0, targets = 0, max_active = 0;
  double rotation_deviation_deg = 0;  ///< squad against the slerp of its samples, largest angle
  double max_deviation = 0;  ///< the largest vertex error of sampled weights, rotations and baking (scene units)
  /// --compact: the deformations written as CSRBF_deformation, the vertex groups (0: none needed),
  /// and the largest distance between a deformation evaluated from what is written (float sources
  /// and coefficients) and the exact displacement, at phase 1, over its vertices.
  std::size_t compact_deformations = 0, groups = 0;
  double compact_error = 0;
  /// --quantize: the largest vertex error that quantizing positions and displacements makes (scene
  /// units; counted in max_deviation).
  double quantization_error = 0;
  /// The exact targets' blended normals (n0 + w dn, normalised) against the deformed mesh's normals
  /// at w = 1/4, 1/2, 3/4, 1: the largest angle with dn fitted to those four (written), and with dn
  /// = n(1) - n0 (for comparison), in degrees.
  double normal_error_deg = 0, normal_error_endpoint_deg = 0;
};

struct GltfReport {
  std::size_t bytes = 0;   ///< the file written
  std::size_t frames = 0;  ///< sample times (the frame rate over the duration)
  double fps = 0;
  double scene_size = 0;        ///< diagonal of the box of every vertex at every frame
  std::size_t frame_bytes = 0;  ///< every frame's vertices as float xyz (the paper's game engines)
  std::size_t csrbf_bytes = 0;  ///< the deformations' sources, coefficients and radii, as doubles
  /// --compact: the bytes of the morph targets' accessors that the extension replaces (their
  /// positions and normals as written without --compact), and the extension's own (sources,
  /// coefficients, vertex groups).
  std::size_t replaced_target_bytes = 0, compact_bytes = 0;
  /// --compact: deformations (object/part/deformation) left as ordinary morph targets, their float
  /// form erring by more than 1e-5 of the object's rest size.
  std::vector<std::string> compact_left_out;
  std::size_t targets = 0, max_active = 0;
  /// Targets identical to an earlier one of their mesh (a baked part at rest over several frames),
  /// which share its accessors.
  std::size_t shared_targets = 0;
  std::vector<GltfObjectReport> objects;
  std::vector<GltfPartReport> parts;  ///< every part that deforms
};

/// Writes the scene to path (.glb: binary; .gltf: JSON with the buffer and images embedded as data
/// URIs), atomically: nothing is written unless the whole file is. Throws InvalidInput for a scene
/// that cannot be exported as asked, io::FileError for files.
GltfReport export_gltf(const anim::Scene& scene, const std::filesystem::path& path, const GltfOptions& options = {});

/// The glb bytes alone (for the web page, and tests).
std::vector<unsigned char> gltf_binary(const anim::Scene& scene, const GltfOptions& options, GltfReport& report);
/// Base64 (RFC 4648, padded): glTF's data URIs and the web page's embedded glb.
std::string base64(const unsigned char* data, std::size_t size);
/// The same, written to out in chunks (no copy of the whole).
void write_base64(std::ostream& out, const unsigned char* data, std::size_t size);
/// Writes glb bytes to path atomically, as they are (.glb) or as one .gltf text (glb_to_gltf);
/// returns the bytes written. Throws InvalidInput for another extension, io::FileError for files.
/// before_commit: as io::write_atomically's (another output renamed just before this one).
std::size_t write_gltf(const std::vector<unsigned char>& glb, const std::filesystem::path& path,
                       const std::function<void()>& before_commit = {});
/// A glb as one .gltf text: its JSON with the binary chunk as a base64 data URI.
std::string glb_to_gltf(const std::vector<unsigned char>& glb);

}  // namespace csrbf::gltf
