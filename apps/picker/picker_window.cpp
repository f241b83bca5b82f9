#include "picker_window.hpp"

#include "csrbf/io/controls.hpp"
#include "csrbf/names.hpp"
#include "gui_common.hpp"

#include <QAction>
#include <QApplication>
#include <QCheckBox>
#include <QCloseEvent>
#include <QComboBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QDragEnterEvent>
#include <QDropEvent>
#include <QFileDialog>
#include <QFileInfo>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPushButton>
#include <QScrollArea>
#include <QSlider>
#include <QStatusBar>
#include <QTableWidget>
#include <QUndoCommand>
#include <QVBoxLayout>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkActor.h>
#include <vtkActor2D.h>
#include <vtkCoordinate.h>
#include <vtkLookupTable.h>
#include <vtkPolyDataMapper2D.h>
#include <vtkProperty2D.h>
#include <vtkScalarBarActor.h>
#include <vtkTextProperty.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkCellPicker.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGlyph3D.h>
#include <vtkInteractorStyleTrackballCamera.h>
#include <vtkNew.h>
#include <vtkObjectFactory.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkRenderer.h>
#include <vtkSphereSource.h>
#include <vtkUnsignedCharArray.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

namespace csrbf::picker {

// ---------------------------------------------------------------------------------------------------
// Mouse: left click on the surface adds a control (shift: pinned); left drag on a handle moves its
// destination; left drag elsewhere orbits; middle drag or shift + left drag pans; wheel or right drag
// zooms; ctrl + left drag selects the active area.

class PickerStyle : public vtkInteractorStyleTrackballCamera {
 public:
  static PickerStyle* New();
  vtkTypeMacro(PickerStyle, vtkInteractorStyleTrackballCamera) PickerWindow* window = nullptr;

  void OnLeftButtonDown() override {
    const int* p = GetInteractor()->GetEventPosition();
    press_[0] = p[0];
    press_[1] = p[1];
    moved_ = false;
    shift_ = GetInteractor()->GetShiftKey() != 0;
    if (GetInteractor()->GetControlKey()) {
      banding_ = true;
      return;
    }
    const int h = window->handle_at(p[0], p[1]);
    if (h >= 0) {
      window->select(h);
      if (!window->doc_.state().controls[std::size_t(h)].pinned) {
        window->begin_drag(h);
        return;
      }
    }
    if (shift_) return;  // shift: a click pins a point; shift-drag pans (below)
    vtkInteractorStyleTrackballCamera::OnLeftButtonDown();
  }

  void OnMouseMove() override {
    const int* p = GetInteractor()->GetEventPosition();
    if (std::abs(p[0] - press_[0]) + std::abs(p[1] - press_[1]) > 3) moved_ = true;
    if (window->dragging_ >= 0) {
      if (moved_) window->drag_to(p[0], p[1]);  // a click that stays put does not move the handle
      return;
    }
    if (banding_) {
      window->show_band(press_[0], press_[1], p[0], p[1]);
      return;
    }
    if (shift_ && moved_ && !banding_ && State == VTKIS_NONE && GetInteractor()->GetShiftKey()) {
      FindPokedRenderer(p[0], p[1]);
      StartPan();
    }
    vtkInteractorStyleTrackballCamera::OnMouseMove();
  }

  void OnLeftButtonUp() override {
    const int* p = GetInteractor()->GetEventPosition();
    if (window->dragging_ >= 0) {
      if (moved_) window->drag_to(p[0], p[1]);  // where the button came up, whatever moves were merged on the way
      window->end_drag();
    } else if (banding_) {
      window->hide_band();
      if (moved_) window->select_region(press_[0], press_[1], p[0], p[1]);
    } else if (!moved_ && window->handle_at(p[0], p[1]) < 0) {
      Vec3 hit;
      if (window->pick_surface(p[0], p[1], hit)) window->add_control(hit, shift_);
    }
    banding_ = false;
    if (State == VTKIS_PAN) EndPan();
    vtkInteractorStyleTrackballCamera::OnLeftButtonUp();
  }

  // VTK's own keys (w wireframe, 3 stereo, e/q quit, p pick, ...) are off: the menus hold every key.
  void OnChar() override {}

