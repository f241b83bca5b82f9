// The Composer's side panel (objects, keys, scene, deformations, look) and the bar under the view
// (timeline, play, scrub), with their refresh from the document and the selection they drive.
#include "composer_window.hpp"

#include "csrbf/render/scene_renderer.hpp"
#include "gui_common.hpp"

#include <QCheckBox>
#include <QColorDialog>
#include <QComboBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QFrame>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QPushButton>
#include <QScrollArea>
#include <QTabWidget>

#include <utility>
#include <QScrollBar>
#include <QSlider>
#include <QVBoxLayout>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkCamera.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>

#include <cctype>
#include <optional>
#include <string>

namespace csrbf::composer {

using nlohmann::json;

/// A number box of the panel (full precision, scientific notation): its value is an edit when
/// typing is done, not at each key; a number out of range is refused with a message, never clamped.
QDoubleSpinBox* ComposerWindow::number_box(QWidget* parent, const char* name, double lo, double hi, double step) {
  // Its name in messages: "keyTime" is "key time".
  QString what;
  for (const char* c = name; *c; ++c) {
    if (std::isupper(static_cast<unsigned char>(*c))) what += ' ';
    what += QChar(std::tolower(static_cast<unsigned char>(*c)));
  }
  auto* s = gui::number_box(parent, name, lo, hi, what, [this](const QString& m) { show_error(m); });
  s->setSingleStep(step);
  return s;
}

void ComposerWindow::build_ui() {
  build_view();
  build_centre();

  auto* dock = new QDockWidget("Properties", this);  // "Scene" is the third tab's name
  dock->setObjectName("scene");
  dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  // Three tabs, as Blender's properties editor has them: the whole panel (1110 pixels high) did not
  // fit the default window and scrolled, its last row cut at the fold. Each tab fits in 820 pixels;
  // a smaller window scrolls the tab alone.
  tabs_ = new QTabWidget(dock);
  tabs_->setObjectName("panelTabs");
  const auto page = [this](const QString& title) {
    auto* scroll = new QScrollArea(tabs_);
    scroll->setWidgetResizable(true);
    scroll->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
    scroll->setFrameShape(QFrame::NoFrame);
    auto* panel = new QWidget(scroll);
    panel->setMinimumWidth(330);
    auto* layout = new QVBoxLayout(panel);
    scroll->setWidget(panel);
    scroll->setMinimumWidth(panel->minimumWidth() + 24);
    tabs_->addTab(scroll, title);
    return std::make_pair(panel, layout);
  };
  {
    auto [panel, layout] = page("Object");
    build_object_list(panel, layout);
    layout->addWidget(build_key_box(panel));
    layout->addWidget(build_orientation_box(panel));
    layout->addStretch(1);
  }
  {
    auto [panel, layout] = page("Deformations");
    layout->addWidget(build_deformation_box(panel));
    layout->addStretch(1);
  }
  {
    auto [panel, layout] = page("Scene");
    layout->addWidget(build_scene_box(panel));
    layout->addWidget(build_look_box(panel));
    layout->addStretch(1);
  }

  // Messages above the tabs, always in sight.
  auto* messages = gui::make_message_box(dock, 96);
  error_ = gui::add_message(messages, "error", "#b03030");
  info_ = gui::add_message(messages, "info", "#9fd89f");
  gui::add_tip(messages,
               "Select an object, click the timeline at a time, place the object and press K for a key. Space "
               "plays, Home frames all, F1 lists every key.");
  auto* dock_body = new QWidget(dock);
  auto* dock_layout = new QVBoxLayout(dock_body);
  dock_layout->setContentsMargins(0, 0, 0, 0);
  dock_layout->addWidget(messages);
  dock_layout->addWidget(tabs_, 1);
  dock->setWidget(dock_body);
  addDockWidget(Qt::RightDockWidgetArea, dock);
}

void ComposerWindow::build_centre() {
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
}

void ComposerWindow::build_object_list(QWidget* panel, QVBoxLayout* layout) {
  objects_ = new QListWidget(panel);
  objects_->setMaximumHeight(6 * objects_->fontMetrics().height() + 8);  // the panel's other rows in sight
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
}

QGroupBox* ComposerWindow::build_key_box(QWidget* panel) {
  auto* keybox = new QGroupBox("Trajectory key", panel);
  auto* kf = new QFormLayout(keybox);
  key_time_ = number_box(keybox, "keyTime", 0, 1e6, 0.1);
  kf->addRow("time (s)", key_time_);
  connect(key_time_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double t) {
    if (updating_ || object_ < 0 || key_ < 0) return;
    edit("Key time", [&](Document& d) {
      d.set_key_time(std::size_t(object_), Document::Track::Position, 0, std::size_t(key_), d.snap(t));
    });
  });
  auto* pos_row = new QHBoxLayout;
  for (int c = 0; c < 3; ++c) {
    key_pos_[c] = number_box(keybox, c == 0 ? "keyX" : c == 1 ? "keyY" : "keyZ", -1e6, 1e6, 0.05);
    pos_row->addWidget(key_pos_[c]);
    connect(key_pos_[c], qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this, c] {
      if (updating_ || !has_object() || key_ < 0) return;
      const auto& trajectory = scene_->objects[std::size_t(object_)].trajectory;
      if (!trajectory || std::size_t(key_) >= trajectory->keys().size()) return;
      // Only the coordinate edited changes: the others keep their full precision (the boxes show 3
      // decimals, and writing all three back rounded the other two).
      Vec3 p = trajectory->keys()[std::size_t(key_)].position;
      p[c] = key_pos_[c]->value();
      edit("Key position", [&](Document& d) { d.set_position(std::size_t(object_), std::size_t(key_), p); });
    });
  }
  kf->addRow("position", pos_row);
  const char* tcb_names[3] = {"tension", "continuity", "bias"};
  for (int c = 0; c < 3; ++c) {
    tcb_[c] = number_box(keybox, tcb_names[c], -1, 1, 0.1);
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
  return keybox;
}

