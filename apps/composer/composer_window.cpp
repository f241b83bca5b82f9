#include "composer_window.hpp"

#include "csrbf/render/movie.hpp"
#include "csrbf/render/scene_renderer.hpp"
#include "gui_common.hpp"

#include <QAction>
#include <QApplication>
#include <QCheckBox>
#include <QCloseEvent>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QInputDialog>
#include <QLabel>
#include <QListWidget>
#include <QMenuBar>
#include <QMessageBox>
#include <QMouseEvent>
#include <QPainter>
#include <QProgressDialog>
#include <QPushButton>
#include <QSlider>
#include <QStatusBar>
#include <QTimer>
#include <QUndoCommand>
#include <QVBoxLayout>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellData.h>
#include <vtkCellArray.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGlyph3D.h>
#include <vtkInteractorStyleTrackballCamera.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkRenderer.h>
#include <vtkSphereSource.h>
#include <vtkUnsignedCharArray.h>

#include <algorithm>
#include <cmath>

namespace csrbf::composer {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

// ---------------------------------------------------------------------------------------------------
// Mouse in the 3D view: left drag on a trajectory key moves it (in the plane through it facing the
// screen); left click on a key selects it; shift + left click adds a key at the current time under
// the cursor; ctrl + left drag turns the selected object (an orientation key at the current time);
// otherwise VTK's trackball camera (orbit, middle pan, wheel zoom).

class ComposerStyle : public vtkInteractorStyleTrackballCamera {
 public:
  static ComposerStyle* New();
  vtkTypeMacro(ComposerStyle, vtkInteractorStyleTrackballCamera)
  ComposerWindow* window = nullptr;

  void OnLeftButtonDown() override {
    const int* p = GetInteractor()->GetEventPosition();
    last_[0] = press_[0] = p[0];
    last_[1] = press_[1] = p[1];
    moved_ = false;
    rotating_ = GetInteractor()->GetControlKey() != 0 && window->selected_object() >= 0;
    shift_ = GetInteractor()->GetShiftKey() != 0;
    if (rotating_) {
      window->drag_start_ = window->doc_.json();
      return;
    }
    const int k = window->key_at(p[0], p[1]);
    if (k >= 0) {
      window->select_key(k);
      window->begin_key_drag(k);
      return;
    }
    if (shift_) return;
    vtkInteractorStyleTrackballCamera::OnLeftButtonDown();
  }
  void OnMouseMove() override {
    const int* p = GetInteractor()->GetEventPosition();
    if (std::abs(p[0] - press_[0]) + std::abs(p[1] - press_[1]) > 3) moved_ = true;
    if (window->dragging_ >= 0) {
      window->drag_key_to(p[0], p[1]);
      return;
    }
    if (rotating_) {
      window->rotate_by(0.5 * (p[0] - last_[0]), -0.5 * (p[1] - last_[1]));
      last_[0] = p[0];
      last_[1] = p[1];
      return;
    }
    vtkInteractorStyleTrackballCamera::OnMouseMove();
  }
  void OnLeftButtonUp() override {
    const int* p = GetInteractor()->GetEventPosition();
    if (window->dragging_ >= 0) {
      window->drag_key_to(p[0], p[1]);
      window->end_key_drag();
    } else if (rotating_) {
      window->end_key_drag();
      rotating_ = false;
    } else if (shift_ && !moved_) {
      window->add_key_at_display(p[0], p[1]);
    }
    vtkInteractorStyleTrackballCamera::OnLeftButtonUp();
  }

 private:
  int press_[2] = {0, 0}, last_[2] = {0, 0};
  bool moved_ = false, shift_ = false, rotating_ = false;
};
vtkStandardNewMacro(ComposerStyle);

/// One edit: the scene JSON before and after; the first redo() is the edit itself.
class JsonCommand : public QUndoCommand {
 public:
  JsonCommand(ComposerWindow* w, json before, json after, const QString& text)
      : QUndoCommand(text), w_(w), before_(std::move(before)), after_(std::move(after)) {}
  void undo() override { restore_(before_); }
  void redo() override {
    if (first_) {
      first_ = false;
      return;
    }
    restore_(after_);
  }

