#include "composer_window.hpp"

#include "csrbf/render/movie.hpp"
#include "csrbf/render/scene_renderer.hpp"
#include "gui_common.hpp"

#include <QAction>
#include <QApplication>
#include <QCheckBox>
#include <QColorDialog>
#include <QComboBox>
#include <QLineEdit>
#include <QScrollArea>
#include <QScrollBar>
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
#include <vtkCameraActor.h>
#include <vtkActorCollection.h>
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
  vtkTypeMacro(ComposerStyle, vtkInteractorStyleTrackballCamera) ComposerWindow* window = nullptr;

  // VTK's own keys (w wireframe, 3 stereo, e/q quit, ...) are off: the menus hold every key.
  void OnChar() override {}

  void OnLeftButtonDown() override {
    const int* p = GetInteractor()->GetEventPosition();
    last_[0] = press_[0] = p[0];
    last_[1] = press_[1] = p[1];
    moved_ = false;
    rotating_ = GetInteractor()->GetControlKey() != 0 && window->has_object();
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
      if (moved_) window->drag_key_to(p[0], p[1]);  // a click that stays put does not move the key
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
      if (moved_) window->drag_key_to(p[0], p[1]);
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
  /// `base`: the folder the two states' relative paths were written for (the document's then).
  JsonCommand(ComposerWindow* w, json before, json after, std::filesystem::path base, const QString& text)
      : QUndoCommand(text), w_(w), before_(std::move(before)), after_(std::move(after)), base_(std::move(base)) {}
  void undo() override { w_->restore(before_, base_); }
  void redo() override {
    if (first_) {
      first_ = false;
      return;
    }
    w_->restore(after_, base_);
  }

 private:
  ComposerWindow* w_;
  json before_, after_;
  std::filesystem::path base_;
  bool first_ = true;
};

// ---------------------------------------------------------------------------------------------------

Timeline::Timeline(ComposerWindow* w) : QWidget(w), w_(w) {
  setObjectName("timeline");
  setMinimumHeight(needed_height());
  setMouseTracking(false);
}

namespace {
constexpr double kLeft = 96.0, kRight = 22.0;  // room for row names, and for the last second's label

Document::Track track_of(int row) {
  return row == 0 ? Document::Track::Position : row == 1 ? Document::Track::Orientation : Document::Track::Phase;
}
}  // namespace

double Timeline::x_of(double t) const {
  const double d = w_->doc_.duration();
  return kLeft + (width() - kLeft - kRight) * (d > 0 ? t / d : 0.0);
}

double Timeline::t_of(double x) const {
  const double d = w_->doc_.duration();
  return std::clamp((x - kLeft) / std::max(1.0, width() - kLeft - kRight) * d, 0.0, d);
}

int Timeline::needed_height() const {
  const int o = w_->object_;
  const std::size_t defs = o >= 0 && o < int(w_->doc_.object_count()) ? w_->doc_.deformation_count(std::size_t(o)) : 0;
  return y_of(int(2 + defs)) + 4;
}

double Timeline::drag_limit(int row, int key, double x) const {
  const auto times = w_->doc_.key_times(std::size_t(w_->object_), track_of(row), std::size_t(std::max(0, row - 2)));
  const double frame = 1.0 / w_->doc_.fps();
  double t = w_->doc_.snap(t_of(x));
  if (key > 0) t = std::max(t, w_->doc_.snap(times[std::size_t(key) - 1]) + frame);
  if (key + 1 < int(times.size())) t = std::min(t, w_->doc_.snap(times[std::size_t(key) + 1]) - frame);
  return std::max(t, 0.0);
}

