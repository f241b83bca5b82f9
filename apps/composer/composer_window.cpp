// The Composer's window as a whole: construction, menus, scene files, objects and deformations added,
// undoable edits, messages, time and playback, and closing with unsaved changes.
#include "composer_window.hpp"
#include "composer_undo.hpp"

#include "csrbf/render/scene_renderer.hpp"
#include "gui_common.hpp"

#include <QAction>
#include <QCheckBox>
#include <QCloseEvent>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QInputDialog>
#include <QLabel>
#include <QLineEdit>
#include <QMenuBar>
#include <QMessageBox>
#include <QPushButton>
#include <QStatusBar>
#include <QTimer>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkCameraActor.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkRenderer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>

namespace csrbf::composer {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

ComposerWindow::ComposerWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle("untitled[*] - csrbf Animation Composer");
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) { setWindowModified(!clean); });
  build_ui();
  build_menus();
  gui::pass_letters_to_shortcuts(this);  // W, D, S work while a number box has focus
  statusBar()->showMessage(
      "Open a scene (Ctrl+O), or add an object (Ctrl+Shift+A)");  // made now: a message later never resizes the view
  timer_ = new QTimer(this);
  connect(timer_, &QTimer::timeout, this, [this] { tick(); });
  rebuild();
  undo_.setClean();
  recovery_timer_ = new QTimer(this);
  recovery_timer_->setInterval(gui::recovery_seconds() * 1000);
  connect(recovery_timer_, &QTimer::timeout, this, [this] { write_recovery(); });
  recovery_timer_->start();
  // Saved (or undone back to the saved state): nothing left to recover.
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) {
    if (clean) recovery_.remove();
  });
}

bool ComposerWindow::write_recovery() {
  if (undo_.isClean()) return false;
  const json j{{"format", "csrbf-composer-recovery"},
               {"path", doc_.path().string()},
               {"base", doc_.base().string()},
               {"scene", doc_.json()}};
  return recovery_.write(j.dump(1));
}

bool ComposerWindow::recover() {
  json j;
  try {
    j = json::parse(recovery_.read());
    if (!j.is_object() || j.value("format", "") != "csrbf-composer-recovery" || !j.contains("scene") ||
        !j["scene"].is_object())
      throw csrbf::Error("not a Composer recovery file");
    Document next;
    next.adopt(j["scene"], j.value("base", ""), j.value("path", ""));
    next.build();  // the whole check, before it replaces anything
    play(false);
    doc_ = std::move(next);
  } catch (const std::exception& e) {
    show_error("Cannot recover " + recovery_.path() + ": " + e.what());
    return false;
  }
  undo_.clear();
  object_ = doc_.object_count() > 0 ? 0 : -1;
  key_ = deformation_ = phase_key_ = -1;
  time_ = 0;
  clear_error();
  scene_.reset();
  rebuild();
  look_through_scene_camera();
  undo_.resetClean();  // recovered work is unsaved work
  const QString name =
      doc_.path().empty() ? QString("untitled") : QFileInfo(QString::fromStdString(doc_.path().string())).fileName();
  setWindowTitle(name + "[*] - csrbf Animation Composer");
  setWindowModified(true);
  statusBar()->showMessage("Recovered unsaved work: save it (Ctrl+S) to keep it", 10000);
  return true;
}

void ComposerWindow::offer_recovery() {
  if (recovery_.offer(this, "The Composer found work on %1", "path", "an untitled scene")) recover();
}

ComposerWindow::~ComposerWindow() {
  // QUndoStack's destructor emits cleanChanged: nothing of this window may answer it any more.
  QObject::disconnect(&undo_, nullptr, this, nullptr);
  timer_->stop();
  if (scene_renderer_) window_->RemoveRenderer(scene_renderer_->renderer());
}

