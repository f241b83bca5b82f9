// The Composer's mouse in the 3D view (ComposerStyle): what a press, a move and a release do.
#include "composer_style.hpp"

#include "composer_window.hpp"

#include <vtkObjectFactory.h>
#include <vtkRenderWindowInteractor.h>

#include <cstdlib>

namespace csrbf::composer {

vtkStandardNewMacro(ComposerStyle);

void ComposerStyle::OnLeftButtonDown() {
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

void ComposerStyle::OnMouseMove() {
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

void ComposerStyle::OnLeftButtonUp() {
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

}  // namespace csrbf::composer