QGroupBox* ComposerWindow::build_orientation_box(QWidget* panel) {
  auto* rotbox = new QGroupBox("Orientation at the current time", panel);
  auto* rf = new QFormLayout(rotbox);
  const char* angle_names[3] = {"yaw", "pitch", "roll"};
  for (int c = 0; c < 3; ++c) {
    angles_[c] = number_box(rotbox, angle_names[c], -360, 360, 5);
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
  return rotbox;
}

QGroupBox* ComposerWindow::build_scene_box(QWidget* panel) {
  auto* scenebox = new QGroupBox("Timing", panel);
  auto* sf = new QFormLayout(scenebox);
  duration_ = number_box(scenebox, "duration", 0.1, 3600, 0.5);
  fps_ = number_box(scenebox, "fps", 1, 240, 1);
  sf->addRow("duration (s)", duration_);
  sf->addRow("frame rate", fps_);
  connect(duration_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    if (!updating_) edit("Duration", [&](Document& d) { d.set_duration(v); });
  });
  connect(fps_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    if (!updating_) edit("Frame rate", [&](Document& d) { d.set_fps(v); });
  });
  return scenebox;
}

// Deformations of the selected object: name, schedule, how they combine.
QGroupBox* ComposerWindow::build_deformation_box(QWidget* panel) {
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
  phase_time_ = number_box(defbox, "phaseTime", 0, 1e6, 0.04);
  phase_value_ = number_box(defbox, "phaseValue", -1e6, 1e6, 0.1);
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
  return defbox;
}

// Look: what the movie shows (saved in the scene).
QGroupBox* ComposerWindow::build_look_box(QWidget* panel) {
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
  view_angle_ = number_box(lookbox, "viewAngle", 1, 179, 5);
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
  light_intensity_ = number_box(lookbox, "lightIntensity", 0, 10, 0.1);
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
  return lookbox;
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
  // A phase key past the schedule's (one just deleted, or an undo's) selects nothing.
  const std::size_t phase_keys =
      has_def ? doc_.key_times(std::size_t(object_), Document::Track::Phase, std::size_t(deformation_)).size() : 0;
  if (phase_key_ >= 0 && std::size_t(phase_key_) >= phase_keys) phase_key_ = -1;
  const bool has_key = has_def && phase_key_ >= 0;
  def_name_->setEnabled(has_def);
  easing_->setEnabled(has_def);
  combine_->setEnabled(n > 0);
  phase_time_->setEnabled(has_key);
  phase_value_->setEnabled(has_key);
  // The buttons too look as what they do allows (the new-user trial took them for live).
  for (const char* b : {"addPhaseKey", "removeDeformation"})
    if (auto* button = findChild<QPushButton*>(b)) button->setEnabled(has_def);
  if (auto* button = findChild<QPushButton*>("deletePhaseKey")) button->setEnabled(has_key);
  def_name_->setText(
      has_def ? QString::fromStdString(doc_.deformation_name(std::size_t(object_), std::size_t(deformation_)))
              : QString());
  combine_->setCurrentText(n > 0 ? QString::fromStdString(doc_.combine(std::size_t(object_))) : "compose");
  easing_->setCurrentText(has_def ? QString::fromStdString(doc_.easing(std::size_t(object_), std::size_t(deformation_)))
                                  : "smooth");
  if (has_key) {
    const auto times = doc_.key_times(std::size_t(object_), Document::Track::Phase, std::size_t(deformation_));
    phase_time_->setValue(times[std::size_t(phase_key_)]);
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
  if (phase_key_ >= 0) key_ = -1;                                   // one selected key at a time: Delete removes it
  if (deformation_ >= 0) tabs_->setCurrentIndex(kDeformationsTab);  // what was picked is in sight
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
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
  if (key_ >= 0) {
    phase_key_ = -1;
    tabs_->setCurrentIndex(kObjectTab);
  }
  refresh_panel();
  refresh_overlays();
  view_->renderWindow()->Render();
}

}  // namespace csrbf::composer
