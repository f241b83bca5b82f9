// The Composer's timeline (Timeline): its drawing, and the mouse that scrubs and moves keys in time.
#include "composer_timeline.hpp"

#include "composer_window.hpp"

#include <QApplication>
#include <QMouseEvent>
#include <QPainter>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace csrbf::composer {

Timeline::Timeline(ComposerWindow* w) : QWidget(w), w_(w) {
  setObjectName("timeline");
  setMinimumHeight(needed_height());
  setMouseTracking(false);
}

namespace {
constexpr double kLeft = 96.0, kRight = 22.0;  // room for row names, and for the last second's label

Document::Track track_of(int row) {
  return row == 0 ? Document::Track::Position : row == 1 ? Document::Track::Orientation : Document::Track::Phase;
}
}  // namespace

double Timeline::x_of(double t) const {
  const double d = w_->doc_.duration();
  return kLeft + (width() - kLeft - kRight) * (d > 0 ? t / d : 0.0);
}

double Timeline::t_of(double x) const {
  const double d = w_->doc_.duration();
  return std::clamp((x - kLeft) / std::max(1.0, width() - kLeft - kRight) * d, 0.0, d);
}

int Timeline::needed_height() const {
  const int o = w_->object_;
  const std::size_t defs = o >= 0 && o < int(w_->doc_.object_count()) ? w_->doc_.deformation_count(std::size_t(o)) : 0;
  return y_of(int(2 + defs)) + 4;
}

double Timeline::drag_limit(int row, int key, double x) const {
  const auto times = w_->doc_.key_times(std::size_t(w_->object_), track_of(row), std::size_t(std::max(0, row - 2)));
  const double frame = 1.0 / w_->doc_.fps();
  double t = w_->doc_.snap(t_of(x));
  if (key > 0) t = std::max(t, w_->doc_.snap(times[std::size_t(key) - 1]) + frame);
  if (key + 1 < int(times.size())) t = std::min(t, w_->doc_.snap(times[std::size_t(key) + 1]) - frame);
  return std::max(t, 0.0);
}

void Timeline::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(45, 47, 52));
  p.setRenderHint(QPainter::Antialiasing);
  const double d = w_->doc_.duration();
  // Seconds ruler: a line a second, its label centred above it.
  p.setPen(QColor(120, 120, 130));
  const QFontMetrics fm(font());
  for (int s = 0; s <= int(d + 1e-9); ++s) {
    const double x = x_of(s);
    p.drawLine(QPointF(x, 16), QPointF(x, height()));
  }
  const int o = w_->object_;
  if (o >= 0 && o < int(w_->doc_.object_count())) {
    std::vector<std::pair<QString, std::vector<double>>> rows;
    rows.push_back({"position", w_->doc_.key_times(std::size_t(o), Document::Track::Position)});
    rows.push_back({"rotation", w_->doc_.key_times(std::size_t(o), Document::Track::Orientation)});
    for (std::size_t k = 0; k < w_->doc_.deformation_count(std::size_t(o)); ++k)
      rows.push_back({QString::fromStdString(w_->doc_.deformation_name(std::size_t(o), k)),
                      w_->doc_.key_times(std::size_t(o), Document::Track::Phase, k)});
    for (int r = 0; r < int(rows.size()); ++r) {
      const int y = y_of(r);
      p.setPen(r >= 2 && r - 2 == w_->deformation_ ? QColor(255, 240, 120) : QColor(200, 200, 210));
      p.drawText(QPointF(4, y + 4), fm.elidedText(rows[std::size_t(r)].first, Qt::ElideRight, int(kLeft) - 10));
      const QColor colour = r == 0 ? QColor(255, 170, 60) : r == 1 ? QColor(90, 170, 255) : QColor(120, 220, 120);
      for (int k = 0; k < int(rows[std::size_t(r)].second.size()); ++k) {
        const double t = (r == drag_row_ && k == drag_key_) ? drag_time_ : rows[std::size_t(r)].second[std::size_t(k)];
        const bool sel = (r == 0 && k == w_->key_) || (r >= 2 && r - 2 == w_->deformation_ && k == w_->phase_key_);
        const double x = x_of(t);
        QPolygonF diamond({QPointF(x, y - 6), QPointF(x + 6, y), QPointF(x, y + 6), QPointF(x - 6, y)});
        p.setBrush(sel ? QColor(255, 240, 60) : colour);
        p.setPen(Qt::black);
        p.drawPolygon(diamond);
      }
    }
  }
  // The labels in a band at the top of what the scroll area shows: in sight however the rows scroll.
  const int top = visibleRegion().boundingRect().top();
  p.fillRect(QRect(0, top, width(), 17), QColor(45, 47, 52));
  p.setPen(QColor(150, 150, 160));
  for (int s = 0; s <= int(d + 1e-9); ++s) {
    const QString label = QString::number(s) + "s";
    p.drawText(QPointF(x_of(s) - fm.horizontalAdvance(label) / 2.0, top + 13), label);
  }
  p.setPen(QPen(QColor(255, 80, 80), 2));
  const double x = x_of(w_->time_);
  p.drawLine(QPointF(x, 0), QPointF(x, height()));
}

