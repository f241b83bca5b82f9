// The Picker's mouse in the 3D view: a VTK interactor style that turns clicks and drags into the
// window's edits (add a control, move a destination, select the active area) or camera moves.
#pragma once

#include <vtkInteractorStyleTrackballCamera.h>

namespace csrbf::picker {

class PickerWindow;

/// Mouse: left click on the surface adds a control (shift: pinned); left drag on a handle moves its
/// destination; left drag elsewhere orbits; middle drag or shift + left drag pans; wheel or right drag
/// zooms; ctrl + left drag selects the active area.
class PickerStyle : public vtkInteractorStyleTrackballCamera {
 public:
  static PickerStyle* New();
  vtkTypeMacro(PickerStyle, vtkInteractorStyleTrackballCamera) PickerWindow* window = nullptr;

  void OnLeftButtonDown() override;
  void OnMouseMove() override;
  void OnLeftButtonUp() override;
  // VTK's own keys (w wireframe, 3 stereo, e/q quit, p pick, ...) are off: the menus hold every key.
  void OnChar() override {}

 private:
  int press_[2] = {0, 0};
  bool moved_ = false, shift_ = false, banding_ = false;
};

}  // namespace csrbf::picker
