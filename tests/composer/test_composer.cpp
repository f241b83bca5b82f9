// The Animation Composer's real window, driven with QTest (run on a private Xvfb: tests/with-xvfb.sh).
#include "composer_window.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/scene.hpp"
#include "gui_common.hpp"
#include "gui_test_helpers.hpp"
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <QAction>
#include <QApplication>
#include <QDoubleSpinBox>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMessageBox>
#include <QTimer>
#include <QScrollArea>
#include <QScrollBar>
#include <QTabBar>
#include <QTabWidget>
#include <QPushButton>
#include <QStatusBar>
#include <QSurfaceFormat>
#include <QTest>
#include <QVTKOpenGLNativeWidget.h>

#include <nlohmann/json.hpp>
#include <vtkActor.h>
#include <vtkActorCollection.h>
#include <vtkCamera.h>
#include <vtkCameraActor.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkRendererCollection.h>

#include <fstream>
#include <unistd.h>

namespace fs = std::filesystem;
using csrbf::Vec3;
using csrbf::composer::ComposerWindow;
using Track = csrbf::composer::Document::Track;

namespace {

const std::string kExamples = std::string(CSRBF_SOURCE_DIR) + "/examples/";
const fs::path kShots = CSRBF_SCREENSHOT_DIR;

struct Fixture : ::testing::Test {
  ComposerWindow w;
  void SetUp() override { ASSERT_TRUE(csrbf::test::show_for_test(w, 1280, 820)); }
  /// Clicks the timeline's ruler (above the key rows) at time t: scrubbing.
  void scrub_to(double t) {
    QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier, QPoint(int(std::lround(w.timeline()->x_of(t))), 8));
  }
};

}  // namespace

TEST_F(Fixture, BuildsASceneThroughTheUiSavesAndReloadsIt) {
  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.new_scene());
  ASSERT_TRUE(w.add_object(QString::fromStdString(kExamples + "fish.obj")));
  ASSERT_EQ(w.document().object_count(), 1u);
  EXPECT_EQ(w.selected_object(), 0);

  // Three trajectory keys: scrub to 0, 1 and 2 s on the timeline and press "Add key" each time.
  auto* add_key = w.findChild<QPushButton*>("addKey");
  for (double t : {0.0, 1.0, 2.0}) {
    scrub_to(t);
    EXPECT_NEAR(w.time(), t, 0.02);
    QTest::mouseClick(add_key, Qt::LeftButton);
  }
  auto times = w.document().key_times(0, Track::Position);
  ASSERT_EQ(times.size(), 3u) << w.error_text().toStdString();
  EXPECT_NEAR(times[1], 1.0, 0.02);
  // Keys 1 and 2 start where the object is; drag them apart in the 3D view.
  for (int k : {1, 2}) {
    w.select_key(k);
    const QPoint from = csrbf::test::widget_point(w, w.key_position(k));
    csrbf::test::drag(w.view(), from, from + QPoint(90 * k, -40 * k));
  }
  const Vec3 k0 = w.key_position(0), k1 = w.key_position(1), k2 = w.key_position(2);
  EXPECT_GT((k1 - k0).norm(), 0.05);
  EXPECT_GT((k2 - k1).norm(), 0.05);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-keys.png").string())));

  // A timing mark: drag the last key's diamond on the timeline from 2 s to 3 s.
  const int y = w.timeline()->y_of(0);
  csrbf::test::drag(w.timeline(), QPoint(int(std::lround(w.timeline()->x_of(times[2]))), y),
                    QPoint(int(std::lround(w.timeline()->x_of(3.0))), y));
  times = w.document().key_times(0, Track::Position);
  ASSERT_EQ(times.size(), 3u);
  EXPECT_NEAR(times[2], 3.0, 0.02);

  // Tension of key 1 through its spin box; an orientation key of 30 degrees yaw at t = 1.
  w.select_key(1);
  w.findChild<QDoubleSpinBox*>("tension")->setValue(0.5);
  scrub_to(1.0);
  w.findChild<QDoubleSpinBox*>("yaw")->setValue(30);
  QTest::mouseClick(w.findChild<QPushButton*>("setOrientation"), Qt::LeftButton);
  ASSERT_EQ(w.document().key_times(0, Track::Orientation).size(), 1u) << w.error_text().toStdString();

  // Attach a deformation made in the Picker (a deformation file).
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 0.3;
  spec.sources = {Vec3(0.95, 0.5, 0.5), Vec3(0.5, 0.5, 0.5)};
  spec.destinations = {Vec3(0.95, 0.5, 0.6), Vec3(0.5, 0.5, 0.5)};
  csrbf::io::write_deformation(dir / "tail.json", spec);
  ASSERT_TRUE(w.attach_deformation(QString::fromStdString((dir / "tail.json").string())));
  EXPECT_EQ(w.document().deformation_count(0), 1u);

  // Save; the file is a scene the CLI reads, with the keys and times set above.
  const fs::path file = dir / "built.scene.json";
  ASSERT_TRUE(w.save_scene(QString::fromStdString(file.string())));
  EXPECT_TRUE(w.undo_stack().isClean());
  const auto j = nlohmann::json::parse(csrbf::test::read_text(file));
  const auto& o = j["objects"][0];
  EXPECT_EQ(fs::weakly_canonical(dir.path / o["mesh"].get<std::string>()),
            fs::weakly_canonical(kExamples + "fish.obj"));
  ASSERT_EQ(o["trajectory"]["keys"].size(), 3u);
  EXPECT_NEAR(o["trajectory"]["keys"][2]["time"].get<double>(), 3.0, 0.02);
  EXPECT_EQ(o["trajectory"]["keys"][1]["tension"].get<double>(), 0.5);
  EXPECT_EQ(o["orientation"]["keys"].size(), 1u);
  EXPECT_EQ(o["parts"][0]["deformations"][0]["deformation"].get<std::string>(), "tail.json");
  const auto scene = csrbf::io::read_scene(file);
  ASSERT_EQ(scene.objects.size(), 1u);
  EXPECT_LT((scene.objects[0].trajectory->position(3.0) - k2).norm(), 1e-9);

  // Reload: the same scene.
  ASSERT_TRUE(w.new_scene());
  EXPECT_EQ(w.document().object_count(), 0u);
  ASSERT_TRUE(w.open_scene(QString::fromStdString(file.string())));
  EXPECT_EQ(w.document().json(), j);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-reloaded.png").string())));

  // Undo and redo.
  w.select_object(0);
  QTest::mouseClick(w.findChild<QPushButton*>("setOrientation"), Qt::LeftButton);  // at t = 0 now
  EXPECT_EQ(w.document().key_times(0, Track::Orientation).size(), 2u);
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);
  EXPECT_EQ(w.document().key_times(0, Track::Orientation).size(), 1u);
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  EXPECT_EQ(w.document().key_times(0, Track::Orientation).size(), 2u);
}

