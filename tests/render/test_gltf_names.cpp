// csrbf::render's old names for csrbf::gltf's exporter, meshopt reader and runtime
// (csrbf/render/gltf_export.hpp, gltf_meshopt.hpp, gltf_runtime.hpp): the same types and functions,
// and render's own exporter, which gives gltf's VTK's texture coordinates and image check.
#include "csrbf/errors.hpp"
#include "csrbf/gltf/glb.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/render/gltf_export.hpp"
#include "csrbf/render/gltf_meshopt.hpp"
#include "csrbf/render/gltf_runtime.hpp"

#include "io/test_helpers.hpp"
#include "render/render_test_helpers.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>
#include <vector>

using namespace csrbf;
using nlohmann::json;

namespace {

// One type a function: the same type where both names are one function (a comparison of the
// pointers would say the same, but GCC warns of it as a self-comparison).
template <auto F>
struct FunctionIdentity {};

}  // namespace

static_assert(std::is_same_v<render::Bake, gltf::Bake>);
static_assert(std::is_same_v<render::Compact, gltf::Compact>);
static_assert(std::is_same_v<render::GltfOptions, gltf::GltfOptions>);
static_assert(std::is_same_v<render::GltfReport, gltf::GltfReport>);
static_assert(std::is_same_v<render::GltfObjectReport, gltf::GltfObjectReport>);
static_assert(std::is_same_v<render::GltfPartReport, gltf::GltfPartReport>);
static_assert(std::is_same_v<render::TextureSupport, gltf::TextureSupport>);
static_assert(std::is_same_v<render::MeshoptView, gltf::MeshoptView>);
static_assert(std::is_same_v<render::GltfRuntime, gltf::GltfRuntime>);
static_assert(std::is_same_v<FunctionIdentity<&render::base64>, FunctionIdentity<&gltf::base64>>);
static_assert(std::is_same_v<FunctionIdentity<&render::write_base64>, FunctionIdentity<&gltf::write_base64>>);
static_assert(std::is_same_v<FunctionIdentity<&render::write_gltf>, FunctionIdentity<&gltf::write_gltf>>);
static_assert(std::is_same_v<FunctionIdentity<&render::glb_to_gltf>, FunctionIdentity<&gltf::glb_to_gltf>>);
static_assert(
    std::is_same_v<FunctionIdentity<&render::gltf_without_meshopt>, FunctionIdentity<&gltf::gltf_without_meshopt>>);
// render's exporter keeps gltf's signatures, but is a function of its own (it fills in the textures).
static_assert(std::is_same_v<decltype(&render::export_gltf), decltype(&gltf::export_gltf)>);
static_assert(std::is_same_v<decltype(&render::gltf_binary), decltype(&gltf::gltf_binary)>);
static_assert(&render::export_gltf != &gltf::export_gltf);
static_assert(&render::gltf_binary != &gltf::gltf_binary);