 private:
  void restore_(const json& j);
  ComposerWindow* w_;
  json before_, after_;
  bool first_ = true;
};

void JsonCommand::restore_(const json& j) { w_->restore(j); }

// ---------------------------------------------------------------------------------------------------

Timeline::Timeline(ComposerWindow* w) : QWidget(w), w_(w) {
  setObjectName("timeline");
  setMinimumHeight(110);
  setMouseTracking(false);
}

double Timeline::x_of(double t) const {
  const double d = w_->doc_.duration();
  return 60.0 + (width() - 75.0) * (d > 0 ? t / d : 0.0);
}

double Timeline::t_of(double x) const {
  const double d = w_->doc_.duration();
  return std::clamp((x - 60.0) / std::max(1.0, width() - 75.0) * d, 0.0, d);
}

void Timeline::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(45, 47, 52));
  p.setRenderHint(QPainter::Antialiasing);
  const double d = w_->doc_.duration();
  // Seconds ruler.
  p.setPen(QColor(120, 120, 130));
  for (int s = 0; s <= int(d); ++s) {
    const double x = x_of(s);
    p.drawLine(QPointF(x, 4), QPointF(x, height() - 4));
    p.drawText(QPointF(x + 2, height() - 4), QString::number(s) + "s");
  }
  const int o = w_->object_;
  if (o >= 0 && o < int(w_->doc_.object_count())) {
    std::vector<std::pair<QString, std::vector<double>>> rows;
    rows.push_back({"position", w_->doc_.key_times(std::size_t(o), Document::Track::Position)});
    rows.push_back({"rotation", w_->doc_.key_times(std::size_t(o), Document::Track::Orientation)});
    for (std::size_t k = 0; k < w_->doc_.deformation_count(std::size_t(o)); ++k)
      rows.push_back({"phase " + QString::number(k + 1), w_->doc_.key_times(std::size_t(o), Document::Track::Phase, k)});
    for (int r = 0; r < int(rows.size()); ++r) {
      const int y = y_of(r);
      p.setPen(QColor(200, 200, 210));
      p.drawText(QPointF(4, y + 4), rows[std::size_t(r)].first);
      const QColor colour = r == 0 ? QColor(255, 170, 60) : r == 1 ? QColor(90, 170, 255) : QColor(120, 220, 120);
      for (int k = 0; k < int(rows[std::size_t(r)].second.size()); ++k) {
        const double t = (r == drag_row_ && k == drag_key_) ? drag_time_ : rows[std::size_t(r)].second[std::size_t(k)];
        const bool sel = r == 0 && k == w_->key_;
        const double x = x_of(t);
        QPolygonF diamond({QPointF(x, y - 6), QPointF(x + 6, y), QPointF(x, y + 6), QPointF(x - 6, y)});
        p.setBrush(sel ? QColor(255, 240, 60) : colour);
        p.setPen(Qt::black);
        p.drawPolygon(diamond);
      }
    }
  }
  p.setPen(QPen(QColor(255, 80, 80), 2));
  const double x = x_of(w_->time_);
  p.drawLine(QPointF(x, 0), QPointF(x, height()));
}

void Timeline::mousePressEvent(QMouseEvent* e) {
  const int o = w_->object_;
  drag_row_ = drag_key_ = -1;
  if (o >= 0) {
    const std::size_t defs = w_->doc_.deformation_count(std::size_t(o));
    for (int r = 0; r < int(2 + defs) && drag_key_ < 0; ++r) {
      if (std::abs(e->pos().y() - y_of(r)) > 7) continue;
      const auto track = r == 0 ? Document::Track::Position : r == 1 ? Document::Track::Orientation : Document::Track::Phase;
      const auto times = w_->doc_.key_times(std::size_t(o), track, std::size_t(std::max(0, r - 2)));
      for (int k = 0; k < int(times.size()); ++k)
        if (std::abs(e->pos().x() - x_of(times[std::size_t(k)])) <= 7) {
          drag_row_ = r;
          drag_key_ = k;
          drag_time_ = times[std::size_t(k)];
          if (r == 0) w_->select_key(k);
          break;
        }
    }
  }
  if (drag_key_ < 0) w_->set_time(t_of(e->pos().x()));  // scrub
  update();
}

void Timeline::mouseMoveEvent(QMouseEvent* e) {
  if (drag_key_ >= 0) drag_time_ = t_of(e->pos().x());
  else w_->set_time(t_of(e->pos().x()));
  update();
}

void Timeline::mouseReleaseEvent(QMouseEvent* e) {
  if (drag_key_ >= 0) {
    const double t = std::round(t_of(e->pos().x()) * 100.0) / 100.0;  // timing marks snap to 0.01 s
    const int r = drag_row_, k = drag_key_;
    drag_row_ = drag_key_ = -1;
    const auto track = r == 0 ? Document::Track::Position : r == 1 ? Document::Track::Orientation : Document::Track::Phase;
    const std::size_t o = std::size_t(w_->object_);
    w_->edit("Move key in time", [&](Document& d) {
      d.set_key_time(o, track, std::size_t(std::max(0, r - 2)), std::size_t(k), t);
    });
  }
  update();
}

// ---------------------------------------------------------------------------------------------------