TEST_F(Fixture, RefusesBadEditsAndKeepsTheScene) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  const auto before = w.document().json();
  // A second key at a time that has one.
  w.set_time(2.0);
  QTest::mouseClick(w.findChild<QPushButton*>("addKey"), Qt::LeftButton);
  EXPECT_NE(w.error_text().toStdString().find("a key is already at t = 2 s"), std::string::npos)
      << w.error_text().toStdString();
  // A key time typed past its neighbour is refused.
  w.select_key(1);
  w.findChild<QDoubleSpinBox*>("keyTime")->setValue(5.0);
  EXPECT_NE(w.error_text().toStdString().find("would pass a neighbouring key"), std::string::npos)
      << w.error_text().toStdString();
  EXPECT_EQ(w.document().json(), before);
  EXPECT_FALSE(w.attach_deformation("/nonexistent/d.json"));
  EXPECT_NE(w.error_text().toStdString().find("/nonexistent/d.json"), std::string::npos);
  EXPECT_FALSE(w.open_scene("/nonexistent/scene.json"));
  EXPECT_EQ(w.document().json(), before);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-error.png").string())));
}

TEST_F(Fixture, PlaysAndExportsTheSameMovieAsTheCommandLine) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "ball.scene.json")));
  const std::size_t shown = w.frames_shown();
  QTest::mouseClick(w.findChild<QPushButton*>("play"), Qt::LeftButton);
  EXPECT_TRUE(w.playing());
  QTest::qWait(1000);
  // Real time, drawn by software OpenGL: on a loaded machine (the suite runs 2 tests on 2 cores)
  // 4 frames came in the first second; the frames are what is checked, not the rate.
  EXPECT_GT(w.time(), 0.4);  // the clock is the wall's, whatever was drawn
  for (int i = 0; i < 100 && w.frames_shown() - shown <= 5; ++i) QTest::qWait(100);
  EXPECT_GT(w.frames_shown() - shown, 5u);
  const std::string rates = w.findChild<QLabel*>("rates")->text().toStdString();
  EXPECT_NE(rates.find("computed"), std::string::npos) << rates;
  EXPECT_NE(rates.find("rendered"), std::string::npos) << rates;
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-playing.png").string())));
  QTest::keyClick(&w, Qt::Key_Space);  // pause
  EXPECT_FALSE(w.playing());

  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.export_movie(QString::fromStdString((dir / "gui.mp4").string()), 160, 120))
      << w.error_text().toStdString();
  const auto probe = csrbf::test::run_shell(
      "ffprobe -v error -count_frames -show_entries stream=nb_read_frames,width,height "
      "-of csv=p=0 " +
      (dir / "gui.mp4").string());
  EXPECT_EQ(probe.out, "160,120,101\n");
  EXPECT_NE(w.info_text().toStdString().find("Wrote"), std::string::npos) << "an export says when it is done";
  // The command line makes the same movie: the same frames, decoded.
  const auto cli = csrbf::test::run_shell(std::string(CSRBF_CLI) + " animate " + kExamples + "ball.scene.json -o " +
                                          (dir / "cli.mp4").string() + " --size 160x120");
  ASSERT_EQ(cli.code, 0) << cli.out;
  const auto a =
      csrbf::test::run_shell("ffmpeg -v error -i " + (dir / "gui.mp4").string() + " -f rawvideo -pix_fmt rgb24 -");
  const auto b =
      csrbf::test::run_shell("ffmpeg -v error -i " + (dir / "cli.mp4").string() + " -f rawvideo -pix_fmt rgb24 -");
  ASSERT_EQ(a.out.size(), b.out.size());
  ASSERT_EQ(a.out.size(), 101u * 160 * 120 * 3);
  double diff = 0;
  for (std::size_t i = 0; i < a.out.size(); ++i)
    diff += std::abs(int((unsigned char)a.out[i]) - int((unsigned char)b.out[i]));
  EXPECT_LT(diff / double(a.out.size()), 0.5);
}