 private:
  int press_[2] = {0, 0};
  bool moved_ = false, shift_ = false, banding_ = false;
};
vtkStandardNewMacro(PickerStyle);

// ---------------------------------------------------------------------------------------------------

/// One edit: the state before and after. The first redo() is the edit itself, already applied.
class StateCommand : public QUndoCommand {
 public:
  StateCommand(PickerWindow* w, State before, State after, const QString& text, int merge_id)
      : QUndoCommand(text), w_(w), before_(std::move(before)), after_(std::move(after)), merge_id_(merge_id) {}
  void undo() override { w_->restore(before_); }
  void redo() override {
    if (first_) {
      first_ = false;
      return;
    }
    w_->restore(after_);
  }
  int id() const override { return merge_id_; }
  bool mergeWith(const QUndoCommand* other) override {
    const auto* o = static_cast<const StateCommand*>(other);
    after_ = o->after_;
    return true;
  }

 private:
  PickerWindow* w_;
  State before_, after_;
  int merge_id_;
  bool first_ = true;
};

namespace {

enum MergeId { kMergeRadius = 1, kMergePhase = 2, kMergeTable = 3 };

QString number(double v) { return QString::number(v, 'g', 6); }

// Radius slider: 0 .. 1000 over R / diagonal from 1e-3 to 1, logarithmic.
int slider_from_fraction(double f) {
  return int(std::lround(1000.0 * (std::log10(std::clamp(f, 1e-3, 1.0)) + 3.0) / 3.0));
}
double fraction_from_slider(int v) { return std::pow(10.0, 3.0 * double(v) / 1000.0 - 3.0); }

}  // namespace

PickerWindow::PickerWindow(QWidget* parent) : QMainWindow(parent) {
  setWindowTitle("csrbf Picker[*]");
  setAcceptDrops(true);
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) { setWindowModified(!clean); });
  build_scene();
  build_ui();
  build_menus();
  refresh();
}

PickerWindow::~PickerWindow() = default;

vtkRenderer* PickerWindow::renderer() const { return renderer_; }

