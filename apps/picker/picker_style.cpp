// The Picker's mouse in the 3D view (PickerStyle): what a press, a move and a release do.
#include "picker_style.hpp"

#include "picker_window.hpp"

#include <vtkObjectFactory.h>
#include <vtkRenderWindowInteractor.h>

#include <cstdlib>

namespace csrbf::picker {

vtkStandardNewMacro(PickerStyle);

void PickerStyle::OnLeftButtonDown() {
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

void PickerStyle::OnMouseMove() {
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

void PickerStyle::OnLeftButtonUp() {
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

}  // namespace csrbf::picker