namespace {

/// A deformation file of the fish's mouth controls (R = 0.3) in `dir`.
QString mouth_deformation(const fs::path& dir) {
  const auto c = csrbf::io::read_controls(kExamples + "fish-mouth.controls");
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 0.3;
  spec.sources = c.sources;
  spec.destinations = c.destinations;
  csrbf::io::write_deformation(dir / "fish-mouth.json", spec);
  return QString::fromStdString((dir / "fish-mouth.json").string());
}

/// The first renderer of the view (the scene's, with the overlays).
vtkRenderer* view_renderer(ComposerWindow& w) { return w.view()->renderWindow()->GetRenderers()->GetFirstRenderer(); }

}  // namespace

TEST_F(Fixture, UndoAfterSaveAsIntoAnotherFolderKeepsTheFilesAndNeverCrashes) {
  // The reported sequence: open the fish, drag a trajectory key, Save As into another folder, Ctrl+Z,
  // click in the view, save again.
  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  const auto opened = w.document().json();
  w.select_key(1);
  const QPoint key = csrbf::test::widget_point(w, w.key_position(1));
  csrbf::test::drag(w.view(), key, key + QPoint(40, -30));
  ASSERT_NE(w.document().json(), opened) << "the drag moved the key";
  ASSERT_TRUE(w.attach_deformation(mouth_deformation(dir.path))) << w.error_text().toStdString();
  fs::create_directories(dir / "elsewhere");
  ASSERT_TRUE(w.save_scene(QString::fromStdString((dir / "elsewhere" / "fish.scene.json").string())));
  EXPECT_FALSE(w.isWindowModified());
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);  // the attachment
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);  // the drag
  EXPECT_TRUE(w.error_text().isEmpty()) << w.error_text().toStdString();
  EXPECT_TRUE(w.isWindowModified());
  ASSERT_EQ(w.selected_object(), 0);
  // The view still shows the fish, and clicks in it (on a key, then elsewhere) are safe.
  const QPoint k1 = csrbf::test::widget_point(w, w.key_position(1));
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::NoModifier, k1);
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::NoModifier, QPoint(20, 20));
  EXPECT_EQ(w.selected_key(), 1);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-undo-after-save-as.png").string())));
  // The state undone to names the same files from the new folder: it saves and reads back whole.
  ASSERT_TRUE(w.save_scene(QString::fromStdString((dir / "elsewhere" / "fish.scene.json").string())));
  const auto scene = csrbf::io::read_scene(dir / "elsewhere" / "fish.scene.json");
  ASSERT_EQ(scene.objects.size(), 1u);
  EXPECT_EQ(scene.objects[0].rest.size(), 977u);
  std::ifstream in(dir / "elsewhere" / "fish.scene.json");
  const auto saved = nlohmann::json::parse(in);
  const fs::path mesh = saved["objects"][0]["mesh"].get<std::string>();
  EXPECT_TRUE(fs::exists(dir / "elsewhere" / mesh)) << mesh;
  EXPECT_EQ(saved["objects"][0]["trajectory"], opened["objects"][0]["trajectory"]) << "the drag is undone";
  // Redo brings both edits back, with the files still found.
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  EXPECT_TRUE(w.error_text().isEmpty()) << w.error_text().toStdString();
  EXPECT_EQ(w.document().deformation_count(0), 5u);
}

