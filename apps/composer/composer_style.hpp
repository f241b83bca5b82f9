// The Composer's mouse in the 3D view: a VTK interactor style that turns clicks and drags into key
// edits (select, move, add a trajectory key; turn the object) or camera moves.
#pragma once

#include <vtkInteractorStyleTrackballCamera.h>

namespace csrbf::composer {

class ComposerWindow;

/// Mouse in the 3D view: left drag on a trajectory key moves it (in the plane through it facing the
/// screen); left click on a key selects it; shift + left click adds a key at the current time under
/// the cursor; ctrl + left drag turns the selected object (an orientation key at the current time);
/// otherwise VTK's trackball camera (orbit, middle pan, wheel zoom).
class ComposerStyle : public vtkInteractorStyleTrackballCamera {
 public:
  static ComposerStyle* New();
  vtkTypeMacro(ComposerStyle, vtkInteractorStyleTrackballCamera) ComposerWindow* window = nullptr;

  // VTK's own keys (w wireframe, 3 stereo, e/q quit, ...) are off: the menus hold every key.
  void OnChar() override {}

  void OnLeftButtonDown() override;
  void OnMouseMove() override;
  void OnLeftButtonUp() override;

 private:
  int press_[2] = {0, 0}, last_[2] = {0, 0};
  bool moved_ = false, shift_ = false, rotating_ = false;
};

}  // namespace csrbf::composer