void PickerWindow::build_scene() {
  view_ = new QVTKOpenGLNativeWidget(this);
  window_ = vtkSmartPointer<vtkGenericOpenGLRenderWindow>::New();
  view_->setRenderWindow(window_);
  renderer_ = vtkSmartPointer<vtkRenderer>::New();
  renderer_->SetBackground(0.16, 0.17, 0.2);
  renderer_->SetBackground2(0.32, 0.34, 0.4);
  renderer_->GradientBackgroundOn();
  window_->AddRenderer(renderer_);
  style_ = vtkSmartPointer<PickerStyle>::New();
  style_->window = this;
  window_->GetInteractor()->SetInteractorStyle(style_);

  mesh_ = vtkSmartPointer<vtkPolyData>::New();
  mesh_->SetPoints(vtkNew<vtkPoints>());
  vtkNew<vtkPolyDataNormals> normals;
  normals->SetInputData(mesh_);
  normals->SplittingOff();
  vtkNew<vtkPolyDataMapper> mesh_mapper;
  mesh_mapper->SetInputConnection(normals->GetOutputPort());
  mesh_mapper->SetScalarModeToUsePointData();
  mesh_mapper->SetColorModeToDirectScalars();
  mesh_actor_ = vtkSmartPointer<vtkActor>::New();
  mesh_actor_->SetMapper(mesh_mapper);
  mesh_actor_->GetProperty()->SetSpecular(0.2);
  renderer_->AddActor(mesh_actor_);

  // Handles: a sphere glyph at each source and each moved destination, coloured per point.
  handles_ = vtkSmartPointer<vtkPolyData>::New();
  handles_->SetPoints(vtkNew<vtkPoints>());
  vtkNew<vtkSphereSource> ball;
  ball->SetThetaResolution(16);
  ball->SetPhiResolution(12);
  handle_glyph_ = vtkSmartPointer<vtkGlyph3D>::New();
  handle_glyph_->SetInputData(handles_);
  handle_glyph_->SetSourceConnection(ball->GetOutputPort());
  handle_glyph_->SetScaleModeToDataScalingOff();
  handle_glyph_->SetColorModeToColorByScalar();
  vtkNew<vtkPolyDataMapper> handle_mapper;
  handle_mapper->SetInputConnection(handle_glyph_->GetOutputPort());
  handle_mapper->SetColorModeToDirectScalars();
  handle_actor_ = vtkSmartPointer<vtkActor>::New();
  handle_actor_->SetMapper(handle_mapper);
  handle_actor_->PickableOff();
  renderer_->AddActor(handle_actor_);

  lines_ = vtkSmartPointer<vtkPolyData>::New();
  lines_->SetPoints(vtkNew<vtkPoints>());
  lines_->SetLines(vtkNew<vtkCellArray>());
  vtkNew<vtkPolyDataMapper> line_mapper;
  line_mapper->SetInputData(lines_);
  line_actor_ = vtkSmartPointer<vtkActor>::New();
  line_actor_->SetMapper(line_mapper);
  line_actor_->GetProperty()->SetColor(1.0, 0.85, 0.2);
  line_actor_->GetProperty()->SetLineWidth(2.0);
  line_actor_->PickableOff();
  renderer_->AddActor(line_actor_);

  // Support spheres: radius R about each source, translucent.
  supports_ = vtkSmartPointer<vtkPolyData>::New();
  supports_->SetPoints(vtkNew<vtkPoints>());
  vtkNew<vtkSphereSource> unit;
  unit->SetRadius(1.0);
  unit->SetThetaResolution(24);
  unit->SetPhiResolution(16);
  support_glyph_ = vtkSmartPointer<vtkGlyph3D>::New();
  support_glyph_->SetInputData(supports_);
  support_glyph_->SetSourceConnection(unit->GetOutputPort());
  support_glyph_->SetScaleModeToDataScalingOff();
  vtkNew<vtkPolyDataMapper> support_mapper;
  support_mapper->SetInputConnection(support_glyph_->GetOutputPort());
  support_mapper->ScalarVisibilityOff();
  support_actor_ = vtkSmartPointer<vtkActor>::New();
  support_actor_->SetMapper(support_mapper);
  support_actor_->GetProperty()->SetColor(0.4, 0.7, 1.0);
  support_actor_->GetProperty()->SetOpacity(0.15);
  support_actor_->PickableOff();
  support_actor_->VisibilityOff();
  renderer_->AddActor(support_actor_);

  // The ctrl + drag rectangle, in display pixels over everything.
  band_ = vtkSmartPointer<vtkPolyData>::New();
  band_->SetPoints(vtkNew<vtkPoints>());
  vtkNew<vtkCellArray> band_line;
  const vtkIdType loop[5] = {0, 1, 2, 3, 0};
  band_line->InsertNextCell(5, loop);
  band_->SetLines(band_line);
  band_->GetPoints()->SetNumberOfPoints(4);
  vtkNew<vtkPolyDataMapper2D> band_mapper;
  band_mapper->SetInputData(band_);
  band_actor_ = vtkSmartPointer<vtkActor2D>::New();
  band_actor_->SetMapper(band_mapper);
  band_actor_->GetProperty()->SetColor(1.0, 0.9, 0.3);
  band_actor_->GetProperty()->SetLineWidth(2);
  band_actor_->VisibilityOff();
  renderer_->AddActor2D(band_actor_);

  // The legend of "colour by displacement": the same map as the vertex colours, 0 .. the largest.
  legend_lut_ = vtkSmartPointer<vtkLookupTable>::New();
  legend_lut_->SetNumberOfTableValues(256);
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0;
    legend_lut_->SetTableValue(i, 0.2 + 0.8 * t, 0.3 + 0.5 * (1 - std::abs(2 * t - 1)), 1.0 - 0.8 * t, 1.0);
  }
  legend_lut_->Build();
  legend_ = vtkSmartPointer<vtkScalarBarActor>::New();
  legend_->SetLookupTable(legend_lut_);
  legend_->SetTitle("|displacement|");
  legend_->SetNumberOfLabels(5);
  legend_->SetLabelFormat("%.3g");
  legend_->SetMaximumWidthInPixels(90);
  legend_->SetPosition(0.02, 0.1);
  legend_->SetWidth(0.1);
  legend_->SetHeight(0.6);
  legend_->GetTitleTextProperty()->SetFontSize(14);
  legend_->GetLabelTextProperty()->SetFontSize(12);
  legend_->VisibilityOff();
  renderer_->AddActor2D(legend_);

  setCentralWidget(view_);
}