void Timeline::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(45, 47, 52));
  p.setRenderHint(QPainter::Antialiasing);
  const double d = w_->doc_.duration();
  // Seconds ruler: a line a second, its label centred above it.
  p.setPen(QColor(120, 120, 130));
  const QFontMetrics fm(font());
  for (int s = 0; s <= int(d + 1e-9); ++s) {
    const double x = x_of(s);
    p.drawLine(QPointF(x, 16), QPointF(x, height()));
  }
  const int o = w_->object_;
  if (o >= 0 && o < int(w_->doc_.object_count())) {
    std::vector<std::pair<QString, std::vector<double>>> rows;
    rows.push_back({"position", w_->doc_.key_times(std::size_t(o), Document::Track::Position)});
    rows.push_back({"rotation", w_->doc_.key_times(std::size_t(o), Document::Track::Orientation)});
    for (std::size_t k = 0; k < w_->doc_.deformation_count(std::size_t(o)); ++k)
      rows.push_back({QString::fromStdString(w_->doc_.deformation_name(std::size_t(o), k)),
                      w_->doc_.key_times(std::size_t(o), Document::Track::Phase, k)});
    for (int r = 0; r < int(rows.size()); ++r) {
      const int y = y_of(r);
      p.setPen(r >= 2 && r - 2 == w_->deformation_ ? QColor(255, 240, 120) : QColor(200, 200, 210));
      p.drawText(QPointF(4, y + 4), fm.elidedText(rows[std::size_t(r)].first, Qt::ElideRight, int(kLeft) - 10));
      const QColor colour = r == 0 ? QColor(255, 170, 60) : r == 1 ? QColor(90, 170, 255) : QColor(120, 220, 120);
      for (int k = 0; k < int(rows[std::size_t(r)].second.size()); ++k) {
        const double t = (r == drag_row_ && k == drag_key_) ? drag_time_ : rows[std::size_t(r)].second[std::size_t(k)];
        const bool sel = (r == 0 && k == w_->key_) || (r >= 2 && r - 2 == w_->deformation_ && k == w_->phase_key_);
        const double x = x_of(t);
        QPolygonF diamond({QPointF(x, y - 6), QPointF(x + 6, y), QPointF(x, y + 6), QPointF(x - 6, y)});
        p.setBrush(sel ? QColor(255, 240, 60) : colour);
        p.setPen(Qt::black);
        p.drawPolygon(diamond);
      }
    }
  }
  // The labels in a band at the top of what the scroll area shows: in sight however the rows scroll.
  const int top = visibleRegion().boundingRect().top();
  p.fillRect(QRect(0, top, width(), 17), QColor(45, 47, 52));
  p.setPen(QColor(150, 150, 160));
  for (int s = 0; s <= int(d + 1e-9); ++s) {
    const QString label = QString::number(s) + "s";
    p.drawText(QPointF(x_of(s) - fm.horizontalAdvance(label) / 2.0, top + 13), label);
  }
  p.setPen(QPen(QColor(255, 80, 80), 2));
  const double x = x_of(w_->time_);
  p.drawLine(QPointF(x, 0), QPointF(x, height()));
}

void Timeline::mousePressEvent(QMouseEvent* e) {
  const int o = w_->object_;
  drag_row_ = drag_key_ = -1;
  if (o >= 0 && o < int(w_->doc_.object_count())) {
    const std::size_t defs = w_->doc_.deformation_count(std::size_t(o));
    for (int r = 0; r < int(2 + defs) && drag_key_ < 0; ++r) {
      if (std::abs(e->pos().y() - y_of(r)) > 7) continue;
      const auto times = w_->doc_.key_times(std::size_t(o), track_of(r), std::size_t(std::max(0, r - 2)));
      for (int k = 0; k < int(times.size()); ++k)
        if (std::abs(e->pos().x() - x_of(times[std::size_t(k)])) <= 7) {
          drag_row_ = r;
          drag_key_ = k;
          drag_time_ = times[std::size_t(k)];
          if (r == 0) w_->select_key(k);
          if (r >= 2) w_->select_phase_key(r - 2, k);
          break;
        }
      if (drag_key_ < 0 && r >= 2 && e->pos().x() < kLeft) w_->select_phase_key(r - 2, -1);  // the row's name
    }
  }
  if (drag_key_ < 0 && e->pos().x() >= kLeft) w_->set_time(t_of(e->pos().x()));  // scrub, on the ruler or between marks
  update();
}

void Timeline::mouseMoveEvent(QMouseEvent* e) {
  if (drag_key_ >= 0)
    drag_time_ = drag_limit(drag_row_, drag_key_, e->pos().x());
  else if (e->pos().x() >= kLeft)
    w_->set_time(t_of(e->pos().x()));
  update();
}

void Timeline::mouseReleaseEvent(QMouseEvent* e) {
  if (drag_key_ >= 0) {
    const int r = drag_row_, k = drag_key_;
    const double t = drag_limit(r, k, e->pos().x());
    drag_row_ = drag_key_ = -1;
    const std::size_t o = std::size_t(w_->object_);
    const auto times = w_->doc_.key_times(o, track_of(r), std::size_t(std::max(0, r - 2)));
    if (std::abs(times[std::size_t(k)] - t) > 1e-12)
      w_->edit("Move key in time", [&](Document& d) {
        d.set_key_time(o, track_of(r), std::size_t(std::max(0, r - 2)), std::size_t(k), t);
      });
  }
  update();
}

// ---------------------------------------------------------------------------------------------------

