// The Picker's real window, driven with QTest mouse and key events (run under xvfb-run).
#include "csrbf/io/deformation.hpp"
#include "gui_common.hpp"
#include "gui_test_helpers.hpp"
#include "io/test_helpers.hpp"
#include "picker_window.hpp"

#include <gtest/gtest.h>

#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QDropEvent>
#include <QMimeData>
#include <QPushButton>
#include <QSlider>
#include <QSurfaceFormat>
#include <QTableWidget>
#include <QTest>
#include <QVTKOpenGLNativeWidget.h>

#include <filesystem>

namespace fs = std::filesystem;
using csrbf::Vec3;
using csrbf::picker::PickerWindow;

namespace {

const std::string kExamples = std::string(CSRBF_SOURCE_DIR) + "/examples/";
const fs::path kShots = CSRBF_SCREENSHOT_DIR;

struct Fixture : ::testing::Test {
  PickerWindow w;
  void SetUp() override {
    ASSERT_TRUE(csrbf::test::show_for_test(w, 1200, 760));
    ASSERT_TRUE(w.open_mesh(QString::fromStdString(kExamples + "fish.obj")));
    QApplication::processEvents();
  }
  QPoint centre() const { return {w.view()->width() / 2, w.view()->height() / 2}; }
};

}  // namespace

TEST_F(Fixture, ClickAddsAControlOnTheSurfaceDragDeformsUndoRestores) {
  const auto& doc = w.document();
  // Click on the middle of the fish: a control appears at a point of the mesh's surface.
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::NoModifier, centre());
  ASSERT_EQ(doc.state().controls.size(), 1u) << w.error_text().toStdString();
  const auto c0 = doc.state().controls[0];
  EXPECT_FALSE(c0.pinned);
  EXPECT_LT(csrbf::picker::distance_to_mesh(doc.rest(), doc.mesh().faces(), c0.source), 1e-6 * doc.diagonal());
  EXPECT_EQ(c0.destination, c0.source);
  EXPECT_EQ(doc.deformed(), doc.rest());

  // Drag its handle 60 pixels up and right: the destination follows, the mesh deforms.
  const QPoint handle = csrbf::test::widget_point(w, c0.destination);
  csrbf::test::drag(w.view(), handle, handle + QPoint(60, -60));
  ASSERT_EQ(doc.state().controls.size(), 1u);
  const auto c1 = doc.state().controls[0];
  EXPECT_EQ(c1.source, c0.source);
  EXPECT_GT((c1.destination - c1.source).norm(), 0.02 * doc.diagonal());
  // The handle ended under the cursor.
  const QPoint now = csrbf::test::widget_point(w, c1.destination);
  EXPECT_LE((now - (handle + QPoint(60, -60))).manhattanLength(), 3);
  std::size_t moved = 0;
  for (std::size_t i = 0; i < doc.rest().size(); ++i) moved += (doc.deformed()[i] - doc.rest()[i]).norm() > 1e-6;
  EXPECT_GT(moved, 3u);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "picker-drag.png").string())));

  // The saved deformation file holds that source and destination.
  csrbf::test::TempDir dir;
  ASSERT_TRUE(w.save_deformation(QString::fromStdString((dir / "d.json").string())));
  const auto spec = csrbf::io::read_deformation(dir / "d.json");
  ASSERT_EQ(spec.sources.size(), 1u);
  EXPECT_EQ(spec.sources[0], c1.source);
  EXPECT_EQ(spec.destinations[0], c1.destination);
  EXPECT_EQ(spec.options.radius, doc.state().radius);

  // Ctrl+Z undoes the drag (the mesh is back at rest), then the click; Ctrl+Shift+Z redoes.
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);
  ASSERT_EQ(doc.state().controls.size(), 1u);
  EXPECT_EQ(doc.state().controls[0].destination, c0.source);
  EXPECT_EQ(doc.deformed(), doc.rest());
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier);
  EXPECT_TRUE(doc.state().controls.empty());
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  QTest::keyClick(&w, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  ASSERT_EQ(doc.state().controls.size(), 1u);
  EXPECT_EQ(doc.state().controls[0].destination, c1.destination);

  // Exported mesh: the deformed positions.
  ASSERT_TRUE(w.export_mesh(QString::fromStdString((dir / "out.obj").string())));
  const auto out = csrbf::io::MeshDocument::load(dir / "out.obj");
  for (std::size_t i = 0; i < doc.rest().size(); ++i) ASSERT_LT((out.positions()[i] - doc.deformed()[i]).norm(), 1e-5);
}

