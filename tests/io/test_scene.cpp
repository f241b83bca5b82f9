#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/scene.hpp"
#include "test_helpers.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;
using csrbf::Vec3;
using csrbf::io::FileError;
using csrbf::test::TempDir;
using csrbf::test::write_text;
using nlohmann::json;

namespace {

const fs::path kExamples = fs::path(CSRBF_SOURCE_DIR) / "examples";

/// A small valid scene in dir: a grouped OBJ square pair, a controls file, and the scene itself.
json minimal_scene(const TempDir& dir) {
  write_text(dir / "quad.obj",
             "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
             "g left\nusemtl red\nf 1 2 3 4\ng right\nusemtl blue\nf 2 5 6 3\n");
  write_text(dir / "lift.controls", "0.5 0.5 0  0.5 0.5 0.2\n1 0 0  1 0 0\n");
  return json::parse(R"({
    "duration": 2, "fps": 10,
    "objects": [{
      "name": "quad", "mesh": "quad.obj",
      "trajectory": {"keys": [{"time": 0, "position": [0, 0, 0]}, {"time": 1, "position": [1, 0, 0]},
                              {"time": 2, "position": [1, 1, 0], "tension": 0.5}]},
      "orientation": {"keys": [{"time": 0, "quaternion": [1, 0, 0, 0]}, {"time": 2, "axis": [0, 0, 1], "angle": 90}]},
      "parts": [{"name": "l", "group": "left", "color": [1, 0, 0],
                 "deformations": [{"controls": "lift.controls", "radius": 0.8, "kernel": "c0",
                                   "phase": {"keys": [{"time": 0, "phase": 0}, {"time": 1, "phase": 1}]}}]},
                {"name": "r", "material": "blue"}]
    }]
  })");
}

std::string error_of(const TempDir& dir, const json& scene) {
  write_text(dir / "scene.json", scene.dump(1));
  try {
    csrbf::io::read_scene(dir / "scene.json");
  } catch (const FileError& e) {
    return e.what();
  }
  return "(no error)";
}

void expect_error(const TempDir& dir, const json& scene, const std::string& path, const std::string& words) {
  const std::string m = error_of(dir, scene);
  EXPECT_NE(m.find("scene.json: " + path + ":"), std::string::npos) << m;
  EXPECT_NE(m.find(words), std::string::npos) << m;
}

}  // namespace

TEST(SceneFile, ReadsAMinimalScene) {
  TempDir dir;
  write_text(dir / "scene.json", minimal_scene(dir).dump());
  const auto scene = csrbf::io::read_scene(dir / "scene.json");
  ASSERT_EQ(scene.objects.size(), 1u);
  const auto& o = scene.objects[0];
  EXPECT_EQ(o.rest.size(), 6u);
  ASSERT_EQ(o.parts.size(), 2u);
  EXPECT_EQ(o.parts[0].vertices, (std::vector<std::uint32_t>{0, 1, 2, 3}));
  EXPECT_EQ(o.parts[0].faces, (std::vector<std::uint32_t>{0}));
  EXPECT_EQ(o.parts[1].faces, (std::vector<std::uint32_t>{1}));
  EXPECT_EQ(o.parts[0].material.color, Vec3(1, 0, 0));
  ASSERT_EQ(o.parts[0].deformations.size(), 1u);
  ASSERT_TRUE(o.parts[0].deformations[0].map);
  EXPECT_EQ(o.parts[0].deformations[0].map->kernel(), csrbf::Kernel::C0);
  EXPECT_DOUBLE_EQ(o.parts[0].deformations[0].schedule.phase(0.5), 0.5);
  EXPECT_EQ(o.trajectory->keys()[2].tension, 0.5);
  EXPECT_NEAR(
      o.orientation.rotation(2.0).angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitZ()))), 0.0,
      1e-12);
  EXPECT_DOUBLE_EQ(scene.duration, 2.0);
  EXPECT_DOUBLE_EQ(scene.fps, 10.0);
  // Evaluation at a key: the centre of gravity sits at the key's position.
  csrbf::anim::Player player(scene);
  player.evaluate(1.0);
  // Vertices 4 and 5 are farther than R from the lift: they move rigidly with the object.
  for (std::uint32_t v : {4u, 5u}) {
    const Vec3 expect = o.orientation.rotation(1.0) * (o.rest[v] - o.centre) + Vec3(1, 0, 0);
    EXPECT_LT((player.positions(0)[v] - expect).norm(), 1e-12);
  }
  // Vertex 2 is in the lifted part, whose schedule reaches phase 1 at t = 1.
  const Vec3 lifted = o.parts[0].deformations[0].map->map(o.rest[2], 1.0);
  EXPECT_GT((lifted - o.rest[2]).norm(), 1e-3);
  EXPECT_LT((player.deformed(0)[2] - lifted).norm(), 1e-12);
}