ComposerWindow::ComposerWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle("untitled[*] - csrbf Animation Composer");
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) { setWindowModified(!clean); });
  build_ui();
  build_menus();
  statusBar()->showMessage(
      "Open a scene (Ctrl+O), or add an object (Ctrl+Shift+A)");  // made now: a message later never resizes the view
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
  // The timeline scrolls inside a box of fixed height: a new deformation row never shrinks the view.
  timeline_ = new Timeline(this);
  timeline_scroll_ = new QScrollArea(centre);
  timeline_scroll_->setObjectName("timelineScroll");
  timeline_scroll_->setWidget(timeline_);
  timeline_scroll_->setWidgetResizable(true);
  timeline_scroll_->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  timeline_scroll_->setFixedHeight(timeline_->y_of(6) + 8);  // 4 deformation rows without scrolling
  // The ruler's band follows the scrolling (Qt would only repaint the newly shown strip).
  connect(timeline_scroll_->verticalScrollBar(), &QScrollBar::valueChanged, timeline_, [this] { timeline_->update(); });
  cl->addWidget(timeline_scroll_);
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

  // The scene camera's frame: its frustum from the camera to the focal plane, where the movie's
  // picture is (4:3, the default movie size).
  camera_actor_ = vtkSmartPointer<vtkCameraActor>::New();
  camera_actor_->SetWidthByHeightRatio(4.0 / 3.0);
  camera_actor_->GetProperty()->SetColor(0.3, 1.0, 0.8);
  camera_actor_->GetProperty()->SetAmbient(1.0);  // lines lit as surfaces turn black
  camera_actor_->GetProperty()->SetDiffuse(0.0);
  camera_actor_->GetProperty()->LightingOff();
  camera_actor_->GetProperty()->SetLineWidth(2);
  camera_actor_->PickableOff();

  auto* dock = new QDockWidget("Scene", this);
  dock->setObjectName("scene");
  dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  auto* dock_scroll = new QScrollArea(dock);
  dock_scroll->setWidgetResizable(true);
  dock_scroll->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  auto* panel = new QWidget(dock_scroll);
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
    const QString f = QFileDialog::getOpenFileName(this, "Add object",
                                                   gui::dialog_folder(QString::fromStdString(doc_.path().string())),
                                                   "Meshes (*.obj *.ply *.off *.stl *.glb *.gltf)");
    gui::remember_folder(f);
    if (!f.isEmpty()) add_object(f);
  });
  auto* attach = new QPushButton("Attach deformation...", panel);
  attach->setObjectName("attach");
  connect(attach, &QPushButton::clicked, this, [this] {
    if (!has_object()) {
      show_error("Select an object first (Object > Add object... makes one)");
      return;
    }
    const QString f = QFileDialog::getOpenFileName(this, "Attach deformation",
                                                   gui::dialog_folder(QString::fromStdString(doc_.path().string())),
                                                   "Deformation (*.json)");
    gui::remember_folder(f);
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
    edit("Key time", [&](Document& d) {
      d.set_key_time(std::size_t(object_), Document::Track::Position, 0, std::size_t(key_), d.snap(t));
    });
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
    if (!has_object()) return;
    const double t = doc_.snap(time_);
    const Vec3 at = anim::pose_at(scene_->objects[std::size_t(object_)], t).position;
    std::size_t k = 0;
    if (edit("Add trajectory key", [&](Document& d) { k = d.add_position_key(std::size_t(object_), t, at); }))
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
    if (!has_object()) return;
    edit("Orientation key", [&](Document& d) {
      d.set_orientation_key(std::size_t(object_), d.snap(time_), angles_[0]->value(), angles_[1]->value(),
                            angles_[2]->value());
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

  // Deformations of the selected object: name, schedule, how they combine.
  auto* defbox = new QGroupBox("Deformations", panel);
  auto* df = new QFormLayout(defbox);
  deformations_ = new QListWidget(defbox);
  deformations_->setObjectName("deformations");
  deformations_->setMaximumHeight(80);
  connect(deformations_, &QListWidget::currentRowChanged, this, [this](int r) {
    if (!updating_) select_phase_key(r, -1);
  });
  df->addRow(deformations_);
  def_name_ = new QLineEdit(defbox);
  def_name_->setObjectName("deformationName");
  connect(def_name_, &QLineEdit::editingFinished, this, [this] {
    if (updating_ || !has_object() || deformation_ < 0) return;
    const std::string name = def_name_->text().toStdString();
    if (name == doc_.deformation_name(std::size_t(object_), std::size_t(deformation_))) return;
    edit("Rename deformation",
         [&](Document& d) { d.set_deformation_name(std::size_t(object_), std::size_t(deformation_), name); });
  });
  df->addRow("name", def_name_);
  combine_ = new QComboBox(defbox);
  combine_->setObjectName("combine");
  combine_->addItems({"compose", "sum"});
  combine_->setToolTip("compose: each on the result of the one before; sum: displacements added (blend shapes)");
  connect(combine_, &QComboBox::currentTextChanged, this, [this](const QString& c) {
    if (updating_ || !has_object()) return;
    edit("Combine", [&](Document& d) { d.set_combine(std::size_t(object_), c.toStdString()); });
  });
  df->addRow("combine", combine_);
  easing_ = new QComboBox(defbox);
  easing_->setObjectName("easing");
  easing_->addItems({"smooth", "linear"});
  connect(easing_, &QComboBox::currentTextChanged, this, [this](const QString& e) {
    if (updating_ || !has_object() || deformation_ < 0) return;
    edit("Easing",
         [&](Document& d) { d.set_easing(std::size_t(object_), std::size_t(deformation_), e.toStdString()); });
  });
  df->addRow("easing", easing_);
  phase_time_ = spin("phaseTime", 0, 1e6, 0.04, 3);
  phase_value_ = spin("phaseValue", -1e6, 1e6, 0.1, 3);
  auto* phase_row = new QHBoxLayout;
  phase_row->addWidget(phase_time_);
  phase_row->addWidget(new QLabel("s  phase", defbox));
  phase_row->addWidget(phase_value_);
  df->addRow("key", phase_row);
  connect(phase_time_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double t) {
    if (updating_ || !has_object() || deformation_ < 0 || phase_key_ < 0) return;
    edit("Phase key time", [&](Document& d) {
      d.set_key_time(std::size_t(object_), Document::Track::Phase, std::size_t(deformation_), std::size_t(phase_key_),
                     d.snap(t));
    });
  });
  connect(phase_value_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    if (updating_ || !has_object() || deformation_ < 0 || phase_key_ < 0) return;
    edit("Phase value", [&](Document& d) {
      d.set_phase_value(std::size_t(object_), std::size_t(deformation_), std::size_t(phase_key_), v);
    });
  });
  auto* def_buttons = new QHBoxLayout;
  auto* add_phase = new QPushButton("Add phase key", defbox);
  add_phase->setObjectName("addPhaseKey");
  add_phase->setToolTip("A key of the selected deformation at the current time, with its current phase");
  connect(add_phase, &QPushButton::clicked, this, [this] {
    if (!has_object() || deformation_ < 0) return;
    const double t = doc_.snap(time_);
    const double v =
        scene_->objects[std::size_t(object_)].parts[0].deformations[std::size_t(deformation_)].schedule.phase(t);
    std::size_t k = 0;
    if (edit("Add phase key",
             [&](Document& d) { k = d.add_phase_key(std::size_t(object_), std::size_t(deformation_), t, v); }))
      select_phase_key(deformation_, int(k));
  });
  auto* del_phase = new QPushButton("Delete key", defbox);
  del_phase->setObjectName("deletePhaseKey");
  connect(del_phase, &QPushButton::clicked, this, [this] {
    if (!has_object() || deformation_ < 0 || phase_key_ < 0) return;
    const int k = phase_key_;
    if (edit("Delete phase key",
             [&](Document& d) { d.remove_phase_key(std::size_t(object_), std::size_t(deformation_), std::size_t(k)); }))
      select_phase_key(deformation_, -1);
  });
  auto* del_def = new QPushButton("Remove", defbox);
  del_def->setObjectName("removeDeformation");
  connect(del_def, &QPushButton::clicked, this, [this] {
    if (!has_object() || deformation_ < 0) return;
    const int k = deformation_;
    if (edit("Remove deformation", [&](Document& d) { d.remove_deformation(std::size_t(object_), std::size_t(k)); }))
      select_phase_key(-1, -1);
  });
  def_buttons->addWidget(add_phase);
  def_buttons->addWidget(del_phase);
  def_buttons->addWidget(del_def);
  df->addRow(def_buttons);
  layout->addWidget(defbox);

  // Look: what the movie shows (saved in the scene).
  auto* lookbox = new QGroupBox("Look (camera, lights, colours)", panel);
  auto* lf = new QFormLayout(lookbox);
  auto* cam_row = new QHBoxLayout;
  auto* cam_from_view = new QPushButton("Set from view", lookbox);
  cam_from_view->setObjectName("cameraFromView");
  cam_from_view->setToolTip("The movie's camera becomes the view's (Ctrl+Shift+C)");
  connect(cam_from_view, &QPushButton::clicked, this, [this] { set_scene_camera_from_view(); });
  auto* look_through = new QPushButton("Look through", lookbox);
  look_through->setObjectName("lookThrough");
  look_through->setToolTip("The view shows what the movie will (C)");
  connect(look_through, &QPushButton::clicked, this, [this] { look_through_scene_camera(); });
  cam_row->addWidget(cam_from_view);
  cam_row->addWidget(look_through);
  lf->addRow("camera", cam_row);
  view_angle_ = spin("viewAngle", 1, 179, 5, 1);
  connect(view_angle_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double a) {
    if (updating_ || !scene_) return;
    const auto& c = scene_->camera;
    edit("View angle", [&](Document& d) { d.set_camera(c.position, c.focal_point, c.view_up, a); });
  });
  lf->addRow("view angle (deg)", view_angle_);
  const auto pick_colour = [this](const Vec3& now, const QString& title) -> std::optional<Vec3> {
    const QColor c = QColorDialog::getColor(QColor::fromRgbF(now.x(), now.y(), now.z()), this, title);
    if (!c.isValid()) return std::nullopt;
    return Vec3(c.redF(), c.greenF(), c.blueF());
  };
  auto* colours = new QHBoxLayout;
  auto* background = new QPushButton("Background...", lookbox);
  background->setObjectName("background");
  connect(background, &QPushButton::clicked, this, [this, pick_colour] {
    if (const auto c = pick_colour(doc_.background(), "Background colour"))
      edit("Background", [&](Document& d) { d.set_background(*c); });
  });
  auto* object_colour = new QPushButton("Object colour...", lookbox);
  object_colour->setObjectName("objectColour");
  connect(object_colour, &QPushButton::clicked, this, [this, pick_colour] {
    if (!has_object()) return;
    if (const auto c = pick_colour(doc_.object_color(std::size_t(object_)), "Object colour"))
      edit("Object colour", [&](Document& d) { d.set_object_color(std::size_t(object_), *c); });
  });
  colours->addWidget(background);
  colours->addWidget(object_colour);
  lf->addRow("colours", colours);
  lights_ = new QListWidget(lookbox);
  lights_->setObjectName("lights");
  lights_->setMaximumHeight(70);
  connect(lights_, &QListWidget::currentRowChanged, this, [this] {
    if (!updating_) refresh_look_panel();  // not while the panel itself refills the list
  });
  lf->addRow("lights", lights_);
  light_intensity_ = spin("lightIntensity", 0, 10, 0.1, 2);
  connect(light_intensity_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    const int l = lights_->currentRow();
    if (updating_ || l < 0) return;
    edit("Light intensity", [&](Document& d) {
      const json& light = d.json()["lights"][std::size_t(l)];
      const Vec3 rgb = light.contains("color") ? Vec3(light["color"][0].get<double>(), light["color"][1].get<double>(),
                                                      light["color"][2].get<double>())
                                               : Vec3(1, 1, 1);
      d.set_light(std::size_t(l), v, rgb);
    });
  });
  lf->addRow("intensity", light_intensity_);
  auto* light_buttons = new QHBoxLayout;
  auto* add_light = new QPushButton("Add from view", lookbox);
  add_light->setObjectName("addLight");
  add_light->setToolTip("A light shining from where the view's camera is, towards the scene camera's focal point");
  connect(add_light, &QPushButton::clicked, this, [this] {
    if (!scene_renderer_) return;
    const double* p = scene_renderer_->renderer()->GetActiveCamera()->GetPosition();
    edit("Add light", [&](Document& d) { d.add_light(Vec3(p[0], p[1], p[2]), 0.8, false); });
  });
  auto* del_light = new QPushButton("Remove", lookbox);
  del_light->setObjectName("removeLight");
  connect(del_light, &QPushButton::clicked, this, [this] {
    const int l = lights_->currentRow();
    if (l >= 0) edit("Remove light", [&](Document& d) { d.remove_light(std::size_t(l)); });
  });
  auto* light_colour = new QPushButton("Colour...", lookbox);
  light_colour->setObjectName("lightColour");
  connect(light_colour, &QPushButton::clicked, this, [this, pick_colour] {
    const int l = lights_->currentRow();
    if (l < 0 || std::size_t(l) >= doc_.light_count()) return;
    const json& light = doc_.json()["lights"][std::size_t(l)];
    const Vec3 now = light.contains("color") ? Vec3(light["color"][0].get<double>(), light["color"][1].get<double>(),
                                                    light["color"][2].get<double>())
                                             : Vec3(1, 1, 1);
    const double intensity = light.value("intensity", 1.0);
    if (const auto c = pick_colour(now, "Light colour"))
      edit("Light colour", [&](Document& d) { d.set_light(std::size_t(l), intensity, *c); });
  });
  light_buttons->addWidget(add_light);
  light_buttons->addWidget(light_colour);
  light_buttons->addWidget(del_light);
  lf->addRow(light_buttons);
  layout->addWidget(lookbox);

  // Messages above the scrolling panel, always in sight.
  auto* messages = gui::make_message_box(dock, 96);
  error_ = gui::add_message(messages, "error", "#b03030");
  info_ = gui::add_message(messages, "info", "#9fd89f");
  layout->addStretch(1);
  dock_scroll->setWidget(panel);
  dock_scroll->setMinimumWidth(panel->minimumWidth() + 24);
  auto* dock_body = new QWidget(dock);
  auto* dock_layout = new QVBoxLayout(dock_body);
  dock_layout->setContentsMargins(0, 0, 0, 0);
  dock_layout->addWidget(messages);
  dock_layout->addWidget(dock_scroll, 1);
  dock->setWidget(dock_body);
  addDockWidget(Qt::RightDockWidgetArea, dock);
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
  add(playm, "To the &start", QKeySequence("Home"), [this] { set_time(0); });
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