ComposerWindow::ComposerWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle("csrbf Animation Composer");
  build_ui();
  build_menus();
  timer_ = new QTimer(this);
  connect(timer_, &QTimer::timeout, this, [this] { tick(); });
  rebuild();
  undo_.setClean();
}

ComposerWindow::~ComposerWindow() {
  timer_->stop();
  if (scene_renderer_) window_->RemoveRenderer(scene_renderer_->renderer());
}

void ComposerWindow::build_ui() {
  view_ = new QVTKOpenGLNativeWidget(this);
  window_ = vtkSmartPointer<vtkGenericOpenGLRenderWindow>::New();
  view_->setRenderWindow(window_);
  style_ = vtkSmartPointer<ComposerStyle>::New();
  style_->window = this;
  window_->GetInteractor()->SetInteractorStyle(style_);

  // Overlays, added to each scene renderer: the trajectory (a polyline through samples of the
  // Kochanek-Bartels curve), key handles, and orientation marks along the path.
  curve_ = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPolyDataMapper> cm;
  cm->SetInputData(curve_);
  curve_actor_ = vtkSmartPointer<vtkActor>::New();
  curve_actor_->SetMapper(cm);
  curve_actor_->GetProperty()->SetColor(1.0, 0.75, 0.2);
  curve_actor_->GetProperty()->SetLineWidth(2);
  curve_actor_->PickableOff();
  handles_ = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkSphereSource> ball;
  vtkNew<vtkGlyph3D> glyph;
  glyph->SetInputData(handles_);
  glyph->SetSourceConnection(ball->GetOutputPort());
  glyph->SetScaleModeToDataScalingOff();
  glyph->SetScaleFactor(0.05);
  glyph->SetColorModeToColorByScalar();
  vtkNew<vtkPolyDataMapper> hm;
  hm->SetInputConnection(glyph->GetOutputPort());
  hm->SetColorModeToDirectScalars();
  handle_actor_ = vtkSmartPointer<vtkActor>::New();
  handle_actor_->SetMapper(hm);
  handle_actor_->PickableOff();
  frames_ = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPolyDataMapper> fm;
  fm->SetInputData(frames_);
  fm->SetColorModeToDirectScalars();
  frame_actor_ = vtkSmartPointer<vtkActor>::New();
  frame_actor_->SetMapper(fm);
  frame_actor_->GetProperty()->SetLineWidth(2);
  frame_actor_->PickableOff();

  auto* centre = new QWidget(this);
  auto* cl = new QVBoxLayout(centre);
  cl->setContentsMargins(0, 0, 0, 0);
  cl->addWidget(view_, 1);
  timeline_ = new Timeline(this);
  cl->addWidget(timeline_);
  auto* transport = new QHBoxLayout;
  play_ = new QPushButton("Play", centre);
  play_->setObjectName("play");
  play_->setCheckable(true);
  connect(play_, &QPushButton::toggled, this, [this](bool on) { play(on); });
  loop_ = new QCheckBox("Loop", centre);
  loop_->setObjectName("loop");
  loop_->setChecked(true);
  scrub_ = new QSlider(Qt::Horizontal, centre);
  scrub_->setObjectName("scrub");
  scrub_->setRange(0, 1000);
  connect(scrub_, &QSlider::valueChanged, this, [this](int v) {
    if (!updating_) set_time(doc_.duration() * v / 1000.0);
  });
  time_label_ = new QLabel(centre);
  rates_ = new QLabel(centre);
  rates_->setObjectName("rates");
  transport->addWidget(play_);
  transport->addWidget(loop_);
  transport->addWidget(scrub_, 1);
  transport->addWidget(time_label_);
  transport->addWidget(rates_);
  cl->addLayout(transport);
  setCentralWidget(centre);

  auto* dock = new QDockWidget("Scene", this);
  dock->setObjectName("scene");
  dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  auto* panel = new QWidget(dock);
  panel->setMinimumWidth(330);
  auto* layout = new QVBoxLayout(panel);
  objects_ = new QListWidget(panel);
  objects_->setObjectName("objects");
  connect(objects_, &QListWidget::currentRowChanged, this, [this](int r) {
    if (!updating_) select_object(r);
  });
  layout->addWidget(new QLabel("Objects", panel));
  layout->addWidget(objects_);
  auto* obj_buttons = new QHBoxLayout;
  auto* add_obj = new QPushButton("Add object...", panel);
  add_obj->setObjectName("addObject");
  connect(add_obj, &QPushButton::clicked, this, [this] {
    const QString f = QFileDialog::getOpenFileName(this, "Add object", {}, "Meshes (*.obj *.ply *.off *.stl *.glb *.gltf)");
    if (!f.isEmpty()) add_object(f);
  });
  auto* attach = new QPushButton("Attach deformation...", panel);
  attach->setObjectName("attach");
  connect(attach, &QPushButton::clicked, this, [this] {
    const QString f = QFileDialog::getOpenFileName(this, "Attach deformation", {}, "Deformation (*.json)");
    if (!f.isEmpty()) attach_deformation(f);
  });
  obj_buttons->addWidget(add_obj);
  obj_buttons->addWidget(attach);
  layout->addLayout(obj_buttons);

  auto* keybox = new QGroupBox("Trajectory key", panel);
  auto* kf = new QFormLayout(keybox);
  auto spin = [&](const char* name, double lo, double hi, double step, int decimals) {
    auto* s = new QDoubleSpinBox(keybox);
    s->setObjectName(name);
    s->setRange(lo, hi);
    s->setSingleStep(step);
    s->setDecimals(decimals);
    s->setKeyboardTracking(false);
    return s;
  };
  key_time_ = spin("keyTime", 0, 1e6, 0.1, 2);
  kf->addRow("time (s)", key_time_);
  connect(key_time_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double t) {
    if (updating_ || object_ < 0 || key_ < 0) return;
    edit("Key time", [&](Document& d) { d.set_key_time(std::size_t(object_), Document::Track::Position, 0, std::size_t(key_), t); });
  });
  auto* pos_row = new QHBoxLayout;
  for (int c = 0; c < 3; ++c) {
    key_pos_[c] = spin(c == 0 ? "keyX" : c == 1 ? "keyY" : "keyZ", -1e6, 1e6, 0.05, 3);
    pos_row->addWidget(key_pos_[c]);
    connect(key_pos_[c], qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this] {
      if (updating_ || object_ < 0 || key_ < 0) return;
      const Vec3 p(key_pos_[0]->value(), key_pos_[1]->value(), key_pos_[2]->value());
      edit("Key position", [&](Document& d) { d.set_position(std::size_t(object_), std::size_t(key_), p); });
    });
  }
  kf->addRow("position", pos_row);
  const char* tcb_names[3] = {"tension", "continuity", "bias"};
  for (int c = 0; c < 3; ++c) {
    tcb_[c] = spin(tcb_names[c], -1, 1, 0.1, 2);
    kf->addRow(tcb_names[c], tcb_[c]);
    connect(tcb_[c], qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this] {
      if (updating_ || object_ < 0 || key_ < 0) return;
      edit("Tension, continuity, bias", [&](Document& d) {
        d.set_tcb(std::size_t(object_), std::size_t(key_), tcb_[0]->value(), tcb_[1]->value(), tcb_[2]->value());
      });
    });
  }
  auto* key_buttons = new QHBoxLayout;
  auto* add_key = new QPushButton("Add key (K)", keybox);
  add_key->setObjectName("addKey");
  add_key->setToolTip("A trajectory key at the current time, where the object is now");
  connect(add_key, &QPushButton::clicked, this, [this] {
    if (object_ < 0) return;
    const Vec3 at = player_ ? anim::pose_at(scene_->objects[std::size_t(object_)], time_).position : Vec3::Zero();
    std::size_t k = 0;
    if (edit("Add trajectory key", [&](Document& d) { k = d.add_position_key(std::size_t(object_), time_, at); }))
      select_key(int(k));
  });
  auto* del_key = new QPushButton("Delete key", keybox);
  del_key->setObjectName("deleteKey");
  connect(del_key, &QPushButton::clicked, this, [this] {
    if (object_ < 0 || key_ < 0) return;
    const int k = key_;
    key_ = -1;
    edit("Delete trajectory key", [&](Document& d) { d.remove_position_key(std::size_t(object_), std::size_t(k)); });
  });
  key_buttons->addWidget(add_key);
  key_buttons->addWidget(del_key);
  kf->addRow(key_buttons);
  layout->addWidget(keybox);

  auto* rotbox = new QGroupBox("Orientation at the current time", panel);
  auto* rf = new QFormLayout(rotbox);
  const char* angle_names[3] = {"yaw", "pitch", "roll"};
  for (int c = 0; c < 3; ++c) {
    angles_[c] = spin(angle_names[c], -360, 360, 5, 1);
    rf->addRow(QString(angle_names[c]) + " (deg)", angles_[c]);
  }
  auto* set_rot = new QPushButton("Set orientation key", rotbox);
  set_rot->setObjectName("setOrientation");
  connect(set_rot, &QPushButton::clicked, this, [this] {
    if (object_ < 0) return;
    edit("Orientation key", [&](Document& d) {
      d.set_orientation_key(std::size_t(object_), time_, angles_[0]->value(), angles_[1]->value(), angles_[2]->value());
    });
  });
  rf->addRow(set_rot);
  layout->addWidget(rotbox);

  auto* scenebox = new QGroupBox("Scene", panel);
  auto* sf = new QFormLayout(scenebox);
  duration_ = spin("duration", 0.1, 3600, 0.5, 2);
  fps_ = spin("fps", 1, 240, 1, 1);
  sf->addRow("duration (s)", duration_);
  sf->addRow("frame rate", fps_);
  connect(duration_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    if (!updating_) edit("Duration", [&](Document& d) { d.set_duration(v); });
  });
  connect(fps_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    if (!updating_) edit("Frame rate", [&](Document& d) { d.set_fps(v); });
  });
  layout->addWidget(scenebox);

  error_ = gui::make_error_label(panel);
  layout->addWidget(error_);
  layout->addStretch(1);
  dock->setWidget(panel);
  addDockWidget(Qt::RightDockWidgetArea, dock);
}

