// The Picker's window as a whole: construction, menus, files (open, load, save, export), undoable
// edits, and closing with unsaved changes. The 3D view, its mouse and the side panel have their own files.
#include "picker_window.hpp"

#include "picker_undo.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "gui_common.hpp"

#include <nlohmann/json.hpp>

#include <QAction>
#include <QDir>
#include <QTimer>
#include <QCheckBox>
#include <QCloseEvent>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QStatusBar>
#include <QUrl>

#include <vtkCellArray.h>
#include <vtkNew.h>
#include <vtkPolyData.h>

#include <filesystem>
#include <iostream>

namespace csrbf::picker {

PickerWindow::PickerWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle("csrbf Picker[*]");
  setAcceptDrops(true);
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) { setWindowModified(!clean); });
  build_scene();
  build_ui();
  build_menus();
  gui::pass_letters_to_shortcuts(this);  // W, D, S work while a number box has focus
  refresh();
  auto* recovery_timer = new QTimer(this);
  recovery_timer->setInterval(gui::recovery_seconds() * 1000);
  connect(recovery_timer, &QTimer::timeout, this, [this] { write_recovery(); });
  recovery_timer->start();
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) {
    if (clean) recovery_.remove();
  });
}

PickerWindow::~PickerWindow() {
  // QUndoStack's destructor emits cleanChanged: nothing of this window may answer it any more.
  QObject::disconnect(&undo_, nullptr, this, nullptr);
}

bool PickerWindow::write_recovery() {
  if (undo_.isClean() || !doc_.has_mesh()) return false;
  // The deformation as its file holds it, inside the recovery file with the mesh it was made on.
  const QString deformation = recovery_.side_path(kRecoveredDeformation);
  try {
    QDir().mkpath(QFileInfo(recovery_.path()).absolutePath());
    io::write_deformation(deformation.toStdString(), doc_.deformation());
  } catch (const std::exception& e) {
    std::cerr << "csrbf-picker: warning: cannot write the recovery file: " << printable(e.what()) << '\n';
    return false;
  }
  const nlohmann::json j{{"format", "csrbf-picker-recovery"},
                         {"mesh", std::filesystem::absolute(doc_.mesh_path()).string()},
                         {"path", deformation_path_.toStdString()},
                         {"deformation", deformation.toStdString()}};
  return recovery_.write(j.dump(1));
}

bool PickerWindow::recover() {
  try {
    const nlohmann::json j = nlohmann::json::parse(recovery_.read());
    if (!j.is_object() || j.value("format", "") != "csrbf-picker-recovery")
      throw csrbf::Error("not a Picker recovery file");
    const auto spec = io::read_deformation(j.value("deformation", ""));
    if (!open_mesh(QString::fromStdString(j.value("mesh", "")))) return false;
    if (!edit(doc_.state_from(spec, j.value("deformation", "")), "Recover unsaved work")) return false;
    deformation_path_ = QString::fromStdString(j.value("path", ""));
  } catch (const std::exception& e) {
    show_error("Cannot recover " + recovery_.path() + ": " + e.what());
    return false;
  }
  undo_.resetClean();  // recovered work is unsaved work
  setWindowModified(true);
  statusBar()->showMessage("Recovered unsaved work: save it (Ctrl+S) to keep it", 10000);
  return true;
}

void PickerWindow::offer_recovery() {
  if (recovery_.offer(this, "The Picker found a deformation of %1", "mesh", "a mesh")) recover();
}