TEST_F(Fixture, DegenerateSettingShowsAnErrorAndKeepsTheLastGoodState) {
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::NoModifier, centre());
  ASSERT_EQ(w.document().state().controls.size(), 1u);
  const auto good = w.document().state();
  // A linear polynomial needs 4 sources not in a plane: with one the engine refuses.
  auto* poly = w.findChild<QComboBox*>("polynomial");
  ASSERT_NE(poly, nullptr);
  poly->setCurrentIndex(2);
  QApplication::processEvents();
  EXPECT_EQ(w.document().state(), good);
  EXPECT_EQ(poly->currentIndex(), 0) << "the widget shows the kept state";
  const std::string error = w.error_text().toStdString();
  EXPECT_NE(error.find("Polynomial"), std::string::npos) << error;
  EXPECT_NE(error.find("last good state is kept"), std::string::npos) << error;
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "picker-error.png").string())));
  // The next good edit clears the message.
  poly->setCurrentIndex(1);
  EXPECT_TRUE(w.error_text().isEmpty());
  EXPECT_EQ(w.document().state().polynomial, csrbf::Polynomial::Constant);
}

TEST_F(Fixture, PinsDeletesEditsAndLimitsToAnActiveArea) {
  const auto& doc = w.document();
  // Shift-click pins a point.
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::ShiftModifier, centre() + QPoint(-80, 0));
  ASSERT_EQ(doc.state().controls.size(), 1u);
  EXPECT_TRUE(doc.state().controls[0].pinned);
  // A second, free control; its destination typed into the table.
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::NoModifier, centre() + QPoint(60, 0));
  ASSERT_EQ(doc.state().controls.size(), 2u);
  auto* table = w.findChild<QTableWidget*>("controls");
  ASSERT_NE(table, nullptr);
  const Vec3 src = doc.state().controls[1].source;
  table->item(1, 4)->setText(QString::number(src.y() + 0.1, 'g', 17));
  EXPECT_NEAR(doc.state().controls[1].destination.y(), src.y() + 0.1, 1e-12);
  EXPECT_TRUE(doc.deformed() != doc.rest());
  // A bad number in the table is refused with a message.
  table->item(1, 3)->setText("abc");
  EXPECT_NE(w.error_text().toStdString().find("'abc' is not a number"), std::string::npos);
  EXPECT_EQ(doc.state().controls[1].destination.x(), src.x());

  // Radius through its spin box; support spheres and displacement colours on: a screenshot.
  auto* radius = w.findChild<QDoubleSpinBox*>("radius");
  radius->setValue(0.25);
  EXPECT_EQ(doc.state().radius, 0.25);
  w.findChild<QCheckBox*>("supports")->setChecked(true);
  w.findChild<QCheckBox*>("colourDisplacement")->setChecked(true);
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "picker-supports.png").string())));

  // Ctrl-drag over the right half selects an active area: the left vertices no longer move.
  const int wv = w.view()->width(), hv = w.view()->height();
  csrbf::test::drag(w.view(), QPoint(wv / 2, 5), QPoint(wv - 5, hv - 5), Qt::ControlModifier);
  ASSERT_FALSE(doc.state().region.empty());
  EXPECT_LT(doc.state().region.size(), doc.rest().size());
  std::vector<char> in(doc.rest().size(), 0);
  for (const auto v : doc.state().region) in[v] = 1;
  for (std::size_t i = 0; i < doc.rest().size(); ++i) {
    if (!in[i]) {
      ASSERT_EQ(doc.deformed()[i], doc.rest()[i]) << i;
    }
  }
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "picker-region.png").string())));
  QTest::mouseClick(w.findChild<QPushButton*>("clearRegion"), Qt::LeftButton);
  EXPECT_TRUE(doc.state().region.empty());

  // Select the pinned point in the table, delete it with the Delete key.
  table->selectRow(0);
  EXPECT_EQ(w.selected(), 0);
  QTest::keyClick(&w, Qt::Key_Delete);
  ASSERT_EQ(doc.state().controls.size(), 1u);
  EXPECT_FALSE(doc.state().controls[0].pinned);
}