void ComposerWindow::build_menus() {
  auto add = [this](QMenu* m, const QString& text, const QKeySequence& key, auto fn) {
    QAction* a = m->addAction(text);
    a->setShortcut(key);
    connect(a, &QAction::triggered, this, fn);
    return a;
  };
  const auto folder = [this] { return gui::dialog_folder(QString::fromStdString(doc_.path().string())); };
  const auto save_as = [this, folder] {
    const QString start = doc_.path().empty() ? folder() + "/scene.json" : QString::fromStdString(doc_.path().string());
    const QString f = QFileDialog::getSaveFileName(this, "Save scene", start, "Scenes (*.json)");
    gui::remember_folder(f);
    return !f.isEmpty() && save_scene(f);
  };
  auto* file = menuBar()->addMenu("&File");
  add(file, "&New scene", QKeySequence::New, [this] {
    if (maybe_save()) new_scene();
  });
  add(file, "&Open scene...", QKeySequence::Open, [this, folder] {
    if (!maybe_save()) return;
    const QString f = QFileDialog::getOpenFileName(this, "Open scene", folder(), "Scenes (*.json)");
    gui::remember_folder(f);
    if (!f.isEmpty()) open_scene(f);
  });
  add(file, "&Save scene", QKeySequence::Save, [this, save_as] {
    if (doc_.path().empty())
      save_as();
    else
      save_scene(QString::fromStdString(doc_.path().string()));
  });
  add(file, "Save scene &as...", QKeySequence("Ctrl+Shift+S"), save_as);  // QKeySequence::SaveAs is empty on X11
  add(file, "&Export movie...", QKeySequence("Ctrl+E"), [this, folder] {
    const QString f =
        QFileDialog::getSaveFileName(this, "Export movie", folder() + "/movie.mp4", "Movies (*.mp4 *.avi)");
    gui::remember_folder(f);
    if (f.isEmpty()) return;
    bool ok = false;
    const QString size =
        QInputDialog::getText(this, "Export movie", "Frame size (WIDTHxHEIGHT):", QLineEdit::Normal, "640x480", &ok);
    if (!ok) return;
    const QStringList wh = size.split('x');
    if (wh.size() != 2 || wh[0].toInt() < 16 || wh[1].toInt() < 16) {
      show_error("Frame size: expected WIDTHxHEIGHT, got '" + size + "'");
      return;
    }
    export_movie(f, wh[0].toInt(), wh[1].toInt());
  });
  file->addSeparator();
  add(file, "&Quit", QKeySequence::Quit, [this] { close(); });

  auto* editm = menuBar()->addMenu("&Edit");
  gui::add_undo_actions(editm, undo_, this);
  editm->addSeparator();
  add(editm, "Add trajectory &key", QKeySequence("K"), [this] { findChild<QPushButton*>("addKey")->click(); });
  add(editm, "&Delete selected key", QKeySequence::Delete, [this] {
    if (phase_key_ >= 0)
      findChild<QPushButton*>("deletePhaseKey")->click();
    else
      findChild<QPushButton*>("deleteKey")->click();
  });
  add(editm, "Set &orientation key", QKeySequence("O"), [this] { findChild<QPushButton*>("setOrientation")->click(); });
  add(editm, "Add &phase key", QKeySequence("P"), [this] { findChild<QPushButton*>("addPhaseKey")->click(); });

  auto* objm = menuBar()->addMenu("&Object");
  add(objm, "&Add object...", QKeySequence("Ctrl+Shift+A"), [this] { findChild<QPushButton*>("addObject")->click(); });
  add(objm, "Attach &deformation...", QKeySequence("Ctrl+D"), [this] { findChild<QPushButton*>("attach")->click(); });
  add(objm, "&Remove object", QKeySequence("Ctrl+Shift+Del"), [this] {
    if (!has_object()) return;
    const int o = object_;
    if (edit("Remove object", [&](Document& d) { d.remove_object(std::size_t(o)); }))
      select_object(std::min(o, int(doc_.object_count()) - 1));
  });
  add(objm, "&Background colour...", QKeySequence(), [this] { findChild<QPushButton*>("background")->click(); });
  add(objm, "Object &colour...", QKeySequence(), [this] { findChild<QPushButton*>("objectColour")->click(); });
  add(objm, "Add &light from view", QKeySequence(), [this] { findChild<QPushButton*>("addLight")->click(); });

  auto* viewm = menuBar()->addMenu("&View");
  add(viewm, "&Reset camera (front, fit)", QKeySequence("R"), [this] { reset_camera(); });
  add(viewm, "&Frame all", QKeySequence("Home"), [this] { frame_all(); });  // as Blender's View All
  gui::add_view_actions(viewm, this, [this](gui::View v) { reset_camera(v); });
  viewm->addSeparator();
  add(viewm, "Set scene &camera from view", QKeySequence("Ctrl+Shift+C"), [this] { set_scene_camera_from_view(); });
  add(viewm, "&Look through scene camera", QKeySequence("C"), [this] { look_through_scene_camera(); });
  QAction* frame = add(viewm, "Show scene camera's &frame", QKeySequence("F"), [this](bool on) {
    camera_actor_->SetVisibility(on);
    view_->renderWindow()->Render();
  });
  frame->setCheckable(true);
  frame->setChecked(true);
  wireframe_ = add(viewm, "&Wireframe", QKeySequence("W"), [this] {
    apply_wireframe();
    view_->renderWindow()->Render();
  });
  wireframe_->setObjectName("wireframe");
  wireframe_->setCheckable(true);

  auto* playm = menuBar()->addMenu("&Animation");
  add(playm, "&Play / pause", QKeySequence("Space"), [this] { play_->toggle(); });
  add(playm, "To the &start", QKeySequence("Shift+Left"), [this] { set_time(0); });  // as in Blender
  add(playm, "&Next frame", QKeySequence("Right"), [this] { set_time(time_ + 1.0 / doc_.fps()); });
  add(playm, "P&revious frame", QKeySequence("Left"), [this] { set_time(time_ - 1.0 / doc_.fps()); });

  auto* help = menuBar()->addMenu("&Help");
  add(help, "&Mouse and keys", QKeySequence::HelpContents, [this] {
    gui::show_reference(this, "csrbf Animation Composer: mouse and keys", R"(
<h3>Mouse in the 3D view</h3>
<table cellpadding=3>
<tr><td><b>Left click</b> on a key (orange ball)</td><td>select it</td></tr>
<tr><td><b>Left drag</b> on a key</td><td>move it, in the plane facing you</td></tr>
<tr><td><b>Shift + left click</b></td><td>add a trajectory key at the current time under the cursor</td></tr>
<tr><td><b>Ctrl + left drag</b></td><td>turn the selected object (an orientation key at the current time)</td></tr>
<tr><td><b>Left drag</b> elsewhere / <b>middle drag</b> / <b>wheel</b></td><td>orbit / pan / zoom</td></tr>
</table>
<h3>Timeline</h3>
<p>Click or drag on the ruler to scrub. Drag a mark to move its key in time: keys sit on frames and
stop one frame short of their neighbours. Click a phase mark (green) to select it; the Deformations
box then edits its time and value. Rows are named after the deformations.</p>
<h3>Keys</h3>
<table cellpadding=3>
<tr><td>Ctrl+N / Ctrl+O / Ctrl+S / Ctrl+Shift+S</td><td>new / open / save / save as</td></tr>
<tr><td>Ctrl+E</td><td>export a movie (MP4, AVI)</td></tr>
<tr><td>Ctrl+Z / Ctrl+Shift+Z, Ctrl+Y</td><td>undo / redo</td></tr>
<tr><td>Ctrl+Shift+A / Ctrl+D / Ctrl+Shift+Del</td><td>add an object / attach a deformation / remove the object</td></tr>
<tr><td>K / O / P</td><td>trajectory key / orientation key / phase key at the current time</td></tr>
<tr><td>Delete</td><td>delete the selected key</td></tr>
<tr><td>Space / Home / Left / Right</td><td>play or pause / to the start / previous / next frame</td></tr>
<tr><td>R / 1 / 3 / 7</td><td>reset the camera (front, fitted) / front / side / top view</td></tr>
<tr><td>C / Ctrl+Shift+C / F</td><td>look through the scene camera / set it from the view / show its frame</td></tr>
<tr><td>W</td><td>wireframe</td></tr>
<tr><td>F1</td><td>this reference</td></tr>
</table>
<p>The movie is rendered through the <b>scene camera</b> (its frame is drawn in cyan), not through the
view: frame a shot in the view, then Set scene camera from view.</p>)");
  });
}