TEST_F(Fixture, KeysSitOnFramesStopAtNeighboursAndPhaseMarksAreEditable) {
  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  // Scrubbing stops on frames, so a key added there is on one (25 fps: multiples of 0.04 s).
  w.set_time(0.5056);
  EXPECT_DOUBLE_EQ(w.time(), 0.52);
  // Dragging the key at 2 s towards 5 s stops one frame short of the key at 4 s.
  const int y = w.timeline()->y_of(0);
  csrbf::test::drag(w.timeline(), QPoint(int(std::lround(w.timeline()->x_of(2.0))), y),
                    QPoint(int(std::lround(w.timeline()->x_of(5.0))), y));
  EXPECT_TRUE(w.error_text().isEmpty()) << w.error_text().toStdString();
  auto times = w.document().key_times(0, Track::Position);
  EXPECT_DOUBLE_EQ(times[1], 3.96);
  // A drag to an odd place lands on a frame.
  csrbf::test::drag(w.timeline(), QPoint(int(std::lround(w.timeline()->x_of(3.96))), y),
                    QPoint(int(std::lround(w.timeline()->x_of(3.0))) + 1, y));
  times = w.document().key_times(0, Track::Position);
  EXPECT_NEAR(times[1] * 25, std::round(times[1] * 25), 1e-9) << times[1];

  // Rows are named after the deformations; clicking a phase mark selects it for the panel.
  EXPECT_EQ(w.document().deformation_name(0, 3), "fin");
  const auto fin = w.document().key_times(0, Track::Phase, 3);
  QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier,
                    QPoint(int(std::lround(w.timeline()->x_of(fin[2]))), w.timeline()->y_of(2 + 3)));
  EXPECT_EQ(w.selected_deformation(), 3);
  EXPECT_EQ(w.selected_phase_key(), 2);
  EXPECT_EQ(w.findChild<QLineEdit*>("deformationName")->text(), "fin");
  EXPECT_DOUBLE_EQ(w.findChild<QDoubleSpinBox*>("phaseTime")->value(), fin[2]);
  // The panel edits it: value, name, easing; Delete removes the selected phase key.
  w.findChild<QDoubleSpinBox*>("phaseValue")->setValue(0.5);
  EXPECT_DOUBLE_EQ(w.document().phase_value(0, 3, 2), 0.5);
  auto* name = w.findChild<QLineEdit*>("deformationName");
  name->setText("dorsal fin");
  emit name->editingFinished();
  EXPECT_EQ(w.document().deformation_name(0, 3), "dorsal fin");
  const std::size_t before = w.document().key_times(0, Track::Phase, 3).size();
  QTest::keyClick(&w, Qt::Key_Delete);
  EXPECT_EQ(w.document().key_times(0, Track::Phase, 3).size(), before - 1);
  EXPECT_EQ(w.document().key_times(0, Track::Position).size(), 5u) << "the trajectory key stays";
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-timeline.png").string())));

  // During playback the orientation boxes follow the animation.
  w.set_time(0);
  const double yaw0 = w.findChild<QDoubleSpinBox*>("yaw")->value();
  w.play(true);
  QTest::qWait(700);
  w.play(false);
  EXPECT_GT(w.time(), 0.3);
  EXPECT_GT(std::abs(w.findChild<QDoubleSpinBox*>("yaw")->value() - yaw0), 1.0);
  // Remove the deformation: the row goes, and the view keeps its size (the timeline scrolls).
  const QSize view = w.view()->size();
  w.select_phase_key(0, -1);
  QTest::mouseClick(w.findChild<QPushButton*>("removeDeformation"), Qt::LeftButton);
  EXPECT_EQ(w.document().deformation_count(0), 3u);
  ASSERT_TRUE(w.attach_deformation(mouth_deformation(dir.path)));
  ASSERT_TRUE(w.attach_deformation(mouth_deformation(dir.path)));
  QApplication::processEvents();
  EXPECT_EQ(w.view()->size(), view);
  EXPECT_FALSE(w.attach_deformation("/nonexistent/d.json"));
  QApplication::processEvents();
  EXPECT_EQ(w.view()->size(), view) << "an error box does not move the view";
}

TEST_F(Fixture, SceneCameraLightsColoursAndViewsAreEditedInTheComposer) {
  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  // The scene's renderer is rebuilt with every edit: look it up each time.
  const auto r = [&] { return view_renderer(w); };
  // VTK's own keys are off: 3 (stereo), e and q (quit) do nothing; W is the documented wireframe toggle.
  QTest::keyClick(w.view(), Qt::Key_3);
  EXPECT_FALSE(w.view()->renderWindow()->GetStereoRender());
  QTest::keyClick(w.view(), Qt::Key_E);
  QTest::keyClick(w.view(), Qt::Key_Q);
  EXPECT_TRUE(w.isVisible());
  const auto representation = [&] {
    vtkActorCollection* actors = r()->GetActors();
    actors->InitTraversal();
    return actors->GetNextActor()->GetProperty()->GetRepresentation();
  };
  QTest::keyClick(&w, Qt::Key_W);
  EXPECT_EQ(representation(), VTK_WIREFRAME);
  QTest::keyClick(&w, Qt::Key_W);
  EXPECT_EQ(representation(), VTK_SURFACE);

  // R: the front view; 7: from the top.
  QTest::keyClick(&w, Qt::Key_7);
  double dir_top[3];
  r()->GetActiveCamera()->GetDirectionOfProjection(dir_top);
  EXPECT_NEAR(dir_top[1], -1.0, 1e-9);
  QTest::keyClick(&w, Qt::Key_R);
  double dir_front[3];
  r()->GetActiveCamera()->GetDirectionOfProjection(dir_front);
  EXPECT_NEAR(dir_front[2], -1.0, 1e-9);
  // The scene camera's frame is drawn; "Set scene camera from view" makes the view the movie's.
  EXPECT_TRUE(w.scene_camera_actor()->GetVisibility());
  QTest::keyClick(&w, Qt::Key_3);  // from the side, zoomed out: the frame reaches from the camera to the fish
  r()->GetActiveCamera()->Dolly(0.35);
  r()->ResetCameraClippingRange();
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-camera-frame.png").string())));
  QTest::keyClick(&w, Qt::Key_R);
  double pos[3];
  r()->GetActiveCamera()->GetPosition(pos);
  ASSERT_TRUE(w.set_scene_camera_from_view());
  const auto& cam = w.document().json()["camera"];
  for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(cam["position"][k].get<double>(), pos[k]);
  EXPECT_TRUE(w.isWindowModified());
  EXPECT_NE(w.windowTitle().indexOf("[*]"), -1);
  // Background, object colour and a light, through the document's edits the panel's buttons make.
  ASSERT_TRUE(w.edit("Background", [](csrbf::composer::Document& d) { d.set_background(Vec3(0.2, 0.3, 0.4)); }));
  ASSERT_TRUE(w.edit("Colour", [](csrbf::composer::Document& d) { d.set_object_color(0, Vec3(0.1, 0.8, 0.2)); }));
  auto* tabs = w.findChild<QTabWidget*>("panelTabs");
  QTest::mouseClick(tabs->tabBar(), Qt::LeftButton, Qt::NoModifier, tabs->tabBar()->tabRect(2).center());
  ASSERT_EQ(tabs->currentIndex(), 2) << "the Scene tab holds the look";
  QTest::mouseClick(w.findChild<QPushButton*>("addLight"), Qt::LeftButton);
  EXPECT_EQ(w.document().light_count(), 3u);
  w.findChild<QListWidget*>("lights")->setCurrentRow(2);
  w.findChild<QDoubleSpinBox*>("lightIntensity")->setValue(0.3);
  EXPECT_DOUBLE_EQ(w.document().json()["lights"][2]["intensity"].get<double>(), 0.3);
  EXPECT_EQ(w.findChild<QListWidget*>("lights")->currentRow(), 2) << "the edited light stays selected";
  ASSERT_TRUE(w.save_scene(QString::fromStdString((dir / "look.scene.json").string())));
  const auto scene = csrbf::io::read_scene(dir / "look.scene.json");
  EXPECT_NEAR((scene.camera.position - Vec3(pos[0], pos[1], pos[2])).norm(), 0, 1e-12);
  EXPECT_EQ(scene.background, Vec3(0.2, 0.3, 0.4));
  EXPECT_EQ(scene.lights.size(), 3u);
  EXPECT_EQ(scene.objects[0].material.color, Vec3(0.1, 0.8, 0.2));
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-look.png").string())));

  // A deformation file opened as a scene is named as one; File > New clears the title and fields.
  EXPECT_FALSE(w.open_scene(mouth_deformation(dir.path)));
  EXPECT_NE(w.error_text().toStdString().find("this is a deformation file, not a scene"), std::string::npos)
      << w.error_text().toStdString();
  w.select_key(1);
  ASSERT_TRUE(w.new_scene());
  EXPECT_TRUE(w.error_text().isEmpty());
  EXPECT_TRUE(w.windowTitle().startsWith("untitled")) << w.windowTitle().toStdString();
  EXPECT_EQ(w.findChild<QDoubleSpinBox*>("keyTime")->value(), 0.0);
  EXPECT_FALSE(w.findChild<QDoubleSpinBox*>("keyTime")->isEnabled());
}

