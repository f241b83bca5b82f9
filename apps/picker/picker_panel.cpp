// The Picker's side panel: the control table, the fit options, the display switches and the message
// boxes (error, fold warning, hints), with their refresh from the state.
#include "picker_window.hpp"

#include "csrbf/names.hpp"
#include "gui_common.hpp"

#include <QCheckBox>
#include <QComboBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QPushButton>
#include <QScrollArea>
#include <QSlider>
#include <QStatusBar>
#include <QTableWidget>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>

namespace csrbf::picker {

namespace {

enum MergeId { kMergeRadius = 1, kMergePhase = 2 };

QString number(double v) { return QString::number(v, 'g', 6); }

// Radius slider: 0 .. 1000 over R / diagonal from 1e-3 to 1, logarithmic.
int slider_from_fraction(double f) {
  return int(std::lround(1000.0 * (std::log10(std::clamp(f, 1e-3, 1.0)) + 3.0) / 3.0));
}
double fraction_from_slider(int v) { return std::pow(10.0, 3.0 * double(v) / 1000.0 - 3.0); }

}  // namespace

void PickerWindow::build_ui() {
  auto* dock = new QDockWidget("Deformation", this);
  dock->setObjectName("deformation");
  dock->setFeatures(QDockWidget::DockWidgetMovable | QDockWidget::DockWidgetFloatable);
  auto* panel = new QWidget(dock);
  panel->setMinimumWidth(560);
  auto* layout = new QVBoxLayout(panel);
  build_control_table(panel, layout);
  build_area_buttons(panel, layout);
  build_fit_options(panel, layout);
  build_display_switches(panel, layout);
  build_messages(panel, layout);

  dock->setWidget(panel);
  addDockWidget(Qt::RightDockWidgetArea, dock);
  timing_ = new QLabel(this);
  statusBar()->addPermanentWidget(timing_);
  statusBar()->showMessage("Open a mesh (ctrl+O or drop a file here)");
}

void PickerWindow::build_control_table(QWidget* panel, QVBoxLayout* layout) {
  table_ = new QTableWidget(0, 7, panel);
  table_->setObjectName("controls");
  table_->setHorizontalHeaderLabels({"sx", "sy", "sz", "dx", "dy", "dz", "pin"});
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  table_->horizontalHeader()->setSectionResizeMode(6, QHeaderView::ResizeToContents);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  layout->addWidget(new QLabel("Control vectors (source, destination)", panel));
  layout->addWidget(table_, 1);
  connect(table_, &QTableWidget::itemSelectionChanged, this, [this] {
    if (updating_) return;
    const auto rows = table_->selectionModel()->selectedRows();
    selected_ = rows.isEmpty() ? -1 : rows.front().row();
    refresh_view();
  });
  connect(table_, &QTableWidget::itemChanged, this, [this](QTableWidgetItem* item) {
    if (updating_) return;
    State next = doc_.state();
    const auto row = std::size_t(item->row());
    if (row >= next.controls.size()) return;
    auto& c = next.controls[row];
    if (item->column() == 6) {
      c.pinned = item->checkState() == Qt::Checked;
      if (c.pinned) c.destination = c.source;
      edit(next, c.pinned ? "Pin control" : "Unpin control");
      return;
    }
    bool ok = false;
    const double v = item->text().toDouble(&ok);
    if (!ok || !std::isfinite(v)) {
      show_error(QString("'%1' is not a number (row %2, column %3)")
                     .arg(item->text())
                     .arg(item->row() + 1)
                     .arg(table_->horizontalHeaderItem(item->column())->text()));
      refresh_table();
      return;
    }
    const int col = item->column();
    if (col < 3) {
      c.source[col] = v;
      if (c.pinned) c.destination = c.source;
    } else {
      c.destination[col - 3] = v;
      if (c.pinned) c.source = c.destination;
    }
    edit(next, "Edit coordinates");
  });
}

void PickerWindow::build_area_buttons(QWidget* panel, QVBoxLayout* layout) {
  auto* del = new QPushButton("Delete", panel);
  del->setObjectName("delete");
  connect(del, &QPushButton::clicked, this, [this] { delete_selected(); });
  auto* clear_region = new QPushButton("Whole mesh", panel);
  clear_region->setObjectName("clearRegion");
  clear_region->setToolTip("Deform the whole mesh again (ctrl + drag selects an active area)");
  connect(clear_region, &QPushButton::clicked, this, [this] {
    State next = doc_.state();
    next.region.clear();
    edit(next, "Whole mesh");
  });
  auto* row = new QHBoxLayout;
  row->addWidget(del);
  row->addWidget(clear_region);
  layout->addLayout(row);
  region_label_ = new QLabel(panel);
  layout->addWidget(region_label_);
}

void PickerWindow::build_fit_options(QWidget* panel, QVBoxLayout* layout) {
  auto* form = new QFormLayout;
  const auto refused = [this](const QString& m) { show_error(m); };
  radius_ = gui::number_box(panel, "radius", 1e-9, 1e12, "Radius R", refused);
  // In significant digits, as R itself: a radius of 1e-5 of the size is 0.001 %, not 0.01 (a box of
  // 2 decimals showed its minimum).
  radius_fraction_ = gui::number_box(panel, "radiusFraction", 1e-12, 1e14, "Radius R in % of the size", refused);
  radius_fraction_->setToolTip("Radius R in percent of the mesh's size (its bounding box's diagonal)");
  radius_slider_ = new QSlider(Qt::Horizontal, panel);
  radius_slider_->setObjectName("radiusSlider");
  radius_slider_->setRange(0, 1000);
  auto* radius_row = new QHBoxLayout;
  radius_row->addWidget(radius_);
  radius_row->addWidget(radius_fraction_);
  radius_row->addWidget(new QLabel("% of size", panel));
  form->addRow("Radius R", radius_row);
  form->addRow("", radius_slider_);
  connect(radius_, qOverload<double>(&QDoubleSpinBox::valueChanged), this,
          [this] { options_changed(kMergeRadius, "Radius"); });
  connect(radius_fraction_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double pct) {
    if (updating_) return;
    updating_ = true;
    radius_->setValue(pct / 100.0 * doc_.diagonal());
    updating_ = false;
    options_changed(kMergeRadius, "Radius");
  });
  connect(radius_slider_, &QSlider::valueChanged, this, [this](int v) {
    if (updating_) return;
    updating_ = true;
    radius_->setValue(fraction_from_slider(v) * doc_.diagonal());
    updating_ = false;
    options_changed(kMergeRadius, "Radius");
  });

