// Which files a command reads (csrbf/io/inputs.hpp): a document and what it names, three levels deep,
// a .gltf's side files, and whether an output is one of them through links.
#include "csrbf/io/inputs.hpp"
#include "csrbf/io/memory.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

using namespace csrbf;
namespace fs = std::filesystem;

namespace {

std::set<fs::path> as_set(const std::vector<fs::path>& files) { return {files.begin(), files.end()}; }

}  // namespace

TEST(Inputs, ADocumentAndEveryFileItNames) {
  test::TempDir dir;
  test::write_text(dir / "ball.scene.json",
                   R"({"objects":[{"mesh":"ball.gltf","texture":"skin.png","parts":[{"deformation":"squash.json"}]}],)"
                   R"("title":"mesh.obj","empty":{"mesh":""}})");
  test::write_text(dir / "squash.json", R"({"controls":"squash.controls","displacements":"sub/d.txt"})");
  test::write_text(dir / "ball.gltf",
                   R"({"buffers":[{"uri":"ball.bin"},{"uri":"data:application/octet-stream;base64,AAAA"}],)"
                   R"("images":[{"uri":"/abs/wood.png"}]})");
  const auto files = io::referenced_files(dir / "ball.scene.json");
  ASSERT_FALSE(files.empty());
  EXPECT_EQ(files.front(), dir / "ball.scene.json");
  // Values of other keys ("title") and empty names are no files; a data: URI is no file.
  EXPECT_EQ(as_set(files),
            (std::set<fs::path>{dir / "ball.scene.json", dir / "ball.gltf", dir / "skin.png", dir / "squash.json",
                                dir / "squash.controls", dir / "sub/d.txt", dir / "ball.bin", "/abs/wood.png"}));
  EXPECT_EQ(files.size(), 8u);
}

TEST(Inputs, DocumentsAreFollowedThreeLevelsDeep) {
  test::TempDir dir;
  test::write_text(dir / "1.json", R"({"file":"2.json"})");
  test::write_text(dir / "2.json", R"({"file":"3.json"})");
  test::write_text(dir / "3.json", R"({"file":"4.json"})");
  test::write_text(dir / "4.json", R"({"mesh":"deep.obj"})");
  EXPECT_EQ(io::referenced_files(dir / "1.json"),
            (std::vector<fs::path>{dir / "1.json", dir / "2.json", dir / "3.json", dir / "4.json"}));
}

TEST(Inputs, ADocumentNotReadContributesNothingMore) {
  test::TempDir dir;
  EXPECT_EQ(io::referenced_files(dir / "missing.json"), std::vector<fs::path>{dir / "missing.json"});
  test::write_text(dir / "broken.json", R"({"mesh":"a.obj")");
  EXPECT_EQ(io::referenced_files(dir / "broken.json"), std::vector<fs::path>{dir / "broken.json"});
  // Under a limit that leaves nothing to parse it, a document is left to its reader.
  test::write_text(dir / "scene.json", R"({"mesh":"a.obj"})");
  EXPECT_EQ(io::referenced_files(dir / "scene.json", 0.0), std::vector<fs::path>{dir / "scene.json"});
  EXPECT_EQ(io::referenced_files(dir / "scene.json").size(), 2u);
}

TEST(Inputs, JsonTakesAnEighthOfWhatTheLimitLeaves) {
  EXPECT_EQ(io::json_bytes_within(0.0), 0.0);
  EXPECT_EQ(io::json_bytes_within(-1.0), 0.0);
  const double limit = io::resident_bytes() + 8.0 * (1 << 30);
  EXPECT_NEAR(io::json_bytes_within(limit), double(1 << 30), 1 << 20);
}

TEST(Inputs, MeshSideFilesAreAGltfsBuffersAndImages) {
  test::TempDir dir;
  const std::string gltf = R"({"buffers":[{"uri":"m.bin"},{"byteLength":4}],"images":[{"uri":"tex/a.png"},)"
                           R"({"uri":"data:image/png;base64,iVBO"},{"uri":7}]})";
  test::write_text(dir / "m.gltf", gltf);
  test::write_text(dir / "M.GLTF", gltf);
  test::write_text(dir / "m.obj", R"({"buffers":[{"uri":"m.bin"}]})");
  const std::vector<fs::path> want{dir / "m.bin", dir / "tex/a.png"};
  EXPECT_EQ(io::mesh_side_files(dir / "m.gltf"), want);
  EXPECT_EQ(io::mesh_side_files(dir / "M.GLTF"), want);
  EXPECT_TRUE(io::mesh_side_files(dir / "m.obj").empty());
  EXPECT_TRUE(io::mesh_side_files(dir / "missing.gltf").empty());
}

TEST(Inputs, AnOutputIsAnInputThroughAnyLink) {
  test::TempDir dir;
  test::write_text(dir / "in.obj", "v 0 0 0\n");
  test::write_text(dir / "other.obj", "v 0 0 0\n");
  fs::create_hard_link(dir / "in.obj", dir / "hard.obj");
  fs::create_symlink(dir / "in.obj", dir / "soft.obj");
  const std::vector<fs::path> inputs{dir / "other.obj", dir / "in.obj"};
  EXPECT_EQ(io::same_file_as(dir / "in.obj", inputs), dir / "in.obj");
  EXPECT_EQ(io::same_file_as(dir / "hard.obj", inputs), dir / "in.obj");
  EXPECT_EQ(io::same_file_as(dir / "soft.obj", inputs), dir / "in.obj");
  EXPECT_EQ(io::same_file_as(dir / "." / "in.obj", inputs), dir / "in.obj");
  // The same text in another file, a file not there yet, and no output are no input.
  EXPECT_EQ(io::same_file_as(dir / "copy.obj", inputs), fs::path());
  test::write_text(dir / "copy.obj", "v 0 0 0\n");
  EXPECT_EQ(io::same_file_as(dir / "copy.obj", inputs), fs::path());
  EXPECT_EQ(io::same_file_as(fs::path(), inputs), fs::path());
}