// Issue 30: no edit ends the program, a bare file name saves, and unsaved work survives a crash.
TEST_F(Fixture, DeletingPhaseKeysDownToTheLastNeverEndsTheProgram) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  const std::size_t d = 3;
  auto keys = [&] { return w.document().key_times(0, Track::Phase, d).size(); };
  ASSERT_GE(keys(), 2u);
  // Deleting the last key of the row (the highest index) left the panel asking for it: EditError
  // "no phase key N" escaped the refresh and Qt ended the program.
  while (keys() > 1) {
    const std::size_t n = keys();
    w.select_phase_key(int(d), int(n - 1));
    QTest::mouseClick(w.findChild<QPushButton*>("deletePhaseKey"), Qt::LeftButton);
    QApplication::processEvents();
    EXPECT_EQ(keys(), n - 1);
    EXPECT_EQ(w.selected_phase_key(), -1);
    EXPECT_TRUE(w.error_text().isEmpty()) << w.error_text().toStdString();
  }
  // The very last one stays, with a message; the scene is unchanged.
  const auto before = w.document().json();
  w.select_phase_key(int(d), 0);
  QTest::mouseClick(w.findChild<QPushButton*>("deletePhaseKey"), Qt::LeftButton);
  QApplication::processEvents();
  EXPECT_EQ(keys(), 1u);
  EXPECT_EQ(w.document().json(), before);
  EXPECT_NE(w.error_text().indexOf("keeps at least one key"), -1) << w.error_text().toStdString();
  // Undo brings every deleted key back.
  while (w.undo_stack().canUndo()) w.undo_stack().undo();
  QApplication::processEvents();
  EXPECT_GE(w.document().key_times(0, Track::Phase, d).size(), 2u);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-last-phase-key.png").string())));
}

TEST_F(Fixture, AnExceptionInAnyHandlerIsShownAndTheProgramGoesOn) {
  QTimer::singleShot(0, [] { throw std::runtime_error("a handler that throws"); });
  QApplication::processEvents();
  QApplication::processEvents();
  EXPECT_NE(csrbf::gui::last_caught_error().indexOf("a handler that throws"), -1);
  auto* box = w.findChild<QMessageBox*>("caughtError");
  QMessageBox* shown = box;
  for (QWidget* top : QApplication::topLevelWidgets())
    if (top->objectName() == "caughtError") shown = qobject_cast<QMessageBox*>(top);
  ASSERT_NE(shown, nullptr);
  EXPECT_TRUE(shown->isVisible());
  EXPECT_NE(shown->text().indexOf("a handler that throws"), -1);
  shown->close();
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));  // still working
}

