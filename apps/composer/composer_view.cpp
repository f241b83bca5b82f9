// The Composer's 3D view: the scene and its overlays (trajectories, keys, orientation marks, the
// scene camera's frame), frames at a time, the cameras, key drags with the mouse, screenshots and movies.
#include "composer_window.hpp"

#include "composer_style.hpp"
#include "composer_undo.hpp"

#include "csrbf/render/movie.hpp"
#include "csrbf/render/scene_renderer.hpp"
#include "gui_common.hpp"

#include <QAction>
#include <QApplication>
#include <QFileInfo>
#include <QLabel>
#include <QListWidget>
#include <QProgressDialog>
#include <QSlider>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkActor.h>
#include <vtkActorCollection.h>
#include <vtkCamera.h>
#include <vtkCameraActor.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGlyph3D.h>
#include <vtkNew.h>
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
#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

namespace csrbf::composer {

using Clock = std::chrono::steady_clock;

void ComposerWindow::build_view() {
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

void ComposerWindow::apply_wireframe() {
  if (!scene_renderer_ || !wireframe_) return;
  vtkActorCollection* actors = scene_renderer_->renderer()->GetActors();
  actors->InitTraversal();
  while (vtkActor* a = actors->GetNextActor())
    if (a != curve_actor_ && a != handle_actor_ && a != frame_actor_ &&
        static_cast<vtkProp*>(a) != static_cast<vtkProp*>(camera_actor_.Get()))
      a->GetProperty()->SetRepresentation(wireframe_->isChecked() ? VTK_WIREFRAME : VTK_SURFACE);
}

void ComposerWindow::frame_all() {
  if (!scene_renderer_) return;
  scene_renderer_->renderer()->ResetCamera();
  view_->renderWindow()->Render();
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

}  // namespace csrbf::composer
