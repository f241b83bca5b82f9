// The Picker's 3D view: the scene (mesh, handles, support spheres, the ctrl + drag rectangle, the
// legend), its refresh from the state, the camera, and the edits made with the mouse in it.
#include "picker_window.hpp"

#include "picker_style.hpp"
#include "picker_undo.hpp"

#include "gui_common.hpp"

#include <QAction>
#include <QCheckBox>
#include <QLabel>
#include <QStatusBar>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkActor.h>
#include <vtkActor2D.h>
#include <vtkCellArray.h>
#include <vtkCellPicker.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGlyph3D.h>
#include <vtkLookupTable.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataMapper2D.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkProperty2D.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSphereSource.h>
#include <vtkTextProperty.h>
#include <vtkUnsignedCharArray.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <vector>

namespace csrbf::picker {

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
  legend_->SetPosition(0.06, 0.1);
  legend_->SetWidth(0.1);
  legend_->SetHeight(0.6);
  // Fonts at their sizes, the title apart from the top value: scaled to the bar's width, the title
  // shrank to 7 pixels and overlapped that value (the new user's trial).
  legend_->UnconstrainedFontSizeOn();
  legend_->SetVerticalTitleSeparation(10);
  legend_->SetMaximumWidthInPixels(130);
  legend_->GetTitleTextProperty()->SetFontSize(14);
  legend_->GetLabelTextProperty()->SetFontSize(12);
  legend_->VisibilityOff();
  renderer_->AddActor2D(legend_);

  setCentralWidget(view_);
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

void PickerWindow::frame_all() {
  renderer_->ResetCamera();
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
  if (edit(next, "Select active area")) area_from_file_ = false;
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

}  // namespace csrbf::picker