// ---------------------------------------------------------------------------------------------------

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
  return edit("Attach deformation",
              [&](Document& d) { d.attach_deformation(std::size_t(object_), file.toStdString()); });
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
  info_->hide();
  undo_.push(new JsonCommand(this, before, doc_.json(), doc_.base(), what));
  scene_ = std::move(scene);
  rebuild();
  return true;
}

void ComposerWindow::restore(const json& j, const std::filesystem::path& base) {
  doc_.set_json(j, base);
  if (object_ >= int(doc_.object_count())) object_ = int(doc_.object_count()) - 1;
  key_ = deformation_ = phase_key_ = -1;
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
  if (object_ >= int(doc_.object_count())) object_ = int(doc_.object_count()) - 1;
  timeline_->setMinimumHeight(timeline_->needed_height());
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
  r->AddActor(camera_actor_);
  if (had) r->GetActiveCamera()->DeepCopy(camera);
  {
    // The scene camera's frame, ending at its focal point.
    const auto& c = scene_->camera;
    vtkNew<vtkCamera> sc;
    sc->SetPosition(c.position.data());
    sc->SetFocalPoint(c.focal_point.data());
    sc->SetViewUp(c.view_up.data());
    sc->SetViewAngle(c.view_angle);
    const double d = (c.position - c.focal_point).norm();
    sc->SetClippingRange(0.05 * d, d);
    camera_actor_->SetCamera(sc);
  }
  apply_wireframe();
  window_->AddRenderer(r);
  updating_ = true;
  objects_->clear();
  for (std::size_t i = 0; i < doc_.object_count(); ++i) objects_->addItem(QString::fromStdString(doc_.object_name(i)));
  if (object_ >= 0) objects_->setCurrentRow(object_);
  updating_ = false;
  time_ = std::clamp(time_, 0.0, doc_.duration());
  if (!has_object() || deformation_ >= int(doc_.deformation_count(std::size_t(object_))))
    deformation_ = phase_key_ = -1;
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
  for (QDoubleSpinBox* s : {key_time_, key_pos_[0], key_pos_[1], key_pos_[2], tcb_[0], tcb_[1], tcb_[2]}) {
    s->setEnabled(has_key);
    if (!has_key) s->setValue(0);  // no stale values of a key that is gone (File > New, undo)
  }
  if (has_key) {
    const auto& k = scene_->objects[std::size_t(object_)].trajectory->keys()[std::size_t(key_)];
    key_time_->setValue(k.time);
    for (int c = 0; c < 3; ++c) key_pos_[c]->setValue(k.position[c]);
    tcb_[0]->setValue(k.tension);
    tcb_[1]->setValue(k.continuity);
    tcb_[2]->setValue(k.bias);
  }
  const Vec3 a = has_object()
                     ? angles_from_quaternion(scene_->objects[std::size_t(object_)].orientation.rotation(time_))
                     : Vec3::Zero();
  for (int c = 0; c < 3; ++c) {
    angles_[c]->setValue(a[c]);
    angles_[c]->setEnabled(has_object());
  }
  updating_ = false;
  refresh_deformation_panel();
  refresh_look_panel();
  timeline_->update();
}

