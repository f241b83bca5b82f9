#include "gui_common.hpp"

#include <QAction>
#include <QApplication>
#include <QLabel>
#include <QMenu>
#include <QPixmap>
#include <QUndoStack>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkRenderWindow.h>
#include <vtkRenderer.h>

#include <cmath>
#include <cstdlib>
#include <iostream>

namespace csrbf::gui {

std::unique_ptr<render::Display> ensure_display(const char* program, bool& ok) {
  ok = true;
  const char* d = std::getenv("DISPLAY");
  if (d && *d) return nullptr;
  try {
    return std::make_unique<render::Display>();
  } catch (const std::exception& e) {
    std::cerr << program << ": error: " << e.what() << '\n';
    ok = false;
    return nullptr;
  }
}

QLabel* make_error_label(QWidget* parent) {
  auto* l = new QLabel(parent);
  l->setObjectName("error");
  l->setWordWrap(true);
  l->setStyleSheet("QLabel { color: white; background: #b03030; padding: 6px; border-radius: 4px; }");
  l->hide();
  return l;
}

void add_undo_actions(QMenu* menu, QUndoStack& stack, QWidget* owner) {
  QAction* undo = stack.createUndoAction(owner, "&Undo");
  undo->setShortcut(QKeySequence::Undo);
  QAction* redo = stack.createRedoAction(owner, "&Redo");
  redo->setShortcuts({QKeySequence::Redo, QKeySequence("Ctrl+Y")});
  menu->addAction(undo);
  menu->addAction(redo);
}

bool save_window_png(QWidget* window, QVTKOpenGLNativeWidget* view, const QString& path) {
  view->renderWindow()->Render();
  QApplication::processEvents();
  return window->grab().save(path, "PNG");
}

Vec3 world_to_display(vtkRenderer* r, const Vec3& w) {
  r->SetWorldPoint(w.x(), w.y(), w.z(), 1.0);
  r->WorldToDisplay();
  const double* d = r->GetDisplayPoint();
  return {d[0], d[1], d[2]};
}

std::optional<Vec3> display_to_world(vtkRenderer* r, double x, double y, double z) {
  r->SetDisplayPoint(x, y, z);
  r->DisplayToWorld();
  const double* w = r->GetWorldPoint();
  if (w[3] == 0) return std::nullopt;
  return Vec3(w[0] / w[3], w[1] / w[3], w[2] / w[3]);
}

QPoint widget_point(QVTKOpenGLNativeWidget* view, double x, double y) {
  const double ratio = view->devicePixelRatioF();  // VTK counts device pixels, y upwards
  return {int(std::lround(x / ratio)), int(std::lround((view->height() * ratio - 1 - y) / ratio))};
}

}  // namespace csrbf::gui