void ComposerWindow::build_menus() {
  auto add = [this](QMenu* m, const QString& text, const QKeySequence& key, auto fn) {
    QAction* a = m->addAction(text);
    a->setShortcut(key);
    connect(a, &QAction::triggered, this, fn);
    return a;
  };
  auto* file = menuBar()->addMenu("&File");
  add(file, "&New scene", QKeySequence::New, [this] {
    if (maybe_save()) new_scene();
  });
  add(file, "&Open scene...", QKeySequence::Open, [this] {
    if (!maybe_save()) return;
    const QString f = QFileDialog::getOpenFileName(this, "Open scene", {}, "Scenes (*.json)");
    if (!f.isEmpty()) open_scene(f);
  });
  add(file, "&Save scene", QKeySequence::Save, [this] {
    QString f = QString::fromStdString(doc_.path().string());
    if (f.isEmpty()) f = QFileDialog::getSaveFileName(this, "Save scene", "scene.json", "Scenes (*.json)");
    if (!f.isEmpty()) save_scene(f);
  });
  add(file, "Save scene &as...", QKeySequence::SaveAs, [this] {
    const QString f = QFileDialog::getSaveFileName(this, "Save scene", "scene.json", "Scenes (*.json)");
    if (!f.isEmpty()) save_scene(f);
  });
  add(file, "&Export movie...", QKeySequence("Ctrl+E"), [this] {
    const QString f = QFileDialog::getSaveFileName(this, "Export movie", "movie.mp4", "Movies (*.mp4 *.avi)");
    if (f.isEmpty()) return;
    bool ok = false;
    const QString size = QInputDialog::getText(this, "Export movie", "Frame size (WIDTHxHEIGHT):", QLineEdit::Normal,
                                               "640x480", &ok);
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
  add(editm, "&Delete trajectory key", QKeySequence::Delete, [this] { findChild<QPushButton*>("deleteKey")->click(); });

  auto* playm = menuBar()->addMenu("&Animation");
  add(playm, "&Play / pause", QKeySequence("Space"), [this] { play_->toggle(); });
  add(playm, "To the &start", QKeySequence("Home"), [this] { set_time(0); });
  add(playm, "&Reset camera", QKeySequence("R"), [this] {
    if (scene_renderer_) scene_renderer_->renderer()->ResetCamera();
    view_->renderWindow()->Render();
  });
}

// ---------------------------------------------------------------------------------------------------

bool ComposerWindow::new_scene() {
  play(false);
  doc_.reset(std::filesystem::current_path());
  undo_.clear();
  object_ = key_ = -1;
  time_ = 0;
  scene_.reset();
  rebuild();
  undo_.setClean();
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
  key_ = -1;
  time_ = 0;
  clear_error();
  scene_.reset();
  rebuild();
  if (scene_renderer_) {
    const auto& c = scene_->camera;
    vtkCamera* cam = scene_renderer_->renderer()->GetActiveCamera();
    cam->SetPosition(c.position.data());
    cam->SetFocalPoint(c.focal_point.data());
    cam->SetViewUp(c.view_up.data());
    cam->SetViewAngle(c.view_angle);
  }
  show_frame();
  undo_.setClean();
  setWindowTitle("csrbf Animation Composer - " + QFileInfo(path).fileName());
  return true;
}

bool ComposerWindow::save_scene(const QString& path) {
  try {
    doc_.save(path.toStdString());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  undo_.setClean();
  setWindowTitle("csrbf Animation Composer - " + QFileInfo(path).fileName());
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
  return edit("Attach deformation", [&](Document& d) { d.attach_deformation(std::size_t(object_), file.toStdString()); });
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
  doc_ = std::move(next);
  clear_error();
  undo_.push(new JsonCommand(this, before, doc_.json(), what));
  scene_ = std::move(scene);
  rebuild();
  return true;
}

void ComposerWindow::restore(const json& j) {
  doc_.set_json(j);
  if (object_ >= int(doc_.object_count())) object_ = int(doc_.object_count()) - 1;
  key_ = -1;
  clear_error();
  scene_.reset();
  rebuild();
}

QString ComposerWindow::error_text() const { return error_->isHidden() ? QString() : error_->text(); }

void ComposerWindow::show_error(const QString& m) {
  error_->setText(m);
  error_->show();
  statusBar()->showMessage(m.section('\n', 0, 0), 10000);
}

void ComposerWindow::clear_error() {
  error_->clear();
  error_->hide();
}

void ComposerWindow::rebuild() {
  if (!scene_) {
    try {
      scene_ = std::make_unique<anim::Scene>(doc_.build());
    } catch (const std::exception& e) {
      show_error(e.what());
      scene_ = std::make_unique<anim::Scene>();
    }
  }
  timeline_->setMinimumHeight(timeline_->y_of(int(2 + (object_ >= 0 ? doc_.deformation_count(std::size_t(object_)) : 0))) + 14);
  // Keep the camera across rebuilds (the scene file's camera is used when a scene is opened).
  vtkNew<vtkCamera> camera;
  const bool had = scene_renderer_ != nullptr;
  if (had) {
    camera->DeepCopy(scene_renderer_->renderer()->GetActiveCamera());
    window_->RemoveRenderer(scene_renderer_->renderer());
  }
  player_.reset();
  scene_renderer_.reset();
  player_ = std::make_unique<anim::Player>(*scene_);
  scene_renderer_ = std::make_unique<render::SceneRenderer>(*scene_);
  vtkRenderer* r = scene_renderer_->renderer();
  r->AddActor(curve_actor_);
  r->AddActor(handle_actor_);
  r->AddActor(frame_actor_);
  if (had) r->GetActiveCamera()->DeepCopy(camera);
  window_->AddRenderer(r);
  updating_ = true;
  objects_->clear();
  for (std::size_t i = 0; i < doc_.object_count(); ++i) objects_->addItem(QString::fromStdString(doc_.object_name(i)));
  if (object_ >= 0) objects_->setCurrentRow(object_);
  updating_ = false;
  time_ = std::clamp(time_, 0.0, doc_.duration());
  refresh_panel();
  refresh_overlays();
  show_frame();
}

void ComposerWindow::show_frame() {
  if (!player_) return;
  auto t0 = Clock::now();
  player_->evaluate(time_);
  compute_s_ += std::chrono::duration<double>(Clock::now() - t0).count();
  t0 = Clock::now();
  scene_renderer_->update(*player_);
  view_->renderWindow()->Render();
  render_s_ += std::chrono::duration<double>(Clock::now() - t0).count();
  ++rate_frames_;
  ++frames_shown_;
  updating_ = true;
  scrub_->setValue(int(std::lround(1000.0 * time_ / doc_.duration())));
  updating_ = false;
  time_label_->setText(QString("t = %1 s").arg(time_, 0, 'f', 2));
  timeline_->update();
}

void ComposerWindow::refresh_panel() {
  updating_ = true;
  duration_->setValue(doc_.duration());
  fps_->setValue(doc_.fps());
  const bool has_key = object_ >= 0 && key_ >= 0 && scene_ && std::size_t(object_) < scene_->objects.size() &&
                       scene_->objects[std::size_t(object_)].trajectory &&
                       std::size_t(key_) < scene_->objects[std::size_t(object_)].trajectory->keys().size();
  for (QDoubleSpinBox* s : {key_time_, key_pos_[0], key_pos_[1], key_pos_[2], tcb_[0], tcb_[1], tcb_[2]}) s->setEnabled(has_key);
  if (has_key) {
    const auto& k = scene_->objects[std::size_t(object_)].trajectory->keys()[std::size_t(key_)];
    key_time_->setValue(k.time);
    for (int c = 0; c < 3; ++c) key_pos_[c]->setValue(k.position[c]);
    tcb_[0]->setValue(k.tension);
    tcb_[1]->setValue(k.continuity);
    tcb_[2]->setValue(k.bias);
  }
  if (object_ >= 0 && scene_ && std::size_t(object_) < scene_->objects.size()) {
    const Vec3 a = angles_from_quaternion(scene_->objects[std::size_t(object_)].orientation.rotation(time_));
    for (int c = 0; c < 3; ++c) angles_[c]->setValue(a[c]);
  }
  updating_ = false;
  timeline_->update();
}

void ComposerWindow::refresh_overlays() {
  vtkNew<vtkPoints> cp, hp, fp;
  vtkNew<vtkCellArray> cl, fl;
  vtkNew<vtkUnsignedCharArray> hc, fc;
  hc->SetNumberOfComponents(3);
  fc->SetNumberOfComponents(3);
  double size = 0.05;
  if (scene_) {
    for (std::size_t o = 0; o < scene_->objects.size(); ++o) {
      const auto& obj = scene_->objects[o];
      if (!obj.trajectory) continue;
      const auto& keys = obj.trajectory->keys();
      // The curve, sampled 40 times a segment.
      const double t0 = keys.front().time, t1 = keys.back().time;
      const int n = std::max(2, 40 * int(keys.size()));
      std::vector<vtkIdType> ids;
      for (int s = 0; s < n; ++s) ids.push_back(cp->InsertNextPoint(obj.trajectory->position(t0 + (t1 - t0) * s / (n - 1)).data()));
      cl->InsertNextCell(vtkIdType(ids.size()), ids.data());
      for (std::size_t k = 0; k < keys.size(); ++k) {
        hp->InsertNextPoint(keys[k].position.data());
        if (int(o) == object_ && int(k) == key_) hc->InsertNextTuple3(255, 240, 60);
        else if (int(o) == object_) hc->InsertNextTuple3(255, 150, 40);
        else hc->InsertNextTuple3(150, 110, 80);
      }
      // Orientation along the path: the object's x (red), y (green), z (blue) axes at 12 times.
      if (int(o) != object_) continue;
      Vec3 lo = obj.rest.front(), hi = obj.rest.front();
      for (const auto& p : obj.rest) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      size = std::max(0.01, 0.04 * (hi - lo).norm());
      for (int s = 0; s <= 12; ++s) {
        const double t = t0 + (t1 - t0) * s / 12.0;
        const anim::Pose pose = anim::pose_at(obj, t);
        for (int a = 0; a < 3; ++a) {
          const vtkIdType i0 = fp->InsertNextPoint(pose.position.data());
          const Vec3 tip = pose.position + pose.rotation * (Vec3::Unit(a) * 4 * size);
          const vtkIdType i1 = fp->InsertNextPoint(tip.data());
          const vtkIdType seg[2] = {i0, i1};
          fl->InsertNextCell(2, seg);
          fc->InsertNextTuple3(a == 0 ? 230 : 40, a == 1 ? 200 : 40, a == 2 ? 255 : 40);
        }
      }
    }
  }
  curve_->SetPoints(cp);
  curve_->SetLines(cl);
  handles_->SetPoints(hp);
  handles_->GetPointData()->SetScalars(hc);
  frames_->SetPoints(fp);
  frames_->SetLines(fl);
  frames_->GetCellData()->SetScalars(fc);
  static_cast<vtkGlyph3D*>(handle_actor_->GetMapper()->GetInputAlgorithm())->SetScaleFactor(2 * size);
  curve_->Modified();
  handles_->Modified();
  frames_->Modified();
}

void ComposerWindow::select_object(int i) {
  object_ = i >= 0 && i < int(doc_.object_count()) ? i : -1;
  key_ = -1;
  updating_ = true;
  objects_->setCurrentRow(object_);
  updating_ = false;
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
}

void ComposerWindow::select_key(int key) {
  key_ = key;
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
}

void ComposerWindow::set_time(double t) {
  time_ = std::clamp(t, 0.0, doc_.duration());
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
  } else if (!on) {
    timer_->stop();
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
  if (rate_frames_ > 0 && compute_s_ > 0 && render_s_ > 0)
    rates_->setText(QString("computed %1 fps, rendered %2 fps")
                        .arg(double(rate_frames_) / compute_s_, 0, 'f', 0)
                        .arg(double(rate_frames_) / render_s_, 0, 'f', 0));
}

bool ComposerWindow::export_movie(const QString& path, int width, int height) {
  play(false);
  if (!scene_ || scene_->objects.empty()) {
    show_error("The scene has no objects to render");
    return false;
  }
  QProgressDialog progress("Rendering " + QFileInfo(path).fileName() + "...", "Cancel", 0,
                           int(scene_->frame_count(0, scene_->duration)), this);
  progress.setWindowModality(Qt::WindowModal);
  progress.setMinimumDuration(0);
  try {
    render::MovieOptions o;
    o.width = width;
    o.height = height;
    const auto stats = render::render_movie(*scene_, path.toStdString(), o, [&](std::size_t done, std::size_t) {
      progress.setValue(int(done));
      QApplication::processEvents();
      return !progress.wasCanceled();
    });
    if (stats.cancelled) {
      statusBar()->showMessage("Export cancelled; nothing was written", 5000);
      return false;
    }
    statusBar()->showMessage(QString("Wrote %1: %2 frames, computation %3 ms, rendering %4 ms a frame")
                                 .arg(path)
                                 .arg(stats.frames)
                                 .arg(1e3 * stats.compute_seconds / double(stats.frames), 0, 'f', 3)
                                 .arg(1e3 * stats.render_seconds / double(stats.frames), 0, 'f', 1),
                             10000);
  } catch (const std::exception& e) {
    show_error(QString("Export: ") + e.what());
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------------

QPointF ComposerWindow::to_display(const Vec3& w) const {
  const Vec3 d = gui::world_to_display(scene_renderer_->renderer(), w);
  return {d.x(), d.y()};
}

Vec3 ComposerWindow::key_position(int k) const {
  return scene_->objects.at(std::size_t(object_)).trajectory->keys().at(std::size_t(k)).position;
}

int ComposerWindow::key_at(int x, int y) const {
  if (object_ < 0 || !scene_ || !scene_->objects[std::size_t(object_)].trajectory) return -1;
  const auto& keys = scene_->objects[std::size_t(object_)].trajectory->keys();
  int best = -1;
  double best_d = 10.0;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const QPointF d = to_display(keys[k].position);
    const double dist = std::hypot(d.x() - x, d.y() - y);
    if (dist < best_d) {
      best_d = dist;
      best = int(k);
    }
  }
  return best;
}

void ComposerWindow::begin_key_drag(int key) {
  dragging_ = key;
  drag_start_ = doc_.json();
  drag_depth_ = gui::world_to_display(scene_renderer_->renderer(), key_position(key)).z();
}

void ComposerWindow::drag_key_to(int x, int y) {
  const auto p = gui::display_to_world(scene_renderer_->renderer(), x, y, drag_depth_);
  if (!p) return;
  live_edit([&](Document& d) { d.set_position(std::size_t(object_), std::size_t(dragging_), *p); });
}

void ComposerWindow::live_edit(const std::function<void(Document&)>& change) {
  // While dragging: the document and the scene follow the mouse; one undo step at the end.
  Document next = doc_;
  try {
    change(next);
    auto scene = std::make_unique<anim::Scene>(next.build());
    doc_ = std::move(next);
    scene_ = std::move(scene);
  } catch (const std::exception& e) {
    show_error(e.what());
    return;
  }
  rebuild();
}

void ComposerWindow::end_key_drag() {
  dragging_ = -1;
  if (doc_.json() == drag_start_) return;
  undo_.push(new JsonCommand(this, drag_start_, doc_.json(), "Move trajectory key"));
}

void ComposerWindow::add_key_at_display(int x, int y) {
  if (object_ < 0) return;
  // On the plane through the object's current position, facing the screen.
  const Vec3 here = anim::pose_at(scene_->objects[std::size_t(object_)], time_).position;
  vtkRenderer* r = scene_renderer_->renderer();
  const auto p = gui::display_to_world(r, x, y, gui::world_to_display(r, here).z());
  if (!p) return;
  std::size_t k = 0;
  if (edit("Add trajectory key", [&](Document& d) { k = d.add_position_key(std::size_t(object_), time_, *p); }))
    select_key(int(k));
}

void ComposerWindow::rotate_by(double dyaw, double dpitch) {
  if (object_ < 0) return;
  const Vec3 a = angles_from_quaternion(scene_->objects[std::size_t(object_)].orientation.rotation(time_));
  live_edit([&](Document& d) { d.set_orientation_key(std::size_t(object_), time_, a[0] + dyaw, a[1] + dpitch, a[2]); });
}

bool ComposerWindow::save_screenshot(const QString& path) { return gui::save_window_png(this, view_, path); }

bool ComposerWindow::maybe_save() {
  if (undo_.isClean() || property("noPrompt").toBool()) return true;
  const auto answer = QMessageBox::question(this, "csrbf Animation Composer", "The scene has unsaved changes. Save them?",
                                            QMessageBox::Save | QMessageBox::Discard | QMessageBox::Cancel,
                                            QMessageBox::Save);
  if (answer == QMessageBox::Cancel) return false;
  if (answer == QMessageBox::Discard) return true;
  QString f = QString::fromStdString(doc_.path().string());
  if (f.isEmpty()) f = QFileDialog::getSaveFileName(this, "Save scene", "scene.json", "Scenes (*.json)");
  return !f.isEmpty() && save_scene(f);
}

void ComposerWindow::closeEvent(QCloseEvent* e) {
  play(false);
  if (maybe_save()) e->accept();
  else e->ignore();
}

}  // namespace csrbf::composer