void PickerWindow::build_menus() {
  auto* file = menuBar()->addMenu("&File");
  auto add = [this](QMenu* m, const QString& text, const QKeySequence& key, auto fn) {
    QAction* a = m->addAction(text);
    a->setShortcut(key);
    connect(a, &QAction::triggered, this, fn);
    return a;
  };
  const auto folder = [this] {
    return gui::dialog_folder(!deformation_path_.isEmpty() ? deformation_path_
                                                           : QString::fromStdString(doc_.mesh_path().string()));
  };
  add(file, "&Open mesh...", QKeySequence::Open, [this, folder] {
    if (!maybe_save()) return;
    const QString f = QFileDialog::getOpenFileName(
        this, "Open mesh", folder(), "Meshes (*.obj *.ply *.off *.stl *.gltf *.glb *.xyz);;All files (*)");
    gui::remember_folder(f);
    if (!f.isEmpty()) open_mesh(f);
  });
  add(file, "&Load deformation...", QKeySequence("Ctrl+L"), [this, folder] {
    const QString f = QFileDialog::getOpenFileName(this, "Load deformation", folder(), "Deformation (*.json)");
    gui::remember_folder(f);
    if (!f.isEmpty()) load_deformation(f);
  });
  add(file, "Load &controls...", QKeySequence("Ctrl+Shift+L"), [this, folder] {
    const QString f =
        QFileDialog::getOpenFileName(this, "Load controls", folder(), "Controls (*.controls *.txt);;All files (*)");
    gui::remember_folder(f);
    if (!f.isEmpty()) load_controls(f);
  });
  file->addSeparator();
  const auto save_as = [this, folder] {
    const QString start = deformation_path_.isEmpty() ? folder() + "/deformation.json" : deformation_path_;
    const QString f = QFileDialog::getSaveFileName(this, "Save deformation", start, "Deformation (*.json)");
    gui::remember_folder(f);
    return !f.isEmpty() && save_deformation(f);
  };
  add(file, "&Save deformation", QKeySequence::Save, [this, save_as] {
    if (deformation_path_.isEmpty())
      save_as();
    else
      save_deformation(deformation_path_);
  });
  add(file, "Save deformation &as...", QKeySequence("Ctrl+Shift+S"), save_as);
  add(file, "Save con&trols...", QKeySequence("Ctrl+Alt+S"), [this, folder] {
    const QString f = QFileDialog::getSaveFileName(this, "Save controls", folder() + "/deformation.controls",
                                                   "Controls (*.controls)");
    gui::remember_folder(f);
    if (!f.isEmpty()) save_controls(f);
  });
  add(file, "&Export deformed mesh...", QKeySequence("Ctrl+E"), [this, folder] {
    const QString f = QFileDialog::getSaveFileName(this, "Export deformed mesh", folder() + "/deformed.obj",
                                                   "Meshes (*.obj *.ply *.off *.stl *.glb *.gltf *.xyz)");
    gui::remember_folder(f);
    if (!f.isEmpty()) export_mesh(f);
  });
  file->addSeparator();
  add(file, "&Quit", QKeySequence::Quit, [this] { close(); });

  auto* editm = menuBar()->addMenu("&Edit");
  gui::add_undo_actions(editm, undo_, this);
  editm->addSeparator();
  add(editm, "&Delete control", QKeySequence::Delete, [this] { delete_selected(); });
  add(editm, "Select &none", QKeySequence("Esc"), [this] { select(-1); });
  add(editm, "&Whole mesh (clear active area)", QKeySequence("Ctrl+Shift+A"), [this] {
    State next = doc_.state();
    next.region.clear();
    edit(next, "Whole mesh");
  });

  auto* viewm = menuBar()->addMenu("&View");
  add(viewm, "&Reset camera (front, fit)", QKeySequence("R"), [this] { reset_camera(); });
  add(viewm, "&Frame all", QKeySequence("Home"), [this] { frame_all(); });  // as Blender's View All
  gui::add_view_actions(viewm, this, [this](gui::View v) { reset_camera(v); });
  viewm->addSeparator();
  QAction* supports =
      add(viewm, "&Support spheres", QKeySequence("S"), [this](bool on) { show_supports_->setChecked(on); });
  supports->setCheckable(true);
  connect(show_supports_, &QCheckBox::toggled, supports, &QAction::setChecked);
  QAction* colours = add(viewm, "Colour by &displacement", QKeySequence("D"),
                         [this](bool on) { colour_displacement_->setChecked(on); });
  colours->setCheckable(true);
  connect(colour_displacement_, &QCheckBox::toggled, colours, &QAction::setChecked);
  wireframe_ = add(viewm, "&Wireframe", QKeySequence("W"), [this] { refresh_view(); });
  wireframe_->setObjectName("wireframe");
  wireframe_->setCheckable(true);

  auto* help = menuBar()->addMenu("&Help");
  add(help, "&Mouse and keys", QKeySequence::HelpContents, [this] {
    gui::show_reference(this, "csrbf Picker: mouse and keys", R"(
<h3>Mouse in the 3D view</h3>
<table cellpadding=3>
<tr><td><b>Left click</b> on the mesh</td><td>add a control vector there</td></tr>
<tr><td><b>Shift + left click</b></td><td>add a pinned point (holds the mesh in place; black)</td></tr>
<tr><td><b>Left drag</b> on a handle</td><td>move the control's destination (orange), in the plane facing you</td></tr>
<tr><td><b>Ctrl + left drag</b></td><td>select the active area: only the vertices in the rectangle move</td></tr>
<tr><td><b>Left drag</b> elsewhere</td><td>orbit</td></tr>
<tr><td><b>Middle drag</b> or <b>shift + left drag</b></td><td>pan</td></tr>
<tr><td><b>Wheel</b> or <b>right drag</b></td><td>zoom</td></tr>
</table>
<h3>Keys</h3>
<table cellpadding=3>
<tr><td>Ctrl+O / Ctrl+L / Ctrl+Shift+L</td><td>open a mesh / load a deformation / load controls</td></tr>
<tr><td>Ctrl+S / Ctrl+Shift+S</td><td>save the deformation / save it as</td></tr>
<tr><td>Ctrl+Alt+S / Ctrl+E</td><td>save controls / export the deformed mesh</td></tr>
<tr><td>Ctrl+Z / Ctrl+Shift+Z, Ctrl+Y</td><td>undo / redo</td></tr>
<tr><td>Delete / Esc</td><td>delete the selected control / select none</td></tr>
<tr><td>Ctrl+Shift+A</td><td>whole mesh (clear the active area)</td></tr>
<tr><td>R</td><td>reset the camera: front view, mesh fitted</td></tr>
<tr><td>1 / 3 / 7 (number row or keypad)</td><td>front / side / top view</td></tr>
<tr><td>S / D / W</td><td>support spheres / colour by displacement / wireframe</td></tr>
<tr><td>F1</td><td>this reference</td></tr>
</table>
<p>Colours: sources green, destinations orange, pinned points black, the selected control yellow,
folded places magenta, vertices outside the active area grey.</p>)");
  });
}