void ComposerWindow::refresh_deformation_panel() {
  updating_ = true;
  const std::size_t n = has_object() ? doc_.deformation_count(std::size_t(object_)) : 0;
  if (deformations_->count() != int(n)) deformations_->clear();
  for (std::size_t d = 0; d < n; ++d) {
    const QString name = QString::fromStdString(doc_.deformation_name(std::size_t(object_), d));
    if (int(d) < deformations_->count())
      deformations_->item(int(d))->setText(name);
    else
      deformations_->addItem(name);
  }
  deformations_->setCurrentRow(deformation_);
  const bool has_def = deformation_ >= 0 && std::size_t(deformation_) < n;
  const bool has_key = has_def && phase_key_ >= 0;
  def_name_->setEnabled(has_def);
  easing_->setEnabled(has_def);
  combine_->setEnabled(n > 0);
  phase_time_->setEnabled(has_key);
  phase_value_->setEnabled(has_key);
  def_name_->setText(
      has_def ? QString::fromStdString(doc_.deformation_name(std::size_t(object_), std::size_t(deformation_)))
              : QString());
  combine_->setCurrentText(n > 0 ? QString::fromStdString(doc_.combine(std::size_t(object_))) : "compose");
  easing_->setCurrentText(has_def ? QString::fromStdString(doc_.easing(std::size_t(object_), std::size_t(deformation_)))
                                  : "smooth");
  if (has_key) {
    const auto times = doc_.key_times(std::size_t(object_), Document::Track::Phase, std::size_t(deformation_));
    phase_time_->setValue(std::size_t(phase_key_) < times.size() ? times[std::size_t(phase_key_)] : 0.0);
    phase_value_->setValue(doc_.phase_value(std::size_t(object_), std::size_t(deformation_), std::size_t(phase_key_)));
  } else {
    phase_time_->setValue(0);
    phase_value_->setValue(0);
  }
  updating_ = false;
}