  kernel_ = new QComboBox(panel);
  kernel_->setObjectName("kernel");
  kernel_->addItems({"C0  ψ2,0 = (1-r)²", "C2  ψ3,1 = (1-r)⁴(4r+1)", "C4  ψ4,2", "C6  ψ5,3"});
  form->addRow("Kernel", kernel_);
  connect(kernel_, qOverload<int>(&QComboBox::currentIndexChanged), this, [this] { options_changed(-1, "Kernel"); });
  polynomial_ = new QComboBox(panel);
  polynomial_->setObjectName("polynomial");
  for (const auto& e : NameTable<Polynomial>::entries)
    polynomial_->addItem(QString::fromUtf8(e.name.data(), int(e.name.size())));
  form->addRow("Polynomial", polynomial_);
  connect(polynomial_, qOverload<int>(&QComboBox::currentIndexChanged), this,
          [this] { options_changed(-1, "Polynomial"); });
  phase_ = new QSlider(Qt::Horizontal, panel);
  phase_->setObjectName("phase");
  phase_->setRange(0, 100);
  phase_label_ = new QLabel(panel);
  auto* phase_row = new QHBoxLayout;
  phase_row->addWidget(phase_);
  phase_row->addWidget(phase_label_);
  form->addRow("Phase", phase_row);
  connect(phase_, &QSlider::valueChanged, this, [this] { options_changed(kMergePhase, "Phase"); });
  layout->addLayout(form);
}

void PickerWindow::build_display_switches(QWidget* panel, QVBoxLayout* layout) {
  show_supports_ = new QCheckBox("Show support spheres (S)", panel);
  show_supports_->setObjectName("supports");
  colour_displacement_ = new QCheckBox("Colour by displacement (D)", panel);
  colour_displacement_->setObjectName("colourDisplacement");
  connect(show_supports_, &QCheckBox::toggled, this, [this] { refresh_view(); });
  connect(colour_displacement_, &QCheckBox::toggled, this, [this] { refresh_view(); });
  layout->addWidget(show_supports_);
  layout->addWidget(colour_displacement_);
}

void PickerWindow::build_messages(QWidget* panel, QVBoxLayout* layout) {
  auto* messages = gui::make_message_box(panel, 170);
  error_ = gui::add_message(messages, "error", "#b03030");
  fold_warning_ = gui::add_message(messages, "foldWarning", "#f0c040");
  hint_ = gui::add_message(messages, "hint", "#a8d0f0");
  gui::add_tip(
      messages,
      "Click the mesh to add a control, then drag its handle to where it goes; Shift + click pins a point, Ctrl + "
      "drag selects the active area. F1 lists every key.");
  layout->addWidget(messages);
}