void PickerWindow::build_ui() {
  auto* dock = new QDockWidget("Deformation", this);
  dock->setObjectName("deformation");
  dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  auto* panel = new QWidget(dock);
  panel->setMinimumWidth(560);
  auto* layout = new QVBoxLayout(panel);

  table_ = new QTableWidget(0, 7, panel);
  table_->setObjectName("controls");
  table_->setHorizontalHeaderLabels({"sx", "sy", "sz", "dx", "dy", "dz", "pin"});
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  table_->horizontalHeader()->setSectionResizeMode(6, QHeaderView::ResizeToContents);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  layout->addWidget(new QLabel("Control vectors (source, destination)", panel));
  layout->addWidget(table_, 1);
  connect(table_, &QTableWidget::itemSelectionChanged, this, [this] {
    if (updating_) return;
    const auto rows = table_->selectionModel()->selectedRows();
    selected_ = rows.isEmpty() ? -1 : rows.front().row();
    refresh_view();
  });
  connect(table_, &QTableWidget::itemChanged, this, [this](QTableWidgetItem* item) {
    if (updating_) return;
    State next = doc_.state();
    const auto row = std::size_t(item->row());
    if (row >= next.controls.size()) return;
    auto& c = next.controls[row];
    if (item->column() == 6) {
      c.pinned = item->checkState() == Qt::Checked;
      if (c.pinned) c.destination = c.source;
      edit(next, c.pinned ? "Pin control" : "Unpin control");
      return;
    }
    bool ok = false;
    const double v = item->text().toDouble(&ok);
    if (!ok || !std::isfinite(v)) {
      show_error(QString("'%1' is not a number (row %2, column %3)")
                     .arg(item->text())
                     .arg(item->row() + 1)
                     .arg(table_->horizontalHeaderItem(item->column())->text()));
      refresh_table();
      return;
    }
    const int col = item->column();
    if (col < 3) {
      c.source[col] = v;
      if (c.pinned) c.destination = c.source;
    } else {
      c.destination[col - 3] = v;
      if (c.pinned) c.source = c.destination;
    }
    edit(next, "Edit coordinates");
  });

  auto* del = new QPushButton("Delete", panel);
  del->setObjectName("delete");
  connect(del, &QPushButton::clicked, this, [this] { delete_selected(); });
  auto* clear_region = new QPushButton("Whole mesh", panel);
  clear_region->setObjectName("clearRegion");
  clear_region->setToolTip("Deform the whole mesh again (ctrl + drag selects an active area)");
  connect(clear_region, &QPushButton::clicked, this, [this] {
    State next = doc_.state();
    next.region.clear();
    edit(next, "Whole mesh");
  });
  auto* row = new QHBoxLayout;
  row->addWidget(del);
  row->addWidget(clear_region);
  layout->addLayout(row);
  region_label_ = new QLabel(panel);
  layout->addWidget(region_label_);

  auto* form = new QFormLayout;
  radius_ = new gui::NumberBox(panel);
  radius_->setObjectName("radius");
  radius_->setRange(1e-9, 1e12);
  radius_->setKeyboardTracking(false);
  radius_fraction_ = new QDoubleSpinBox(panel);
  radius_fraction_->setObjectName("radiusFraction");
  radius_fraction_->setDecimals(2);
  radius_fraction_->setRange(0.01, 1e12);
  radius_fraction_->setSuffix(" % of size");
  radius_fraction_->setKeyboardTracking(false);
  radius_slider_ = new QSlider(Qt::Horizontal, panel);
  radius_slider_->setObjectName("radiusSlider");
  radius_slider_->setRange(0, 1000);
  auto* radius_row = new QHBoxLayout;
  radius_row->addWidget(radius_);
  radius_row->addWidget(radius_fraction_);
  form->addRow("Radius R", radius_row);
  form->addRow("", radius_slider_);
  connect(radius_, qOverload<double>(&QDoubleSpinBox::valueChanged), this,
          [this] { options_changed(kMergeRadius, "Radius"); });
  connect(radius_fraction_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double pct) {
    if (updating_) return;
    updating_ = true;
    radius_->setValue(pct / 100.0 * doc_.diagonal());
    updating_ = false;
    options_changed(kMergeRadius, "Radius");
  });
  connect(radius_slider_, &QSlider::valueChanged, this, [this](int v) {
    if (updating_) return;
    updating_ = true;
    radius_->setValue(fraction_from_slider(v) * doc_.diagonal());
    updating_ = false;
    options_changed(kMergeRadius, "Radius");
  });

  kernel_ = new QComboBox(panel);
  kernel_->setObjectName("kernel");
  kernel_->addItems({"C0  ψ2,0 = (1-r)²", "C2  ψ3,1 = (1-r)⁴(4r+1)", "C4  ψ4,2", "C6  ψ5,3"});
  form->addRow("Kernel", kernel_);
  connect(kernel_, qOverload<int>(&QComboBox::currentIndexChanged), this, [this] { options_changed(-1, "Kernel"); });
  polynomial_ = new QComboBox(panel);
  polynomial_->setObjectName("polynomial");
  for (const auto& e : NameTable<Polynomial>::entries)
    polynomial_->addItem(QString::fromUtf8(e.name.data(), int(e.name.size())));
  form->addRow("Polynomial", polynomial_);
  connect(polynomial_, qOverload<int>(&QComboBox::currentIndexChanged), this,
          [this] { options_changed(-1, "Polynomial"); });
  phase_ = new QSlider(Qt::Horizontal, panel);
  phase_->setObjectName("phase");
  phase_->setRange(0, 100);
  phase_label_ = new QLabel(panel);
  auto* phase_row = new QHBoxLayout;
  phase_row->addWidget(phase_);
  phase_row->addWidget(phase_label_);
  form->addRow("Phase", phase_row);
  connect(phase_, &QSlider::valueChanged, this, [this] { options_changed(kMergePhase, "Phase"); });
  layout->addLayout(form);

  show_supports_ = new QCheckBox("Show support spheres (S)", panel);
  show_supports_->setObjectName("supports");
  colour_displacement_ = new QCheckBox("Colour by displacement (D)", panel);
  colour_displacement_->setObjectName("colourDisplacement");
  connect(show_supports_, &QCheckBox::toggled, this, [this] { refresh_view(); });
  connect(colour_displacement_, &QCheckBox::toggled, this, [this] { refresh_view(); });
  layout->addWidget(show_supports_);
  layout->addWidget(colour_displacement_);

  auto* messages = gui::make_message_box(panel, 170);
  error_ = gui::add_message(messages, "error", "#b03030");
  fold_warning_ = gui::add_message(messages, "foldWarning", "#f0c040");
  hint_ = gui::add_message(messages, "hint", "#a8d0f0");
  layout->addWidget(messages);

  dock->setWidget(panel);
  addDockWidget(Qt::RightDockWidgetArea, dock);
  timing_ = new QLabel(this);
  statusBar()->addPermanentWidget(timing_);
  statusBar()->showMessage("Open a mesh (ctrl+O or drop a file here)");
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