TEST_F(Fixture, LoadsDeformationsAndReportsBadFiles) {
  ASSERT_TRUE(w.load_controls(QString::fromStdString(kExamples + "fish-tail-left.controls")));
  EXPECT_EQ(w.document().state().controls.size(), 92u);
  csrbf::test::TempDir dir;
  csrbf::test::write_text(dir / "bad.json", R"({"radius": -1, "controls": "x"})");
  EXPECT_FALSE(w.load_deformation(QString::fromStdString((dir / "bad.json").string())));
  EXPECT_NE(w.error_text().toStdString().find("bad.json: radius: expected a number > 0"), std::string::npos)
      << w.error_text().toStdString();
  EXPECT_EQ(w.document().state().controls.size(), 92u);
  EXPECT_FALSE(w.open_mesh(QString::fromStdString((dir / "missing.obj").string())));
  EXPECT_EQ(w.document().rest().size(), 977u) << "the open mesh stays";
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "picker-loaded.png").string())));

  // A mesh dropped on the window opens; a dropped deformation file loads.
  csrbf::io::DeformationSpec spec;
  spec.options.radius = 0.2;
  spec.sources = {Vec3(0.5, 0.5, 0.8)};
  spec.destinations = {Vec3(0.5, 0.55, 0.85)};
  csrbf::io::write_deformation(dir / "face.json", spec);
  for (const std::string& file : {kExamples + "face.obj", (dir / "face.json").string()}) {
    QMimeData mime;
    mime.setUrls({QUrl::fromLocalFile(QString::fromStdString(file))});
    QDragEnterEvent enter(QPoint(100, 100), Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
    QApplication::sendEvent(&w, &enter);
    EXPECT_TRUE(enter.isAccepted());
    QDropEvent drop(QPointF(100, 100), Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
    QApplication::sendEvent(&w, &drop);
  }
  EXPECT_EQ(w.document().rest().size(), 6158u);
  ASSERT_EQ(w.document().state().controls.size(), 1u);
  EXPECT_EQ(w.document().state().radius, 0.2);
}

TEST_F(Fixture, FoldedRegionsAreColouredAndWarned) {
  const auto& doc = w.document();
  QTest::mouseClick(w.view(), Qt::LeftButton, Qt::NoModifier, centre());
  ASSERT_EQ(doc.state().controls.size(), 1u);
  EXPECT_TRUE(w.fold_warning().isEmpty());
  // Push the control 0.8 R sideways: C2 folds from phase 1 / (0.8 * 135 / 64) = 0.59.
  auto s = doc.state();
  s.controls[0].destination = s.controls[0].source + Vec3(0, 0.8 * s.radius, 0);
  ASSERT_TRUE(w.edit(s, "Push"));
  const std::string warning = w.fold_warning().toStdString();
  EXPECT_NE(warning.find("over (det dT/dx <= 0"), std::string::npos) << warning;
  // The closed form's 0.59 holds at r = R/4 ahead of the push; the vertices near there start at or after it.
  const auto at = warning.find("fold-free up to phase ");
  ASSERT_NE(at, std::string::npos) << warning;
  const double first = std::stod(warning.substr(at + 22));
  EXPECT_GE(first, 0.59);
  EXPECT_LT(first, 1.0);
  EXPECT_FALSE(doc.folds().folded_vertices.empty());
  ASSERT_TRUE(w.save_screenshot(QString::fromStdString((kShots / "picker-folds.png").string())));
  // Below the first fold nothing folds.
  w.findChild<QSlider*>("phase")->setValue(50);
  EXPECT_TRUE(w.fold_warning().isEmpty()) << w.fold_warning().toStdString();
}

int main(int argc, char** argv) {
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication app(argc, argv);
  fs::create_directories(kShots);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