TEST_F(Fixture, ASceneOpenedByABareFileNameSaves) {
  csrbf::test::TempDir dir;
  for (const auto& e : fs::directory_iterator(kExamples))
    if (e.path().filename().string().starts_with("fish")) fs::copy_file(e.path(), dir / e.path().filename().string());
  const fs::path was = fs::current_path();
  fs::current_path(dir.path);
  const bool opened = w.open_scene("fish.scene.json");
  bool edited = false, saved = false, again = false;
  if (opened) {
    edited = w.edit("Rename", [](csrbf::composer::Document& d) { d.set_deformation_name(0, 0, "jaw"); });
    saved = w.save_scene("fish.scene.json");
    again = w.open_scene("fish.scene.json");
  }
  fs::current_path(was);
  ASSERT_TRUE(opened) << w.error_text().toStdString();
  EXPECT_TRUE(edited) << w.error_text().toStdString();
  EXPECT_TRUE(saved) << w.error_text().toStdString();
  EXPECT_TRUE(again) << w.error_text().toStdString();
  EXPECT_EQ(w.document().deformation_name(0, 0), "jaw");
  EXPECT_NO_THROW(csrbf::io::read_scene(dir / "fish.scene.json"));
}

TEST_F(Fixture, UnsavedWorkIsKeptAsideAndOfferedAgain) {
  csrbf::test::TempDir dir;
  fs::copy_file(kExamples + "fish.scene.json", dir / "fish.scene.json");
  for (const auto& e : fs::directory_iterator(kExamples))
    if (e.path().filename().string().starts_with("fish-") || e.path().filename() == "fish.obj")
      fs::copy_file(e.path(), dir / e.path().filename().string());
  ASSERT_TRUE(w.open_scene(QString::fromStdString((dir / "fish.scene.json").string())));
  w.recovery().remove();
  EXPECT_FALSE(w.write_recovery()) << "nothing unsaved, nothing written";
  ASSERT_TRUE(w.edit("Rename", [](csrbf::composer::Document& d) { d.set_deformation_name(0, 1, "unsaved work"); }));
  ASSERT_TRUE(w.write_recovery());
  ASSERT_TRUE(w.recovery().exists());
  // The next start (after a crash) offers it: recovered, unsaved, the scene file untouched.
  {
    ComposerWindow next;
    ASSERT_TRUE(csrbf::test::show_for_test(next, 1280, 820));
    ASSERT_TRUE(next.recovery().exists());
    ASSERT_TRUE(next.recover()) << next.error_text().toStdString();
    EXPECT_EQ(next.document().deformation_name(0, 1), "unsaved work");
    EXPECT_EQ(next.document().json(), w.document().json());
    EXPECT_EQ(next.document().path(), fs::absolute(dir / "fish.scene.json").lexically_normal());
    EXPECT_TRUE(next.isWindowModified());
    EXPECT_FALSE(next.undo_stack().isClean());
    ASSERT_TRUE(next.save_screenshot(QString::fromStdString((kShots / "composer-recovered.png").string())));
    next.setProperty("noPrompt", true);
  }
  {
    // The offer at start names the scene the work belongs to; No discards it.
    ComposerWindow next;
    ASSERT_TRUE(csrbf::test::show_for_test(next, 1280, 820));
    QString asked;
    QTimer::singleShot(200, [&] {
      if (auto* box = qobject_cast<QMessageBox*>(QApplication::activeModalWidget())) {
        asked = box->text();
        box->button(QMessageBox::No)->click();
      }
    });
    next.offer_recovery();
    EXPECT_NE(asked.indexOf(QString::fromStdString(fs::absolute(dir / "fish.scene.json").lexically_normal().string())),
              -1)
        << asked.toStdString();
    EXPECT_NE(asked.indexOf("No discards it for good"), -1) << asked.toStdString();
    EXPECT_FALSE(next.recovery().exists());
    ASSERT_TRUE(w.write_recovery());  // still unsaved in w
  }
  EXPECT_EQ(csrbf::io::read_scene(dir / "fish.scene.json").objects[0].parts.size(),
            csrbf::io::read_scene(kExamples + "fish.scene.json").objects[0].parts.size());
  // Saved: nothing left to recover.
  ASSERT_TRUE(w.save_scene(QString::fromStdString((dir / "fish.scene.json").string())));
  EXPECT_FALSE(w.recovery().exists());
}

TEST_F(Fixture, EditingOneCoordinateKeepsTheOthersFullPrecision) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  const Vec3 exact(0.123456789012, -1.987654321098, 0.333333333333);
  ASSERT_TRUE(w.edit("Place", [&](csrbf::composer::Document& d) { d.set_position(0, 1, exact); }));
  w.select_key(1);
  QApplication::processEvents();
  auto* y = w.findChild<QDoubleSpinBox*>("keyY");
  ASSERT_NE(y, nullptr);
  y->setValue(0.5);  // the box shows 3 decimals; x and z were written back rounded to them
  QApplication::processEvents();
  const auto j = w.document().json()["objects"][0]["trajectory"]["keys"][1]["position"];
  EXPECT_EQ(j[0].get<double>(), exact.x());
  EXPECT_EQ(j[1].get<double>(), 0.5);
  EXPECT_EQ(j[2].get<double>(), exact.z());
}