void ComposerWindow::refresh_look_panel() {
  updating_ = true;
  const int row = lights_->currentRow();
  lights_->clear();
  for (std::size_t l = 0; l < doc_.light_count(); ++l) lights_->addItem(QString::fromStdString(doc_.light_label(l)));
  if (lights_->count() == 0) lights_->addItem("(none: one headlight)");
  const bool has_light = row >= 0 && std::size_t(row) < doc_.light_count();
  lights_->setCurrentRow(has_light ? row : -1);
  light_intensity_->setEnabled(has_light);
  light_intensity_->setValue(has_light ? doc_.json()["lights"][std::size_t(row)].value("intensity", 1.0) : 0.0);
  if (scene_) view_angle_->setValue(scene_->camera.view_angle);
  updating_ = false;
}

void ComposerWindow::select_phase_key(int deformation, int key) {
  const int n = has_object() ? int(doc_.deformation_count(std::size_t(object_))) : 0;
  deformation_ = deformation >= 0 && deformation < n ? deformation : -1;
  phase_key_ = deformation_ >= 0 ? key : -1;
  if (phase_key_ >= 0) key_ = -1;  // one selected key at a time: Delete removes it
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
}

void ComposerWindow::apply_wireframe() {
  if (!scene_renderer_ || !wireframe_) return;
  vtkActorCollection* actors = scene_renderer_->renderer()->GetActors();
  actors->InitTraversal();
  while (vtkActor* a = actors->GetNextActor())
    if (a != curve_actor_ && a != handle_actor_ && a != frame_actor_ &&
        static_cast<vtkProp*>(a) != static_cast<vtkProp*>(camera_actor_.Get()))
      a->GetProperty()->SetRepresentation(wireframe_->isChecked() ? VTK_WIREFRAME : VTK_SURFACE);
}