TEST(SceneFile, ReadsTheBundledExamples) {
  for (const char* name : {"fish", "face", "ball"}) {
    const auto scene = csrbf::io::read_scene(kExamples / (std::string(name) + ".scene.json"));
    EXPECT_GT(scene.objects.size(), 0u) << name;
    csrbf::anim::Player player(scene);
    player.evaluate(0.3);
    for (std::size_t o = 0; o < scene.objects.size(); ++o)
      for (const auto& p : player.positions(o)) ASSERT_TRUE(p.allFinite()) << name;
  }
  // The fish's deformations share fish.controls' sources, so (the interpolant being linear in the
  // data) tail-left + mouth + fin at phase 1 is fish.controls' deformation.
  const auto fish = csrbf::io::read_scene(kExamples / "fish.scene.json");
  const auto& defs = fish.objects[0].parts[0].deformations;
  ASSERT_EQ(defs.size(), 4u);
  const auto controls = csrbf::io::read_controls(kExamples / "fish.controls");
  const auto whole = csrbf::SpaceMap::fit(controls.sources, controls.destinations, csrbf::FitOptions{0.3});
  double worst = 0;
  for (const auto& x : fish.objects[0].rest) {
    const Vec3 sum = defs[0].map->displacement(x) + defs[2].map->displacement(x) + defs[3].map->displacement(x);
    worst = std::max(worst, (sum - whole.displacement(x)).norm());
  }
  EXPECT_LT(worst, 1e-6);  // the controls files hold 6 decimals
}