TEST_F(Fixture, HomeFramesTheWholeScene) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  vtkCamera* cam = view_renderer(w)->GetActiveCamera();
  cam->Dolly(20);  // far too close
  const double before = cam->GetDistance();
  double dir0[3];
  cam->GetDirectionOfProjection(dir0);
  w.setFocus();
  QTest::keyClick(&w, Qt::Key_Home);
  QApplication::processEvents();
  EXPECT_GT(cam->GetDistance(), 5 * before) << "Home frames the whole scene";
  double dir1[3];
  cam->GetDirectionOfProjection(dir1);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(dir1[k], dir0[k], 1e-9) << "from where the camera looked";
  w.set_time(2.0);
  QTest::keyClick(&w, Qt::Key_Left, Qt::ShiftModifier);
  EXPECT_EQ(w.time(), 0.0) << "Shift+Left goes to the start";
}

// Issue 30, point 17, as a new user met them: a pause left the time between frames; the Composer's
// W did nothing while a number box had focus; "Opened ...: 1 objects" stayed in the status bar
// after the scene changed; attaching a scene as a deformation gave a message about a key.
TEST_F(Fixture, PausesOnAFrameKeysReachTheViewAndMessagesStayTrue) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "ball.scene.json")));
  EXPECT_FALSE(w.statusBar()->currentMessage().isEmpty());
  QTest::mouseClick(w.findChild<QPushButton*>("play"), Qt::LeftButton);
  QTest::qWait(530);  // not a multiple of 1 / fps
  QTest::mouseClick(w.findChild<QPushButton*>("play"), Qt::LeftButton);
  ASSERT_FALSE(w.playing());
  const double fps = w.document().fps(), frames = w.time() * fps;
  EXPECT_GT(w.time(), 0.2);
  EXPECT_NEAR(frames, std::round(frames), 1e-9) << "paused at " << w.time() << " s, between frames";

  w.select_object(1);  // the ball, which has a trajectory
  w.select_key(0);
  auto* x = w.findChild<QDoubleSpinBox*>("keyX");
  w.activateWindow();
  x->setFocus();
  QApplication::processEvents();
  ASSERT_TRUE(x->hasFocus());
  const bool wire = w.findChild<QAction*>("wireframe") ? w.findChild<QAction*>("wireframe")->isChecked() : false;
  QTest::keyClick(x, Qt::Key_W);
  ASSERT_NE(w.findChild<QAction*>("wireframe"), nullptr);
  EXPECT_NE(w.findChild<QAction*>("wireframe")->isChecked(), wire) << "W with a number box focused";
  QTest::keyClick(x, Qt::Key_W);

  // An edit: "Opened ...: N objects" no longer describes the scene.
  ASSERT_TRUE(w.edit("Place", [&](csrbf::composer::Document& d) { d.set_position(1, 0, Vec3(0, 0, 0.5)); }));
  EXPECT_TRUE(w.statusBar()->currentMessage().isEmpty()) << w.statusBar()->currentMessage().toStdString();

  // A scene picked where a deformation goes: said so, in words a new user can act on.
  EXPECT_FALSE(w.attach_deformation(QString::fromStdString(kExamples + "fish.scene.json")));
  const std::string e = w.error_text().toStdString();
  EXPECT_NE(e.find("fish.scene.json is a scene, not a deformation"), std::string::npos) << e;
  EXPECT_NE(e.find("File > Open"), std::string::npos) << e;
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-scene-as-deformation.png").string())));
}

int main(int argc, char** argv) {
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  // The recovery file goes to a folder of the test's own, never the user's.
  const fs::path data = fs::temp_directory_path() / ("csrbf-composer-test-" + std::to_string(::getpid()));
  ::setenv("XDG_DATA_HOME", data.c_str(), 1);
  csrbf::gui::SafeApplication app(argc, argv);
  fs::create_directories(kShots);
  ::testing::InitGoogleTest(&argc, argv);
  const int status = RUN_ALL_TESTS();
  std::error_code ec;
  fs::remove_all(data, ec);
  return status;
}

// Issue 30, point 17: the side panel (objects, trajectory key, orientation, scene, deformations, look:
// 1110 pixels) scrolled in the default 1280x820 window, its last row cut at the fold. It is now in
// three tabs, each of which fits; picking a key on the timeline or in the view shows its tab.
TEST_F(Fixture, EachTabOfTheSidePanelFitsTheDefaultWindow) {
  ASSERT_TRUE(w.open_scene(QString::fromStdString(kExamples + "fish.scene.json")));
  auto* tabs = w.findChild<QTabWidget*>("panelTabs");
  ASSERT_NE(tabs, nullptr);
  ASSERT_EQ(tabs->count(), 3);
  const char* names[3] = {"Object", "Deformations", "Scene"};
  for (int t = 0; t < 3; ++t) {
    EXPECT_EQ(tabs->tabText(t).toStdString(), names[t]);
    QTest::mouseClick(tabs->tabBar(), Qt::LeftButton, Qt::NoModifier, tabs->tabBar()->tabRect(t).center());
    ASSERT_EQ(tabs->currentIndex(), t);
    QApplication::processEvents();
    auto* scroll = qobject_cast<QScrollArea*>(tabs->currentWidget());
    ASSERT_NE(scroll, nullptr);
    EXPECT_EQ(scroll->verticalScrollBar()->maximum(), 0)
        << names[t] << ": " << scroll->widget()->sizeHint().height() << " pixels in " << scroll->viewport()->height();
    ASSERT_TRUE(w.save_screenshot(
        QString::fromStdString((kShots / (std::string("composer-tab-") + names[t] + ".png")).string())));
  }
  // A phase key picked on the timeline shows the Deformations tab; a trajectory key, the Object tab.
  const auto fin = w.document().key_times(0, Track::Phase, 3);
  QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier,
                    QPoint(int(std::lround(w.timeline()->x_of(fin[1]))), w.timeline()->y_of(2 + 3)));
  EXPECT_EQ(w.selected_deformation(), 3);
  EXPECT_EQ(tabs->currentIndex(), 1);
  const auto pos = w.document().key_times(0, Track::Position);
  QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier,
                    QPoint(int(std::lround(w.timeline()->x_of(pos[1]))), w.timeline()->y_of(0)));
  EXPECT_EQ(w.selected_key(), 1);
  EXPECT_EQ(tabs->currentIndex(), 0);
}