void ComposerWindow::reset_camera(gui::View view) {
  if (!scene_renderer_ || !player_) return;
  double b[6] = {0, 1, 0, 1, 0, 1};
  bool any = false;
  for (std::size_t o = 0; scene_ && o < scene_->objects.size(); ++o)
    for (const auto& p : player_->positions(o)) {
      for (int k = 0; k < 3; ++k) {
        b[2 * k] = any ? std::min(b[2 * k], p[k]) : p[k];
        b[2 * k + 1] = any ? std::max(b[2 * k + 1], p[k]) : p[k];
      }
      any = true;
    }
  gui::set_view(scene_renderer_->renderer(), b, view);
  view_->renderWindow()->Render();
}

bool ComposerWindow::set_scene_camera_from_view() {
  if (!scene_renderer_) return false;
  vtkCamera* c = scene_renderer_->renderer()->GetActiveCamera();
  const Vec3 pos(c->GetPosition()), focal(c->GetFocalPoint()), up(c->GetViewUp());
  const double angle = c->GetViewAngle();
  if (!edit("Set scene camera from view", [&](Document& d) { d.set_camera(pos, focal, up, angle); })) return false;
  show_info("The movie's camera is now the view's");
  return true;
}

void ComposerWindow::look_through_scene_camera() {
  if (!scene_renderer_ || !scene_) return;
  const auto& c = scene_->camera;
  vtkCamera* cam = scene_renderer_->renderer()->GetActiveCamera();
  cam->SetPosition(c.position.data());
  cam->SetFocalPoint(c.focal_point.data());
  cam->SetViewUp(c.view_up.data());
  cam->SetViewAngle(c.view_angle);
  scene_renderer_->renderer()->ResetCameraClippingRange();
  show_frame();
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
      for (int s = 0; s < n; ++s)
        ids.push_back(cp->InsertNextPoint(obj.trajectory->position(t0 + (t1 - t0) * s / (n - 1)).data()));
      cl->InsertNextCell(vtkIdType(ids.size()), ids.data());
      for (std::size_t k = 0; k < keys.size(); ++k) {
        hp->InsertNextPoint(keys[k].position.data());
        if (int(o) == object_ && int(k) == key_)
          hc->InsertNextTuple3(255, 240, 60);
        else if (int(o) == object_)
          hc->InsertNextTuple3(255, 150, 40);
        else
          hc->InsertNextTuple3(150, 110, 80);
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
  key_ = deformation_ = phase_key_ = -1;
  timeline_->setMinimumHeight(timeline_->needed_height());
  updating_ = true;
  objects_->setCurrentRow(object_);
  updating_ = false;
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
}

void ComposerWindow::select_key(int key) {
  key_ = key;
  if (key_ >= 0) phase_key_ = -1;
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
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

bool ComposerWindow::export_movie(const QString& path, int width, int height) {
  play(false);
  if (!scene_ || scene_->objects.empty()) {
    show_error("The scene has no objects to render");
    return false;
  }
  QProgressDialog progress("Rendering " + QFileInfo(path).fileName() + "...", "Cancel", 0,
                           int(scene_->frame_count(0, scene_->duration)), this);
  progress.setWindowTitle("Export movie");
  progress.setMinimumWidth(420);
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
      show_info("Export cancelled; nothing was written");
      return false;
    }
    clear_error();
    show_info(QString("Wrote %1: %2 frames, computation %3 ms, rendering %4 ms a frame")
                  .arg(path)
                  .arg(stats.frames)
                  .arg(1e3 * stats.compute_seconds / double(stats.frames), 0, 'f', 3)
                  .arg(1e3 * stats.render_seconds / double(stats.frames), 0, 'f', 1));
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

vtkCameraActor* ComposerWindow::scene_camera_actor() const { return camera_actor_; }

bool ComposerWindow::has_object() const {
  return object_ >= 0 && scene_ && std::size_t(object_) < scene_->objects.size();
}

int ComposerWindow::key_at(int x, int y) const {
  if (!has_object() || !scene_->objects[std::size_t(object_)].trajectory) return -1;
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
  undo_.push(new JsonCommand(this, drag_start_, doc_.json(), doc_.base(), "Move trajectory key"));
}

void ComposerWindow::add_key_at_display(int x, int y) {
  if (!has_object()) return;
  // On the plane through the object's current position, facing the screen.
  const Vec3 here = anim::pose_at(scene_->objects[std::size_t(object_)], time_).position;
  vtkRenderer* r = scene_renderer_->renderer();
  const auto p = gui::display_to_world(r, x, y, gui::world_to_display(r, here).z());
  if (!p) return;
  std::size_t k = 0;
  if (edit("Add trajectory key", [&](Document& d) { k = d.add_position_key(std::size_t(object_), d.snap(time_), *p); }))
    select_key(int(k));
}

void ComposerWindow::rotate_by(double dyaw, double dpitch) {
  if (!has_object()) return;
  const double t = doc_.snap(time_);
  const Vec3 a = angles_from_quaternion(scene_->objects[std::size_t(object_)].orientation.rotation(t));
  live_edit([&](Document& d) { d.set_orientation_key(std::size_t(object_), t, a[0] + dyaw, a[1] + dpitch, a[2]); });
}

bool ComposerWindow::save_screenshot(const QString& path) { return gui::save_window_png(this, view_, path); }

bool ComposerWindow::maybe_save() {
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
  if (maybe_save())
    e->accept();
  else
    e->ignore();
}

}  // namespace csrbf::composer