// ---------------------------------------------------------------------------------------------------

bool PickerWindow::open_mesh(const QString& path) {
  try {
    doc_.load_mesh(path.toStdString());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  undo_.clear();
  selected_ = -1;
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
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  deformation_path_ = path;
  statusBar()->showMessage("Loaded " + path, 5000);
  return true;
}

bool PickerWindow::load_controls(const QString& path, std::optional<double> radius) {
  if (!doc_.has_mesh()) {
    show_error("Open a mesh before loading controls");
    return false;
  }
  QString proposal;
  try {
    const auto c = io::read_controls(path.toStdString());
    io::DeformationSpec spec = doc_.deformation();
    spec.sources = c.sources;
    spec.destinations = c.destinations;
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
  statusBar()->showMessage(proposal.isEmpty()
                               ? "Loaded " + path
                               : QString("Radius R = %1 proposed (see the blue box)").arg(doc_.state().radius),
                           10000);
  return true;
}

bool PickerWindow::save_deformation(const QString& path) {
  try {
    io::write_deformation(path.toStdString(), doc_.deformation());
  } catch (const std::exception& e) {
    show_error(e.what());
    return false;
  }
  undo_.setClean();
  deformation_path_ = path;
  clear_error();
  statusBar()->showMessage("Saved " + path, 5000);
  return true;
}

bool PickerWindow::save_controls(const QString& path) {
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

void PickerWindow::options_changed(int merge_id, const QString& what) {
  if (updating_) return;
  State next = doc_.state();
  next.radius = radius_->value();
  next.kernel = NameTable<Kernel>::entries[std::size_t(std::max(0, kernel_->currentIndex()))].value;
  next.polynomial = NameTable<Polynomial>::entries[std::size_t(std::max(0, polynomial_->currentIndex()))].value;
  next.phase = phase_->value() / 100.0;
  edit(next, what, merge_id);
}

QString PickerWindow::fold_warning() const { return fold_warning_->isHidden() ? QString() : fold_warning_->text(); }

QString PickerWindow::error_text() const { return error_->isHidden() ? QString() : error_->text(); }

void PickerWindow::show_error(const QString& message) {
  error_->setText(message);
  error_->show();
  statusBar()->showMessage(message.section('\n', 0, 0), 10000);
}

void PickerWindow::clear_error() {
  error_->clear();
  error_->hide();
}

// ---------------------------------------------------------------------------------------------------

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

void PickerWindow::refresh_options() {
  updating_ = true;
  const auto& s = doc_.state();
  radius_->setValue(s.radius);
  radius_fraction_->setValue(100.0 * s.radius / doc_.diagonal());
  radius_slider_->setValue(slider_from_fraction(s.radius / doc_.diagonal()));
  kernel_->setCurrentIndex(int(table_index(s.kernel)));
  polynomial_->setCurrentIndex(int(table_index(s.polynomial)));
  phase_->setValue(int(std::lround(s.phase * 100)));
  phase_label_->setText(QString::number(s.phase, 'f', 2));
  updating_ = false;
}

void PickerWindow::refresh_table() {
  updating_ = true;
  const auto& cs = doc_.state().controls;
  table_->setRowCount(int(cs.size()));
  for (int r = 0; r < int(cs.size()); ++r) {
    const auto& c = cs[std::size_t(r)];
    const double v[6] = {c.source.x(),      c.source.y(),      c.source.z(),
                         c.destination.x(), c.destination.y(), c.destination.z()};
    for (int k = 0; k < 6; ++k) {
      auto* item = new QTableWidgetItem(number(v[k]));
      table_->setItem(r, k, item);
    }
    auto* pin = new QTableWidgetItem;
    pin->setFlags(Qt::ItemIsUserCheckable | Qt::ItemIsEnabled | Qt::ItemIsSelectable);
    pin->setCheckState(c.pinned ? Qt::Checked : Qt::Unchecked);
    table_->setItem(r, 6, pin);
  }
  if (selected_ >= 0 && selected_ < int(cs.size()))
    table_->selectRow(selected_);
  else
    table_->clearSelection();
  updating_ = false;
}

void PickerWindow::refresh_view() {
  if (!doc_.has_mesh()) {
    view_->renderWindow()->Render();
    return;
  }
  const auto& s = doc_.state();
  const auto& pos = doc_.deformed();
  vtkPoints* pts = mesh_->GetPoints();
  pts->SetNumberOfPoints(vtkIdType(pos.size()));
  for (std::size_t i = 0; i < pos.size(); ++i) pts->SetPoint(vtkIdType(i), pos[i].data());
  pts->Modified();

  // Colours: the mesh's, dimmed outside the active area, or a blue-to-red map of |displacement|.
  vtkNew<vtkUnsignedCharArray> rgb;
  rgb->SetNumberOfComponents(3);
  rgb->SetNumberOfTuples(vtkIdType(pos.size()));
  std::vector<char> active(pos.size(), s.region.empty() ? 1 : 0);
  for (const auto v : s.region) active[v] = 1;
  const bool by_displacement = colour_displacement_->isChecked();
  std::vector<double> mag;
  double top = 0;
  if (by_displacement) {
    mag = doc_.displacement_magnitudes();
    for (const double m : mag) top = std::max(top, m);
  }
  legend_lut_->SetTableRange(0, top > 0 ? top : 1);
  // Folded places (det dT/dx <= 0: space turned inside out) in magenta, with a warning.
  const FoldReport folds = doc_.folds();
  std::vector<char> folded(pos.size(), 0);
  for (const auto v : folds.folded_vertices) folded[v] = 1;
  if (folds.folded > 0 || folds.edge_flipped > 0) {
    const QString edge =
        folds.edge_flipped == 0
            ? QString()
            : QString(" %1 of the triangles across the active area's edge turn over.").arg(folds.edge_flipped);
    fold_warning_->setText(QString("%1 %2 over (det dT/dx <= 0, shown in magenta).%3 The map is fold-free up "
                                   "to phase %4: lower the phase or the displacements, or raise the radius.")
                               .arg(folds.folded)
                               .arg(folds.folded == 1 ? "point folds" : "points fold")
                               .arg(edge)
                               .arg(folds.fold_free_phase, 0, 'f', 3));
    fold_warning_->show();
  } else {
    fold_warning_->hide();
  }
  for (std::size_t i = 0; i < pos.size(); ++i) {
    double c[3] = {0.85, 0.8, 0.72};
    if (by_displacement) legend_lut_->GetColor(mag[i], c);
    if (!active[i]) c[0] = c[1] = c[2] = 0.45;
    if (folded[i]) c[0] = 1.0, c[1] = 0.1, c[2] = 0.9;
    rgb->SetTuple3(vtkIdType(i), 255 * c[0], 255 * c[1], 255 * c[2]);
  }
  mesh_->GetPointData()->SetScalars(rgb);
  mesh_->Modified();
  legend_->SetVisibility(by_displacement);
  mesh_actor_->GetProperty()->SetRepresentation(wireframe_ && wireframe_->isChecked() ? VTK_WIREFRAME : VTK_SURFACE);

  // Handles: source (green, or blue when pinned), destination (orange), the selected one yellow.
  const double size = 0.012 * doc_.diagonal();
  handle_glyph_->SetScaleFactor(2 * size);
  vtkNew<vtkPoints> hp;
  vtkNew<vtkUnsignedCharArray> hc;
  hc->SetNumberOfComponents(3);
  vtkNew<vtkPoints> lp;
  vtkNew<vtkCellArray> lc;
  vtkNew<vtkPoints> sp;
  for (std::size_t i = 0; i < s.controls.size(); ++i) {
    const auto& c = s.controls[i];
    const bool sel = int(i) == selected_;
    hp->InsertNextPoint(c.source.data());
    if (sel)
      hc->InsertNextTuple3(255, 240, 60);
    else if (c.pinned)
      hc->InsertNextTuple3(20, 20, 20);  // black: seen on the mesh and on every displacement colour
    else
      hc->InsertNextTuple3(60, 200, 90);
    sp->InsertNextPoint(c.source.data());
    if (!c.pinned && c.destination != c.source) {
      hp->InsertNextPoint(c.destination.data());
      if (sel)
        hc->InsertNextTuple3(255, 240, 60);
      else
        hc->InsertNextTuple3(255, 120, 40);
      const vtkIdType a = lp->InsertNextPoint(c.source.data()), b = lp->InsertNextPoint(c.destination.data());
      const vtkIdType ids[2] = {a, b};
      lc->InsertNextCell(2, ids);
    }
  }
  handles_->SetPoints(hp);
  handles_->GetPointData()->SetScalars(hc);
  handles_->Modified();
  lines_->SetPoints(lp);
  lines_->SetLines(lc);
  lines_->Modified();
  supports_->SetPoints(sp);
  supports_->Modified();
  support_glyph_->SetScaleFactor(s.radius);
  support_actor_->SetVisibility(show_supports_->isChecked() && !s.controls.empty());
  view_->renderWindow()->Render();
}

void PickerWindow::reset_camera(gui::View view) {
  double b[6] = {-1, 1, -1, 1, -1, 1};
  const auto& pos = doc_.deformed();
  if (!pos.empty()) {
    for (int k = 0; k < 3; ++k) b[2 * k] = b[2 * k + 1] = pos.front()[k];
    for (const auto& p : pos)
      for (int k = 0; k < 3; ++k) {
        b[2 * k] = std::min(b[2 * k], p[k]);
        b[2 * k + 1] = std::max(b[2 * k + 1], p[k]);
      }
  }
  gui::set_view(renderer_, b, view);
  view_->renderWindow()->Render();
}

void PickerWindow::show_band(int x0, int y0, int x1, int y1) {
  vtkPoints* p = band_->GetPoints();
  p->SetPoint(0, x0, y0, 0);
  p->SetPoint(1, x1, y0, 0);
  p->SetPoint(2, x1, y1, 0);
  p->SetPoint(3, x0, y1, 0);
  p->Modified();
  band_->Modified();
  band_actor_->VisibilityOn();
  view_->renderWindow()->Render();
}

void PickerWindow::hide_band() {
  band_actor_->VisibilityOff();
  view_->renderWindow()->Render();
}

bool PickerWindow::band_visible() const { return band_actor_->GetVisibility() != 0; }

QString PickerWindow::hint() const { return hint_->isHidden() ? QString() : hint_->text(); }

void PickerWindow::refresh_hints() {
  // What the numbers cannot show by themselves: a map that moves nothing, or moves the mesh far more
  // than any control asks (a polynomial extrapolating from too few controls).
  QStringList hints;
  if (!proposal_.isEmpty()) hints << proposal_;
  const auto& s = doc_.state();
  double longest = 0;
  for (const auto& c : s.controls) longest = std::max(longest, (c.destination - c.source).norm());
  if (longest > 0 && doc_.has_mesh()) {
    const auto mag = doc_.displacement_magnitudes();
    const double most = mag.empty() ? 0.0 : *std::max_element(mag.begin(), mag.end());
    if (most == 0) {
      hints << QString("No vertex moves: none lies within R = %1 of a moved control%2. Raise the radius.")
                   .arg(s.radius, 0, 'g', 4)
                   .arg(s.region.empty() ? QString() : QString(" inside the active area"));
    } else if (most > 2.0 * longest) {
      hints << QString(
                   "The mesh moves up to %1, %2 times the longest control vector (%3)%4. Check the result, or use "
                   "more controls%5.")
                   .arg(most, 0, 'g', 3)
                   .arg(most / longest, 0, 'f', 1)
                   .arg(longest, 0, 'g', 3)
                   .arg(s.polynomial == Polynomial::None
                            ? QString()
                            : QString(": the %1 polynomial extrapolates from the controls")
                                  .arg(QString::fromUtf8(name_of(s.polynomial).data(),
                                                         int(name_of(s.polynomial).size()))))
                   .arg(s.polynomial == Polynomial::None ? QString() : QString(" or polynomial 'none'"));
    }
  }
  hint_->setText(hints.join("\n"));
  hint_->setVisible(!hints.isEmpty());
}

// ---------------------------------------------------------------------------------------------------

QPointF PickerWindow::to_display(const Vec3& w) const {
  const Vec3 d = gui::world_to_display(renderer_, w);
  return {d.x(), d.y()};
}

bool PickerWindow::pick_surface(int x, int y, Vec3& hit) const {
  if (!doc_.has_mesh()) return false;
  vtkNew<vtkCellPicker> picker;
  picker->SetTolerance(0.0005);
  picker->PickFromListOn();
  picker->AddPickList(mesh_actor_);
  if (!picker->Pick(x, y, 0, renderer_)) return false;
  const double* p = picker->GetPickPosition();
  hit = Vec3(p[0], p[1], p[2]);
  return true;
}

int PickerWindow::handle_at(int x, int y) const {
  const auto& cs = doc_.state().controls;
  int best = -1;
  double best_d = 10.0;  // pixels
  for (std::size_t i = 0; i < cs.size(); ++i) {
    for (const Vec3& p : {cs[i].destination, cs[i].source}) {
      const QPointF d = to_display(p);
      const double dist = std::hypot(d.x() - x, d.y() - y);
      if (dist < best_d) {
        best_d = dist;
        best = int(i);
      }
      if (cs[i].pinned || cs[i].destination == cs[i].source) break;  // one handle
    }
  }
  return best;
}

void PickerWindow::select(int control) {
  selected_ = control < int(doc_.state().controls.size()) ? control : -1;
  refresh_table();
  refresh_view();
}

void PickerWindow::add_control(const Vec3& at, bool pinned) {
  State next = doc_.state();
  next.controls.push_back({at, at, pinned});
  if (edit(next, pinned ? "Add pinned point" : "Add control")) select(int(next.controls.size()) - 1);
}

void PickerWindow::begin_drag(int control) {
  dragging_ = control;
  frame_ms_.clear();
  drag_start_ = doc_.state();
  drag_depth_ = gui::world_to_display(renderer_, doc_.state().controls[std::size_t(control)].destination).z();
}

void PickerWindow::drag_to(int x, int y) {
  const auto start = std::chrono::steady_clock::now();
  // The destination follows the cursor in the plane through it parallel to the screen.
  const auto w = gui::display_to_world(renderer_, x, y, drag_depth_);
  if (!w) return;
  State next = doc_.state();
  next.controls[std::size_t(dragging_)].destination = *w;
  const Outcome o = doc_.apply(next);  // live, not yet an undo step
  if (!o.ok) {
    show_error(QString::fromStdString(o.error));
    return;
  }
  clear_error();
  refresh_view();
  refresh_table();
  // The interactive frame rate: whole frames (fit, evaluation, colours, drawing) over the last 10 moves.
  frame_ms_.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  if (frame_ms_.size() > 10) frame_ms_.erase(frame_ms_.begin());
  drag_fps_ = 1000.0 * double(frame_ms_.size()) / std::accumulate(frame_ms_.begin(), frame_ms_.end(), 0.0);
  timing_->setText(QString("fit %1 ms, evaluation %2 ms, %3 fps while dragging")
                       .arg(o.fit_ms, 0, 'f', 3)
                       .arg(o.eval_ms, 0, 'f', 3)
                       .arg(drag_fps_, 0, 'f', 0));
}

void PickerWindow::end_drag() {
  const State after = doc_.state();
  dragging_ = -1;
  if (after == drag_start_) return;
  undo_.push(new StateCommand(this, drag_start_, after, "Move destination", -1));
  refresh();
}

void PickerWindow::select_region(int x0, int y0, int x1, int y1) {
  if (!doc_.has_mesh()) return;
  const double lx = std::min(x0, x1), hx = std::max(x0, x1), ly = std::min(y0, y1), hy = std::max(y0, y1);
  State next = doc_.state();
  next.region.clear();
  const auto& rest = doc_.rest();
  for (std::size_t i = 0; i < rest.size(); ++i) {
    const QPointF d = to_display(doc_.deformed()[i]);
    if (d.x() >= lx && d.x() <= hx && d.y() >= ly && d.y() <= hy) next.region.push_back(std::uint32_t(i));
  }
  if (next.region.empty()) {
    statusBar()->showMessage("No vertex in the selected rectangle", 5000);
    return;
  }
  edit(next, "Select active area");
}

void PickerWindow::delete_selected() {
  if (selected_ < 0 || selected_ >= int(doc_.state().controls.size())) return;
  State next = doc_.state();
  next.controls.erase(next.controls.begin() + selected_);
  const int was = selected_;
  selected_ = -1;
  if (!edit(next, "Delete control")) selected_ = was;
}

bool PickerWindow::save_screenshot(const QString& path) { return gui::save_window_png(this, view_, path); }

// ---------------------------------------------------------------------------------------------------

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
  e->accept();
}

}  // namespace csrbf::picker