void PickerWindow::options_changed(int merge_id, const QString& what) {
  if (updating_) return;
  State next = doc_.state();
  next.radius = radius_->value();
  next.kernel = NameTable<Kernel>::entries[std::size_t(std::max(0, kernel_->currentIndex()))].value;
  next.polynomial = NameTable<Polynomial>::entries[std::size_t(std::max(0, polynomial_->currentIndex()))].value;
  next.phase = phase_->value() / 100.0;
  edit(next, what, merge_id);
}

QString PickerWindow::fold_warning() const { return fold_warning_->isHidden() ? QString() : fold_warning_->text(); }

QString PickerWindow::error_text() const { return error_->isHidden() ? QString() : error_->text(); }

void PickerWindow::show_error(const QString& message) {
  error_->setText(message);
  error_->show();
  statusBar()->showMessage(message.section('\n', 0, 0), 10000);
}

void PickerWindow::clear_error() {
  // The status bar repeats an error's first line: it goes with the error, not 10 s later.
  if (!error_->isHidden() && statusBar()->currentMessage() == error_->text().section('\n', 0, 0))
    statusBar()->clearMessage();
  error_->clear();
  error_->hide();
}

void PickerWindow::refresh_options() {
  updating_ = true;
  const auto& s = doc_.state();
  radius_->setValue(s.radius);
  radius_fraction_->setValue(100.0 * s.radius / doc_.diagonal());
  radius_slider_->setValue(slider_from_fraction(s.radius / doc_.diagonal()));
  kernel_->setCurrentIndex(int(table_index(s.kernel)));
  polynomial_->setCurrentIndex(int(table_index(s.polynomial)));
  phase_->setValue(int(std::lround(s.phase * 100)));
  phase_label_->setText(QString::number(s.phase, 'f', 2));
  updating_ = false;
}

void PickerWindow::refresh_table() {
  updating_ = true;
  const auto& cs = doc_.state().controls;
  table_->setRowCount(int(cs.size()));
  for (int r = 0; r < int(cs.size()); ++r) {
    const auto& c = cs[std::size_t(r)];
    const double v[6] = {c.source.x(),      c.source.y(),      c.source.z(),
                         c.destination.x(), c.destination.y(), c.destination.z()};
    for (int k = 0; k < 6; ++k) {
      auto* item = new QTableWidgetItem(number(v[k]));
      table_->setItem(r, k, item);
    }
    auto* pin = new QTableWidgetItem;
    pin->setFlags(Qt::ItemIsUserCheckable | Qt::ItemIsEnabled | Qt::ItemIsSelectable);
    pin->setCheckState(c.pinned ? Qt::Checked : Qt::Unchecked);
    table_->setItem(r, 6, pin);
  }
  if (selected_ >= 0 && selected_ < int(cs.size()))
    table_->selectRow(selected_);
  else
    table_->clearSelection();
  updating_ = false;
}

QString PickerWindow::hint() const { return hint_->isHidden() ? QString() : hint_->text(); }

void PickerWindow::refresh_hints() {
  // What the numbers cannot show by themselves: a map that moves nothing, or moves the mesh far more
  // than any control asks (a polynomial extrapolating from too few controls).
  QStringList hints;
  if (!proposal_.isEmpty()) hints << proposal_;
  const auto& s = doc_.state();
  double longest = 0;
  for (const auto& c : s.controls) longest = std::max(longest, (c.destination - c.source).norm());
  if (longest > 0 && doc_.has_mesh()) {
    const auto mag = doc_.displacement_magnitudes();
    const double most = mag.empty() ? 0.0 : *std::max_element(mag.begin(), mag.end());
    if (most == 0) {
      hints << QString("No vertex moves: none lies within R = %1 of a moved control%2. Raise the radius.")
                   .arg(s.radius, 0, 'g', 4)
                   .arg(s.region.empty() ? QString() : QString(" inside the active area"));
    } else if (most > 2.0 * longest) {
      hints << QString(
                   "The mesh moves up to %1, %2 times the longest control vector (%3)%4. Check the result, or use "
                   "more controls%5.")
                   .arg(most, 0, 'g', 3)
                   .arg(most / longest, 0, 'f', 1)
                   .arg(longest, 0, 'g', 3)
                   .arg(s.polynomial == Polynomial::None
                            ? QString()
                            : QString(": the %1 polynomial extrapolates from the controls")
                                  .arg(QString::fromUtf8(name_of(s.polynomial).data(),
                                                         int(name_of(s.polynomial).size()))))
                   .arg(s.polynomial == Polynomial::None ? QString() : QString(" or polynomial 'none'"));
    }
  }
  hint_->setText(hints.join("\n"));
  hint_->setVisible(!hints.isEmpty());
}

}  // namespace csrbf::picker
