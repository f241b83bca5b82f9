// Pieces the Qt programs (Picker, Composer) share: the display at start-up, the error box, the undo
// actions, screenshots, and conversions between world, VTK display and Qt widget coordinates.
#pragma once

#include "csrbf/neighbor_index.hpp"
#include "csrbf/render/process.hpp"

#include <QPoint>
#include <QString>

#include <memory>
#include <optional>

class QLabel;
class QMenu;
class QUndoStack;
class QWidget;
class QVTKOpenGLNativeWidget;
class vtkRenderer;

namespace csrbf::gui {

/// Call before QApplication: without DISPLAY, starts a private Xvfb (Qt and Debian's VTK need X).
/// Returns null when DISPLAY is set; prints "program: error: ..." and returns null with ok = false
/// when no display can be had.
std::unique_ptr<render::Display> ensure_display(const char* program, bool& ok);

/// A red box for messages, hidden until shown.
QLabel* make_error_label(QWidget* parent);
/// Undo (Ctrl+Z) and redo (Ctrl+Shift+Z, Ctrl+Y) of a stack, added to a menu.
void add_undo_actions(QMenu* menu, QUndoStack& stack, QWidget* owner);
/// Renders the VTK view and saves the whole window as a PNG.
bool save_window_png(QWidget* window, QVTKOpenGLNativeWidget* view, const QString& path);

/// VTK display coordinates (pixels from the bottom left, z the depth) of a world point.
Vec3 world_to_display(vtkRenderer* r, const Vec3& world);
/// The world point at display (x, y) and depth z; empty at infinity.
std::optional<Vec3> display_to_world(vtkRenderer* r, double x, double y, double z);
/// Qt widget coordinates of VTK display coordinates in a view.
QPoint widget_point(QVTKOpenGLNativeWidget* view, double display_x, double display_y);

}  // namespace csrbf::gui