// The new user's trial: a value typed but not confirmed (no Enter, no Tab) was dropped by Ctrl+S
// (the status bar said "Saved" over the old value) and by quitting; typed values were rounded to
// the box's 3 decimals; a click on a timeline mark moved it to the snapped time under the pointer;
// a duration of 0 was replaced by the old one without a word.
TEST_F(Fixture, WhatIsTypedIsSavedExactlyAndAClickOnAMarkOnlySelectsIt) {
  csrbf::test::TempDir dir;
  for (const auto& e : fs::directory_iterator(kExamples))
    if (e.path().filename().string().starts_with("fish")) fs::copy_file(e.path(), dir / e.path().filename().string());
  const QString scene = QString::fromStdString((dir / "fish.scene.json").string());
  ASSERT_TRUE(w.open_scene(scene));
  // A click on the mark of the position key at 2 s, and one 6 px beside the fin's phase mark at 1 s:
  // each selects, nothing moves.
  const auto before = w.document().json();
  const int y0 = w.timeline()->y_of(0);
  QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier,
                    QPoint(int(std::lround(w.timeline()->x_of(2.0))), y0));
  EXPECT_EQ(w.selected_key(), 1);
  const auto fin = w.document().key_times(0, Track::Phase, 3);
  QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier,
                    QPoint(int(std::lround(w.timeline()->x_of(fin[1]))) + 6, w.timeline()->y_of(2 + 3)));
  EXPECT_EQ(w.selected_phase_key(), 1);
  EXPECT_EQ(w.document().json(), before);
  EXPECT_FALSE(w.isWindowModified());
  // z of the key at 2 s, typed in full and saved by Ctrl+S while the box still has the focus.
  w.select_key(1);
  QApplication::processEvents();
  auto* z = w.findChild<QDoubleSpinBox*>("keyZ");
  ASSERT_NE(z, nullptr);
  z->setFocus();
  z->findChild<QLineEdit*>()->selectAll();
  QTest::keyClicks(z->findChild<QLineEdit*>(), "0.123456789012");
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_S, Qt::ControlModifier);
  EXPECT_FALSE(w.isWindowModified());
  std::ifstream in(dir / "fish.scene.json");
  const auto saved = nlohmann::json::parse(in);
  EXPECT_EQ(saved["objects"][0]["trajectory"]["keys"][1]["position"][2].get<double>(), 0.123456789012);
  // Ctrl+Z with the focus still in the box undoes the program's last edit (it was inert there); with
  // text typed and not yet entered, it undoes the typing only, as in any text field.
  const auto z_of_key = [&] { return w.document().json()["objects"][0]["trajectory"]["keys"][1]["position"][2]; };
  z->findChild<QLineEdit*>()->selectAll();
  QTest::keyClicks(z->findChild<QLineEdit*>(), "0.5");
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_Return);
  EXPECT_EQ(z_of_key().get<double>(), 0.5);
  EXPECT_TRUE(w.isWindowModified());
  ASSERT_TRUE(z->hasFocus());
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_Z, Qt::ControlModifier);
  EXPECT_EQ(z_of_key().get<double>(), 0.123456789012);
  EXPECT_FALSE(w.isWindowModified());
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_Y, Qt::ControlModifier);
  EXPECT_EQ(z_of_key().get<double>(), 0.5);
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_Z, Qt::ControlModifier);
  z->findChild<QLineEdit*>()->selectAll();
  QTest::keyClicks(z->findChild<QLineEdit*>(), "0.7");
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_Z, Qt::ControlModifier);
  EXPECT_EQ(z_of_key().get<double>(), 0.123456789012);
  EXPECT_NE(z->cleanText(), "0.7");
  QTest::keyClick(z->findChild<QLineEdit*>(), Qt::Key_Escape);
  // A duration of 0 is refused with a message naming the box and its least value.
  auto* duration = w.findChild<QDoubleSpinBox*>("duration");
  const double d0 = duration->value();
  duration->setFocus();
  duration->findChild<QLineEdit*>()->selectAll();
  QTest::keyClicks(duration->findChild<QLineEdit*>(), "0");
  QTest::keyClick(duration->findChild<QLineEdit*>(), Qt::Key_Return);
  EXPECT_EQ(duration->value(), d0);
  EXPECT_TRUE(w.error_text().contains("0 refused: duration is at least 0.1")) << w.error_text().toStdString();
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-typed-saved.png").string())));
}
