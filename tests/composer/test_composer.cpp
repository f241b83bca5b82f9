// The Animation Composer's real window, driven with QTest (run under xvfb-run).
#include "composer_window.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/scene.hpp"
#include "gui_common.hpp"
#include "gui_test_helpers.hpp"
#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <QApplication>
#include <QDoubleSpinBox>
#include <QLabel>
#include <QPushButton>
#include <QSurfaceFormat>
#include <QTest>
#include <QVTKOpenGLNativeWidget.h>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;
using csrbf::Vec3;
using csrbf::composer::ComposerWindow;
using Track = csrbf::composer::Document::Track;

namespace {

const std::string kExamples = std::string(CSRBF_SOURCE_DIR) + "/examples/";
const fs::path kShots = CSRBF_SCREENSHOT_DIR;


struct Fixture : ::testing::Test {
  ComposerWindow w;
  void SetUp() override {
    ASSERT_TRUE(csrbf::test::show_for_test(w, 1280, 820));
  }
  /// Clicks the timeline's ruler (below the key rows) at time t: scrubbing.
  void scrub_to(double t) {
    QTest::mouseClick(w.timeline(), Qt::LeftButton, Qt::NoModifier,
                      QPoint(int(std::lround(w.timeline()->x_of(t))), w.timeline()->height() - 3));
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
  EXPECT_EQ(fs::weakly_canonical(dir.path / o["mesh"].get<std::string>()), fs::weakly_canonical(kExamples + "fish.obj"));
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
  EXPECT_NE(w.error_text().toStdString().find("a key is already at t = 2 s"), std::string::npos) << w.error_text().toStdString();
  // A timing mark dragged past its neighbour.
  const int y = w.timeline()->y_of(0);
  csrbf::test::drag(w.timeline(), QPoint(int(std::lround(w.timeline()->x_of(2.0))), y),
       QPoint(int(std::lround(w.timeline()->x_of(5.0))), y));
  EXPECT_NE(w.error_text().toStdString().find("would pass a neighbouring key"), std::string::npos)
      << w.error_text().toStdString();
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
  EXPECT_GT(w.frames_shown() - shown, 5u);
  EXPECT_GT(w.time(), 0.4);
  const std::string rates = w.findChild<QLabel*>("rates")->text().toStdString();
  EXPECT_NE(rates.find("computed"), std::string::npos) << rates;
  EXPECT_NE(rates.find("rendered"), std::string::npos) << rates;
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "composer-playing.png").string())));
  QTest::keyClick(&w, Qt::Key_Space);  // pause
  EXPECT_FALSE(w.playing());

  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.export_movie(QString::fromStdString((dir / "gui.mp4").string()), 160, 120)) << w.error_text().toStdString();
  const auto probe = csrbf::test::run_shell("ffprobe -v error -count_frames -show_entries stream=nb_read_frames,width,height "
                                            "-of csv=p=0 " + (dir / "gui.mp4").string());
  EXPECT_EQ(probe.out, "160,120,101\n");
  // The command line makes the same movie: the same frames, decoded.
  const auto cli = csrbf::test::run_shell(std::string(CSRBF_CLI) + " animate " + kExamples + "ball.scene.json -o " +
                                          (dir / "cli.mp4").string() + " --size 160x120");
  ASSERT_EQ(cli.code, 0) << cli.out;
  const auto a = csrbf::test::run_shell("ffmpeg -v error -i " + (dir / "gui.mp4").string() + " -f rawvideo -pix_fmt rgb24 -");
  const auto b = csrbf::test::run_shell("ffmpeg -v error -i " + (dir / "cli.mp4").string() + " -f rawvideo -pix_fmt rgb24 -");
  ASSERT_EQ(a.out.size(), b.out.size());
  ASSERT_EQ(a.out.size(), 101u * 160 * 120 * 3);
  double diff = 0;
  for (std::size_t i = 0; i < a.out.size(); ++i) diff += std::abs(int((unsigned char)a.out[i]) - int((unsigned char)b.out[i]));
  EXPECT_LT(diff / double(a.out.size()), 0.5);
}

int main(int argc, char** argv) {
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication app(argc, argv);
  fs::create_directories(kShots);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
