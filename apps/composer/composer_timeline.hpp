// The Composer's timeline: the selected object's keys against time, under the 3D view.
#pragma once

#include <QWidget>

namespace csrbf::composer {

class ComposerWindow;

/// Rows of key marks (position, orientation, each deformation's phase) against time, with the
/// current time as a line. Click: scrub; drag a mark: move that key in time.
class Timeline : public QWidget {
  Q_OBJECT
 public:
  explicit Timeline(ComposerWindow* w);
  QSize sizeHint() const override { return {600, 110}; }
  /// x pixel of time t, and back.
  double x_of(double t) const;
  double t_of(double x) const;
  /// Row y centre of a track row (0: position, 1: orientation, 2 + d: deformation d).
  int y_of(int row) const { return 30 + 20 * row; }
  /// Height that shows every row of the selected object and the seconds ruler.
  int needed_height() const;
  /// The time a dragged mark of `row`, key `key`, may take at x: on a frame, and stopped one frame
  /// short of its neighbours (a mark never jumps over another).
  double drag_limit(int row, int key, double x) const;

 protected:
  void paintEvent(QPaintEvent*) override;
  void mousePressEvent(QMouseEvent*) override;
  void mouseMoveEvent(QMouseEvent*) override;
  void mouseReleaseEvent(QMouseEvent*) override;

 private:
  ComposerWindow* w_;
  int drag_row_ = -1, drag_key_ = -1;
  double drag_time_ = 0;
  QPoint drag_from_;      // where the press on a key was
  bool dragged_ = false;  // the pointer has gone the drag distance since
};

}  // namespace csrbf::composer
