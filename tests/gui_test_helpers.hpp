// QTest helpers shared by the GUI tests.
#pragma once

#include <QApplication>
#include <QPoint>
#include <QTest>
#include <QWidget>

#include "gui_common.hpp"

namespace csrbf::test {

/// Shows a window without its unsaved-changes prompt and makes it active (keyboard shortcuts go to
/// the active window); false if the X server never exposed or activated it.
inline bool show_for_test(QWidget& w, int width, int height) {
  w.setProperty("noPrompt", true);
  w.resize(width, height);
  w.show();
  if (!QTest::qWaitForWindowExposed(&w)) return false;
  w.activateWindow();
  return QTest::qWaitForWindowActive(&w);
}

/// Qt widget coordinates of a world point in a window's 3D view (windows with to_display and view).
template <class Window, class Point>
QPoint widget_point(Window& w, const Point& p) {
  const QPointF d = w.to_display(p);
  return gui::widget_point(w.view(), d.x(), d.y());
}

/// Left-button drag in steps, with the modifiers held; events processed after the release.
inline void drag(QWidget* on, const QPoint& from, const QPoint& to, Qt::KeyboardModifiers mods = Qt::NoModifier) {
  QTest::mousePress(on, Qt::LeftButton, mods, from);
  for (int k = 1; k <= 8; ++k) QTest::mouseMove(on, from + (to - from) * k / 8, 5);
  QTest::mouseRelease(on, Qt::LeftButton, mods, to);
  QApplication::processEvents();
}

}  // namespace csrbf::test