bool PickerWindow::open_mesh(const QString& path) {
  try {
    doc_.load_mesh(path.toStdString());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  undo_.clear();
  selected_ = -1;
  area_from_file_ = false;
  vtkNew<vtkCellArray> polys;
  for (const auto& f : doc_.mesh().faces()) {
    polys->InsertNextCell(vtkIdType(f.size()));
    for (const auto v : f) polys->InsertCellPoint(vtkIdType(v));
  }
  mesh_->SetPolys(polys);
  clear_error();
  proposal_.clear();
  deformation_path_.clear();
  setWindowTitle(QFileInfo(path).fileName() + "[*] - csrbf Picker");
  setWindowModified(false);
  timing_->clear();  // the last mesh's
  statusBar()->showMessage(QString("%1: %2 vertices, %3 polygons")
                               .arg(QFileInfo(path).fileName())
                               .arg(doc_.rest().size())
                               .arg(doc_.mesh().faces().size()));
  refresh();
  reset_camera();
  return true;
}

bool PickerWindow::load_deformation(const QString& path) {
  if (!doc_.has_mesh()) {
    show_error("Open a mesh before loading a deformation");
    return false;
  }
  try {
    const auto spec = io::read_deformation(path.toStdString());
    if (!edit(doc_.state_from(spec, path.toStdString()), "Load deformation")) return false;
    area_from_file_ = spec.area.has_value();
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  deformation_path_ = path;
  undo_.setClean();  // what is shown is what the file holds (undo still goes back)
  statusBar()->showMessage("Loaded " + path, 5000);
  return true;
}

bool PickerWindow::load_controls(const QString& path, std::optional<double> radius) {
  if (!doc_.has_mesh()) {
    show_error("Open a mesh before loading controls");
    return false;
  }
  QString proposal, area_note;
  try {
    const auto c = io::read_controls(path.toStdString());
    io::DeformationSpec spec = doc_.deformation();
    spec.sources = c.sources;
    spec.destinations = c.destinations;
    // An area picked here stays (controls loaded to act inside it); one that came with the last
    // deformation file, or was saved into one, belongs to that file, and goes with it. The status
    // bar says which.
    area_note = !spec.area ? QString()
                : area_from_file_
                    ? QString("; the last file's active area was cleared")
                    : QString("; the active area picked here (%1 vertices) stays: \"Whole mesh\" drops it")
                          .arg(spec.area->vertices.size());
    if (area_from_file_) spec.area.reset();
    State next = doc_.state_from(spec);
    if (radius) {
      next.radius = *radius;
    } else {
      // A controls file carries no radius: the current one may fold the mesh or move nothing.
      next.radius = doc_.propose_radius(next);
      proposal = QString(
                     "Radius R = %1 (%2 % of the mesh's size) proposed for %3 controls from their spacing and "
                     "length. Change it in the panel.")
                     .arg(next.radius, 0, 'g', 4)
                     .arg(100.0 * next.radius / doc_.diagonal(), 0, 'g', 3)
                     .arg(next.controls.size());
    }
    if (!edit(next, "Load controls")) return false;
    area_from_file_ = false;
    const FoldReport folds = radius ? FoldReport{} : doc_.folds();
    if (!radius)
      proposal.replace(". Change it", folds.folded == 0 && folds.edge_flipped == 0
                                          ? QString("; the mesh does not fold at phase 1. Change it")
                                          : QString("; the mesh still folds even at the mesh's size. Change it"));
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  proposal_ = proposal;
  refresh_hints();
  statusBar()->showMessage(
      (proposal.isEmpty() ? "Loaded " + path
                          : QString("Radius R = %1 proposed (see the blue box)").arg(doc_.state().radius)) +
          area_note,
      10000);
  return true;
}

bool PickerWindow::save_deformation(const QString& path) {
  gui::commit_pending_edit();
  try {
    io::write_deformation(path.toStdString(), doc_.deformation());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  undo_.setClean();
  deformation_path_ = path;
  area_from_file_ = doc_.deformation().area.has_value();  // saved: the area is now that file's
  clear_error();
  statusBar()->showMessage("Saved " + path, 5000);
  return true;
}

bool PickerWindow::save_controls(const QString& path) {
  gui::commit_pending_edit();
  try {
    const auto d = doc_.deformation();
    io::write_controls(path.toStdString(), d.sources, d.destinations);
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  clear_error();
  statusBar()->showMessage("Saved " + path, 5000);
  return true;
}

bool PickerWindow::export_mesh(const QString& path) {
  gui::commit_pending_edit();
  if (!doc_.has_mesh()) {
    show_error("No mesh to export");
    return false;
  }
  try {
    doc_.export_mesh(path.toStdString());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  clear_error();
  statusBar()->showMessage("Exported " + path, 5000);
  return true;
}

bool PickerWindow::edit(const State& next, const QString& what, int merge_id) {
  if (!doc_.has_mesh()) return false;
  const State before = doc_.state();
  if (next == before) return true;
  const Outcome o = doc_.apply(next);
  if (!o.ok) {
    show_error(what + ": " + QString::fromStdString(o.error) + "\nThe last good state is kept.");
    refresh();  // widgets back to the kept state
    return false;
  }
  clear_error();
  proposal_.clear();
  statusBar()->clearMessage();  // a proposal or a file's figures, no longer what is shown
  undo_.push(new StateCommand(this, before, next, what, merge_id));
  refresh(&o);
  return true;
}

void PickerWindow::restore(const State& s) {
  const Outcome o = doc_.apply(s);
  if (!o.ok)
    show_error(QString::fromStdString(o.error));
  else
    clear_error();
  if (selected_ >= int(doc_.state().controls.size())) selected_ = -1;
  refresh(&o);
}

void PickerWindow::refresh(const Outcome* outcome) {
  refresh_options();
  refresh_table();
  refresh_view();
  const auto& s = doc_.state();
  if (outcome) {
    timing_->setText(
        QString("fit %1 ms, evaluation %2 ms").arg(outcome->fit_ms, 0, 'f', 3).arg(outcome->eval_ms, 0, 'f', 3));
  }
  refresh_hints();
  region_label_->setText(s.region.empty()
                             ? "Active area: whole mesh (ctrl + drag to select one)"
                             : QString("Active area: %1 of %2 vertices").arg(s.region.size()).arg(doc_.rest().size()));
}

void PickerWindow::dragEnterEvent(QDragEnterEvent* e) {
  if (e->mimeData()->hasUrls()) e->acceptProposedAction();
}

void PickerWindow::dropEvent(QDropEvent* e) {
  for (const QUrl& url : e->mimeData()->urls()) {
    const QString f = url.toLocalFile();
    if (f.endsWith(".json", Qt::CaseInsensitive))
      load_deformation(f);
    else if (f.endsWith(".controls", Qt::CaseInsensitive))
      load_controls(f);
    else if (maybe_save())
      open_mesh(f);
  }
}

bool PickerWindow::maybe_save() {
  gui::commit_pending_edit();
  if (undo_.isClean() || property("noPrompt").toBool()) return true;
  const auto answer = gui::ask_unsaved(this, "The deformation has unsaved changes.");
  if (answer == QMessageBox::Cancel) return false;
  if (answer == QMessageBox::Discard) return true;
  QString f = deformation_path_;
  if (f.isEmpty()) {
    f = QFileDialog::getSaveFileName(
        this, "Save deformation",
        gui::dialog_folder(QString::fromStdString(doc_.mesh_path().string())) + "/deformation.json",
        "Deformation (*.json)");
    gui::remember_folder(f);
  }
  return !f.isEmpty() && save_deformation(f);
}

void PickerWindow::closeEvent(QCloseEvent* e) {
  if (isVisible() && !maybe_save()) {
    e->ignore();
    return;
  }
  if (!property("noPrompt").toBool()) recovery_.remove();  // saved, or discarded on purpose
  e->accept();
}

}  // namespace csrbf::picker