TEST(SceneFile, ErrorsNameTheJsonPath) {
  TempDir dir;
  const json good = minimal_scene(dir);
  auto with = [&](auto edit) {
    json j = good;
    edit(j);
    return j;
  };
  expect_error(dir, with([](json& j) {
                 j["objects"][0]["colour"] = {1, 0, 0};
               }),
               "objects[0].colour", "unknown key 'colour'");
  expect_error(dir, with([](json& j) { j["duration"] = "long"; }), "duration", "expected a number, got \"long\"");
  expect_error(dir, with([](json& j) { j["duration"] = -1; }), "duration", "expected a number > 0");
  expect_error(dir, with([](json& j) { j.erase("duration"); }), "duration", "missing");
  expect_error(dir, with([](json& j) { j["objects"][0]["trajectory"]["keys"][2]["time"] = 0.5; }),
               "objects[0].trajectory.keys[2].time",
               "keys must be in time order: 0.5 is not after the previous key's 1");
  expect_error(dir, with([](json& j) {
                 j["objects"][0]["trajectory"]["keys"][1]["position"] = {1, 2};
               }),
               "objects[0].trajectory.keys[1].position", "expected [x, y, z]");
  expect_error(dir, with([](json& j) { j["objects"][0]["trajectory"]["keys"][1]["tension"] = 3; }),
               "objects[0].trajectory.keys[1].tension", "in [-1, 1]");
  expect_error(dir, with([](json& j) { j["objects"][0]["mesh"] = "nowhere.obj"; }), "objects[0].mesh", "nowhere.obj");
  expect_error(dir, with([](json& j) { j["objects"][0]["parts"][0]["group"] = "middle"; }), "objects[0].parts[0].group",
               "no group 'middle' (it has: left, right)");
  expect_error(dir, with([](json& j) {
                 j["objects"][0]["parts"][0]["color"] = {1, 2, 0};
               }),
               "objects[0].parts[0].color[1]", "in [0, 1]");
  expect_error(dir, with([](json& j) {
                 j["objects"][0]["parts"][1]["vertices"] = {0, 9};
                 j["objects"][0]["parts"][1].erase("material");
               }),
               "objects[0].parts[1].vertices[1]", "vertex 9 is out of range (the mesh has 6)");
  expect_error(dir, with([](json& j) { j["objects"][0]["parts"][0]["deformations"][0]["kernel"] = "c3"; }),
               "objects[0].parts[0].deformations[0].kernel", "one of \"c0\"");
  expect_error(dir, with([](json& j) { j["objects"][0]["parts"][0]["deformations"][0]["controls"] = "none.controls"; }),
               "objects[0].parts[0].deformations[0].controls", "none.controls");
  expect_error(dir, with([](json& j) { j["objects"][0]["parts"][0]["deformations"][0]["polynomial"] = "linear"; }),
               "objects[0].parts[0].deformations[0]", "cannot fit this deformation");
  expect_error(dir,
               with([](json& j) { j["objects"][0]["parts"][0]["deformations"][0]["phase"]["keys"][1]["time"] = 0; }),
               "objects[0].parts[0].deformations[0].phase.keys[1].time", "time order");
  expect_error(dir, with([](json& j) {
                 j["objects"][0]["parts"][0]["deformations"][0] =
                     json::parse(R"({"contact": {"collider": "ghost", "collider_radius": 0.2}, "radius": 0.4})");
               }),
               "objects[0].parts[0].deformations[0].contact.collider", "no object is named 'ghost'");
  expect_error(dir, with([](json& j) {
                 j["objects"][0]["orientation"]["keys"][0]["quaternion"] = {0, 0, 0, 0};
               }),
               "objects[0].orientation.keys[0].quaternion", "zero");
  expect_error(dir, with([](json& j) {
                 j["camera"] = {{"position", {0, 0, 1}}, {"focal_point", {0, 0, 0}}, {"view_up", {0, 0, 2}}};
               }),
               "camera.view_up", "parallel");
  // Not JSON at all: the line and column.
  write_text(dir / "scene.json", "{\n  \"duration\": 2,\n  oops\n}");
  try {
    csrbf::io::read_scene(dir / "scene.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
}

TEST(Scene, ADeformationsActiveAreaMovesOnlyItsVerticesInComposeAndSum) {
  TempDir dir;
  json j = minimal_scene(dir);
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 3.0;
  spec.sources = {Vec3(0.5, 0.5, 0), Vec3(1.5, 0.5, 0)};
  spec.destinations = {Vec3(0.5, 0.5, 0.3), Vec3(1.5, 0.6, 0)};
  spec.area = csrbf::io::ActiveArea{6, {1, 2, 4}, std::nullopt};
  csrbf::io::write_deformation(dir / "area.json", spec);
  const auto map = spec.fit();
  for (const char* combine : {"compose", "sum"}) {
    json scene = j;
    scene["objects"][0]["parts"] = json::array({json{
        {"combine", combine}, {"deformations", json::array({json{{"deformation", "area.json"}, {"phase", 0.5}}})}}});
    write_text(dir / "s.json", scene.dump());
    const auto sc = csrbf::io::read_scene(dir / "s.json");
    csrbf::anim::Player player(sc);
    player.evaluate(0.25);
    const auto& rest = sc.objects[0].rest;
    const auto& got = player.deformed(0);
    for (std::size_t i = 0; i < rest.size(); ++i) {
      std::vector<Vec3> one = {rest[i]};
      if (i == 1 || i == 2 || i == 4) map.apply(one, one, 0.5);
      EXPECT_LT((got[i] - one[0]).norm(), 1e-14) << combine << " vertex " << i;
    }
  }
  // An entry naming a file cannot give another area beside it (it would be ignored).
  json both = j;
  both["objects"][0]["parts"] = json::array({json{
      {"deformations",
       json::array({json{{"deformation", "area.json"}, {"active_area", {{"vertex_count", 6}, {"vertices", {0}}}}}})}}});
  write_text(dir / "s.json", both.dump());
  try {
    csrbf::io::read_scene(dir / "s.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find("deformations[0].active_area: set in the deformation file; remove it here"),
              std::string::npos)
        << e.what();
  }
  // The area must fit the object's mesh.
  spec.area = csrbf::io::ActiveArea{7, {1}, std::nullopt};
  csrbf::io::write_deformation(dir / "area.json", spec);
  json scene = j;
  scene["objects"][0]["parts"] =
      json::array({json{{"deformations", json::array({json{{"deformation", "area.json"}}})}}});
  write_text(dir / "s.json", scene.dump());
  try {
    csrbf::io::read_scene(dir / "s.json");
    FAIL();
  } catch (const FileError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "objects[0].parts[0].deformations[0].deformation: this deformation: active_area: the "
                  "deformation was picked on a mesh of 7 vertices, this object's mesh has 6"),
              std::string::npos)
        << e.what();
  }
}