bool ComposerWindow::new_scene() {
  play(false);
  doc_.reset(std::filesystem::current_path());
  undo_.clear();
  object_ = key_ = deformation_ = phase_key_ = -1;
  time_ = 0;
  clear_error();
  info_->hide();
  scene_.reset();
  rebuild();
  look_through_scene_camera();
  undo_.setClean();
  setWindowTitle("untitled[*] - csrbf Animation Composer");
  setWindowModified(false);
  return true;
}

bool ComposerWindow::open_scene(const QString& path) {
  play(false);
  Document next = doc_;
  try {
    next.open(path.toStdString());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  doc_ = std::move(next);
  undo_.clear();
  object_ = doc_.object_count() > 0 ? 0 : -1;
  key_ = deformation_ = phase_key_ = -1;
  time_ = 0;
  clear_error();
  info_->hide();
  scene_.reset();
  rebuild();
  look_through_scene_camera();
  undo_.setClean();
  setWindowTitle(QFileInfo(path).fileName() + "[*] - csrbf Animation Composer");
  setWindowModified(false);
  statusBar()->showMessage(QString("Opened %1: %2 objects, %3 s at %4 fps")
                               .arg(path)
                               .arg(doc_.object_count())
                               .arg(doc_.duration())
                               .arg(doc_.fps()));
  return true;
}

bool ComposerWindow::save_scene(const QString& path) {
  gui::commit_pending_edit();
  try {
    doc_.save(path.toStdString());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  undo_.setClean();
  clear_error();
  setWindowTitle(QFileInfo(path).fileName() + "[*] - csrbf Animation Composer");
  setWindowModified(false);
  statusBar()->showMessage("Saved " + path, 5000);
  return true;
}

bool ComposerWindow::add_object(const QString& mesh) {
  std::size_t i = 0;
  if (!edit("Add object", [&](Document& d) { i = d.add_object(mesh.toStdString()); })) return false;
  select_object(int(i));
  if (doc_.object_count() == 1 && scene_renderer_) {
    scene_renderer_->renderer()->ResetCamera();
    show_frame();
  }
  return true;
}

bool ComposerWindow::attach_deformation(const QString& file) {
  if (object_ < 0) {
    show_error("Select an object first");
    return false;
  }
  if (!edit("Attach deformation", [&](Document& d) { d.attach_deformation(std::size_t(object_), file.toStdString()); }))
    return false;
  tabs_->setCurrentIndex(kDeformationsTab);  // where the attached deformation is edited
  return true;
}

bool ComposerWindow::edit(const QString& what, const std::function<void(Document&)>& change) {
  Document next = doc_;
  std::unique_ptr<anim::Scene> scene;
  try {
    change(next);
    scene = std::make_unique<anim::Scene>(next.build());
  } catch (const std::exception& e) {
    show_error(what + ": " + e.what() + "\nThe scene is unchanged.");
    refresh_panel();
    return false;
  }
  const json before = doc_.json();
  const std::filesystem::path before_base = doc_.base();
  const int selection[4] = {object_, key_, deformation_, phase_key_};
  try {
    doc_ = std::move(next);
    clear_error();
    info_->hide();
    scene_ = std::move(scene);
    rebuild();
  } catch (const std::exception& e) {
    // Showing the edited scene failed: back to the scene before the edit, with no undo step.
    doc_.set_json(before, before_base);
    object_ = selection[0], key_ = selection[1], deformation_ = selection[2], phase_key_ = selection[3];
    scene_.reset();
    rebuild();
    show_error(what + ": " + e.what() + "\nThe scene is unchanged.");
    return false;
  }
  statusBar()->clearMessage();  // "Opened ...: N objects" and the like no longer describe the scene
  undo_.push(new JsonCommand(this, before, doc_.json(), doc_.base(), what));
  return true;
}

void ComposerWindow::restore(const json& j, const std::filesystem::path& base) {
  doc_.set_json(j, base);
  if (object_ >= int(doc_.object_count())) object_ = int(doc_.object_count()) - 1;
  // What was selected stays selected where it still exists (undoing a key's edit with the focus in
  // its box keeps that key in the panel, as Blender does); what is gone is deselected.
  if (object_ < 0) {
    key_ = deformation_ = phase_key_ = -1;
  } else {
    const auto o = std::size_t(object_);
    if (key_ >= int(doc_.key_times(o, Document::Track::Position).size())) key_ = -1;
    if (deformation_ >= int(doc_.deformation_count(o))) deformation_ = -1;
    if (deformation_ < 0 ||
        phase_key_ >= int(doc_.key_times(o, Document::Track::Phase, std::size_t(deformation_)).size()))
      phase_key_ = -1;
  }
  clear_error();
  scene_.reset();
  rebuild();
}

QString ComposerWindow::error_text() const { return error_->isHidden() ? QString() : error_->text(); }

QString ComposerWindow::info_text() const { return info_->isHidden() ? QString() : info_->text(); }

void ComposerWindow::show_info(const QString& m) {
  info_->setText(m);
  info_->show();
  statusBar()->showMessage(m, 10000);
}

void ComposerWindow::show_error(const QString& m) {
  error_->setText(m);
  error_->show();
  statusBar()->showMessage(m.section('\n', 0, 0), 10000);
}

void ComposerWindow::clear_error() {
  // The status bar repeats an error's first line: it goes with the error, not 10 s later.
  if (!error_->isHidden() && statusBar()->currentMessage() == error_->text().section('\n', 0, 0))
    statusBar()->clearMessage();
  error_->clear();
  error_->hide();
}

void ComposerWindow::set_time(double t) {
  time_ = doc_.snap(std::clamp(t, 0.0, doc_.duration()));  // scrubbing stops on frames, as keys do
  time_ = std::min(time_, doc_.duration());
  show_frame();
  refresh_panel();
}

bool ComposerWindow::playing() const { return timer_->isActive(); }

void ComposerWindow::play(bool on) {
  if (on && !timer_->isActive()) {
    if (time_ >= doc_.duration()) time_ = 0;
    compute_s_ = render_s_ = 0;
    rate_frames_ = 0;
    last_tick_ = Clock::now();
    timer_->start(int(std::lround(1000.0 / doc_.fps())));
  } else if (!on && timer_->isActive()) {
    timer_->stop();
    // Playing runs in real time, between frames: a pause stops on the nearest frame, where keys go
    // and the time box can show it (else a key added now lands off the frame grid).
    set_time(time_);
  }
  if (play_->isChecked() != on) play_->setChecked(on);
  play_->setText(on ? "Pause" : "Play");
}

void ComposerWindow::tick() {
  // Real time: the animation keeps the scene's pace even when frames take longer than 1 / fps.
  const auto now = Clock::now();
  double t = time_ + std::chrono::duration<double>(now - last_tick_).count();
  last_tick_ = now;
  if (t > doc_.duration()) {
    if (loop_->isChecked()) {
      t = std::fmod(t, doc_.duration());
    } else {
      set_time(doc_.duration());
      play(false);
      return;
    }
  }
  time_ = t;
  show_frame();
  if (has_object()) {  // the orientation box follows the animation
    updating_ = true;
    const Vec3 a = angles_from_quaternion(scene_->objects[std::size_t(object_)].orientation.rotation(time_));
    for (int c = 0; c < 3; ++c) angles_[c]->setValue(a[c]);
    updating_ = false;
  }
  if (rate_frames_ > 0 && compute_s_ > 0 && render_s_ > 0)
    rates_->setText(QString("computed %1 fps, rendered %2 fps")
                        .arg(double(rate_frames_) / compute_s_, 0, 'f', 0)
                        .arg(double(rate_frames_) / render_s_, 0, 'f', 0));
}

bool ComposerWindow::has_object() const {
  return object_ >= 0 && scene_ && std::size_t(object_) < scene_->objects.size();
}

bool ComposerWindow::maybe_save() {
  gui::commit_pending_edit();
  if (undo_.isClean() || property("noPrompt").toBool()) return true;
  const auto answer = gui::ask_unsaved(this, "The scene has unsaved changes.");
  if (answer == QMessageBox::Cancel) return false;
  if (answer == QMessageBox::Discard) return true;
  QString f = QString::fromStdString(doc_.path().string());
  if (f.isEmpty()) {
    f = QFileDialog::getSaveFileName(this, "Save scene", gui::dialog_folder({}) + "/scene.json", "Scenes (*.json)");
    gui::remember_folder(f);
  }
  return !f.isEmpty() && save_scene(f);
}

void ComposerWindow::closeEvent(QCloseEvent* e) {
  play(false);
  if (maybe_save()) {
    if (!property("noPrompt").toBool()) recovery_.remove();  // saved, or discarded on purpose
    e->accept();
  } else {
    e->ignore();
  }
}

}  // namespace csrbf::composer