void Timeline::mousePressEvent(QMouseEvent* e) {
  const int o = w_->object_;
  drag_row_ = drag_key_ = -1;
  if (o >= 0 && o < int(w_->doc_.object_count())) {
    const std::size_t defs = w_->doc_.deformation_count(std::size_t(o));
    for (int r = 0; r < int(2 + defs) && drag_key_ < 0; ++r) {
      if (std::abs(e->pos().y() - y_of(r)) > 7) continue;
      const auto times = w_->doc_.key_times(std::size_t(o), track_of(r), std::size_t(std::max(0, r - 2)));
      for (int k = 0; k < int(times.size()); ++k)
        if (std::abs(e->pos().x() - x_of(times[std::size_t(k)])) <= 7) {
          drag_row_ = r;
          drag_key_ = k;
          drag_time_ = times[std::size_t(k)];
          drag_from_ = e->pos();
          dragged_ = false;
          if (r == 0) w_->select_key(k);
          if (r >= 2) w_->select_phase_key(r - 2, k);
          break;
        }
      if (drag_key_ < 0 && r >= 2 && e->pos().x() < kLeft) w_->select_phase_key(r - 2, -1);  // the row's name
    }
  }
  if (drag_key_ < 0 && e->pos().x() >= kLeft) w_->set_time(t_of(e->pos().x()));  // scrub, on the ruler or between marks
  update();
}

void Timeline::mouseMoveEvent(QMouseEvent* e) {
  if (drag_key_ >= 0) {
    // A key moves once the pointer has gone the platform's drag distance: a click only selects it
    // (a click 6 px beside a mark moved it to the snapped time under the pointer).
    if ((e->pos() - drag_from_).manhattanLength() >= QApplication::startDragDistance()) dragged_ = true;
    if (dragged_) drag_time_ = drag_limit(drag_row_, drag_key_, e->pos().x());
  } else if (e->pos().x() >= kLeft) {
    w_->set_time(t_of(e->pos().x()));
  }
  update();
}

void Timeline::mouseReleaseEvent(QMouseEvent* e) {
  if (drag_key_ >= 0 && (e->pos() - drag_from_).manhattanLength() >= QApplication::startDragDistance()) dragged_ = true;
  if (drag_key_ >= 0 && !dragged_) {
    drag_row_ = drag_key_ = -1;
  } else if (drag_key_ >= 0) {
    const int r = drag_row_, k = drag_key_;
    const double t = drag_limit(r, k, e->pos().x());
    drag_row_ = drag_key_ = -1;
    const std::size_t o = std::size_t(w_->object_);
    const auto times = w_->doc_.key_times(o, track_of(r), std::size_t(std::max(0, r - 2)));
    if (std::abs(times[std::size_t(k)] - t) > 1e-12)
      w_->edit("Move key in time", [&](Document& d) {
        d.set_key_time(o, track_of(r), std::size_t(std::max(0, r - 2)), std::size_t(k), t);
      });
  }
  update();
}

}  // namespace csrbf::composer