namespace {

const std::string kChecker = (std::filesystem::path(CSRBF_SOURCE_DIR) / "examples" / "checker.png").string();

/// The moving red ball (examples/sphere.obj), its material textured with the checker, sphere-mapped.
anim::Scene textured_ball() {
  anim::Scene scene = test::moving_ball();
  scene.objects[0].material.texture = kChecker;
  scene.objects[0].material.mapping = anim::TextureMapping::Sphere;
  return scene;
}

/// Every face of the object, as the exporter's primitive of the faces in no part lists them.
std::vector<std::uint32_t> all_faces(const anim::Object& object) {
  std::vector<std::uint32_t> faces(object.faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) faces[f] = std::uint32_t(f);
  return faces;
}

/// The TEXCOORD_0 floats of the glb's first primitive (u v a vertex), or none where it has none.
std::vector<float> texcoords(const std::vector<unsigned char>& glb) {
  const gltf::GlbChunks chunks = gltf::split_glb(glb);
  const json doc = json::parse(chunks.json);
  const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  if (!attributes.contains("TEXCOORD_0")) return {};
  const json& accessor = doc["accessors"][attributes["TEXCOORD_0"].get<std::size_t>()];
  EXPECT_EQ(accessor["type"], "VEC2");
  EXPECT_EQ(accessor["componentType"], gltf::code(gltf::ComponentType::Float));
  const json& view = doc["bufferViews"][accessor["bufferView"].get<std::size_t>()];
  EXPECT_FALSE(view.contains("byteStride") && view["byteStride"] != 8);
  const std::size_t at = view.value("byteOffset", std::size_t(0)) + accessor.value("byteOffset", std::size_t(0));
  std::vector<float> uv(2 * accessor["count"].get<std::size_t>());
  EXPECT_LE(at + 4 * uv.size(), chunks.bin.size());
  std::memcpy(uv.data(), chunks.bin.data() + at, 4 * uv.size());
  return uv;
}

std::string refusal(const anim::Scene& scene, const gltf::GltfOptions& options) {
  gltf::GltfReport report;
  try {
    gltf::gltf_binary(scene, options, report);
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return "(not refused)";
}

}  // namespace

TEST(GltfNames, VtkTexturesSetsBothHooks) {
  const render::TextureSupport vtk = render::vtk_textures();
  ASSERT_TRUE(vtk.coordinates);
  ASSERT_TRUE(vtk.check_decodes);
  const anim::Scene scene = textured_ball();
  const anim::Object& ball = scene.objects[0];
  const std::vector<float> uv = vtk.coordinates(ball, all_faces(ball), anim::TextureMapping::Sphere);
  ASSERT_EQ(uv.size(), 2 * ball.rest.size());
  for (float c : uv) {
    EXPECT_GE(c, 0.0f);
    EXPECT_LE(c, 1.0f);
  }
  EXPECT_NO_THROW(vtk.check_decodes(kChecker));
  const test::TempDir dir;
  test::write_text(dir / "text.png", "not an image\n");
  EXPECT_THROW(vtk.check_decodes((dir / "text.png").string()), io::FileError);
}

TEST(GltfNames, RendersExporterWritesVtksSphereCoordinates) {
  const anim::Scene scene = textured_ball();
  const anim::Object& ball = scene.objects[0];
  render::GltfReport report;
  const std::vector<unsigned char> glb = render::gltf_binary(scene, {}, report);
  const std::vector<float> uv = texcoords(glb);
  ASSERT_EQ(uv.size(), 2 * ball.rest.size());
  // Every vertex in the image, and the sphere's coordinates spread over it, not one spot.
  float lo[2] = {1, 1}, hi[2] = {0, 0};
  for (std::size_t i = 0; i < uv.size(); ++i) {
    EXPECT_GE(uv[i], 0.0f) << i;
    EXPECT_LE(uv[i], 1.0f) << i;
    lo[i % 2] = std::min(lo[i % 2], uv[i]);
    hi[i % 2] = std::max(hi[i % 2], uv[i]);
  }
  EXPECT_GT(hi[0] - lo[0], 0.9f);
  EXPECT_GT(hi[1] - lo[1], 0.9f);
  // Exactly what VTK's projection gives the rest shape.
  EXPECT_EQ(uv, render::vtk_textures().coordinates(ball, all_faces(ball), anim::TextureMapping::Sphere));
  const json doc = json::parse(gltf::split_glb(glb).json);
  ASSERT_EQ(doc["images"].size(), 1u);
  EXPECT_EQ(doc["images"][0]["mimeType"], "image/png");
  EXPECT_EQ(doc["images"][0]["name"], "checker.png");
}

TEST(GltfNames, GltfsExporterWithoutTextureSupportRefusesATexturedScene) {
  const anim::Scene scene = textured_ball();
  // No coordinates: refused, naming the object and what is missing.
  const std::string none = refusal(scene, {});
  EXPECT_NE(none.find("'ball'"), std::string::npos) << none;
  EXPECT_NE(none.find("no texture coordinates"), std::string::npos) << none;
  // Coordinates but no image check: refused, naming the texture.
  gltf::GltfOptions half;
  half.textures.coordinates = render::vtk_textures().coordinates;
  const std::string unchecked = refusal(scene, half);
  EXPECT_NE(unchecked.find("'" + kChecker + "'"), std::string::npos) << unchecked;
  EXPECT_NE(unchecked.find("no image check"), std::string::npos) << unchecked;
  // Without the texture it needs neither, and writes no coordinates.
  anim::Scene plain = scene;
  plain.objects[0].material.texture.clear();
  gltf::GltfReport report;
  EXPECT_TRUE(texcoords(gltf::gltf_binary(plain, {}, report)).empty());
}

TEST(GltfNames, RendersExporterKeepsTheCallersTextureSupport) {
  const anim::Scene scene = textured_ball();
  std::vector<std::string> checked;
  render::GltfOptions options;
  options.textures.coordinates = [](const anim::Object& object, const std::vector<std::uint32_t>&,
                                    anim::TextureMapping mapping) {
    EXPECT_EQ(mapping, anim::TextureMapping::Sphere);
    return std::vector<float>(2 * object.rest.size(), 0.25f);
  };
  options.textures.check_decodes = [&](const std::string& file) { checked.push_back(file); };
  render::GltfReport report;
  const std::vector<float> uv = texcoords(render::gltf_binary(scene, options, report));
  EXPECT_EQ(uv, std::vector<float>(2 * scene.objects[0].rest.size(), 0.25f));
  EXPECT_EQ(checked, std::vector<std::string>{kChecker});
}
