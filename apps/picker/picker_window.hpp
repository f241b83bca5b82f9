// The Picker's main window (Qt 5 + VTK 9): pick control points on a mesh, drag their destinations,
// see the deformation live. Mouse and keyboard reference: README, "Picker". Its members are defined
// by part: picker_window.cpp (menus, files, undo), picker_view.cpp (3D view), picker_panel.cpp (side panel).
#pragma once

#include "gui_common.hpp"
#include "picker_document.hpp"

#include <QMainWindow>
#include <QUndoStack>

#include <vtkSmartPointer.h>

#include <optional>
#include <vector>

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QSlider;
class QTableWidget;
class QVBoxLayout;
class QVTKOpenGLNativeWidget;
class QAction;
class vtkActor;
class vtkActor2D;
class vtkLookupTable;
class vtkScalarBarActor;
class vtkGenericOpenGLRenderWindow;
class vtkPolyData;
class vtkRenderer;
class vtkGlyph3D;

namespace csrbf::picker {

class PickerStyle;

class PickerWindow : public QMainWindow {
  Q_OBJECT

 public:
  explicit PickerWindow(QWidget* parent = nullptr);
  ~PickerWindow() override;

  /// Opens a mesh; false (with the error shown) if it cannot be read. Frames it (front view).
  bool open_mesh(const QString& path);
  bool load_deformation(const QString& path);
  /// Loads a controls text file. Without a radius, proposes one from the controls (see
  /// Document::propose_radius) and says so in the status bar and the hint box.
  bool load_controls(const QString& path, std::optional<double> radius = std::nullopt);
  bool save_deformation(const QString& path);
  bool save_controls(const QString& path);
  bool export_mesh(const QString& path);

  /// Applies a whole new state as one undoable edit. merge_id >= 0 merges consecutive edits of
  /// the same kind (slider moves). False, with the engine's message shown and the last good state
  /// kept, when the state cannot be fitted.
  bool edit(const State& next, const QString& what, int merge_id = -1);

  const Document& document() const { return doc_; }
  QUndoStack& undo_stack() { return undo_; }
  QVTKOpenGLNativeWidget* view() const { return view_; }
  vtkRenderer* renderer() const;
  /// The message of the last refused edit or failed file operation; empty when the last one succeeded.
  QString error_text() const;
  /// The fold warning shown, or empty when nothing folds.
  QString fold_warning() const;
  int selected() const { return selected_; }
  void select(int control);
  /// Display coordinates (VTK: pixels from the bottom left) of a world point.
  QPointF to_display(const Vec3& world) const;
  /// Renders and saves the whole window as a PNG; false on failure.
  bool save_screenshot(const QString& path);
  /// R: the front view, zoomed to fit the mesh; also the side and top views (numpad 3, 7).
  void reset_camera(gui::View view = gui::View::Front);
  /// Home: the whole mesh in view, from where the camera looks now (Blender's View All).
  void frame_all();
  /// The deformation file Ctrl+S writes to; empty until one was saved or loaded.
  const QString& deformation_path() const { return deformation_path_; }
  /// Save, Discard or Cancel when the deformation has unsaved edits: true to go on.
  bool maybe_save();
  /// Unsaved work kept for the next start (gui::Recovery, as the Composer's): the mesh's path and
  /// the deformation, written every recovery_seconds() while there are unsaved edits, removed when
  /// they are saved or discarded.
  const gui::Recovery& recovery() const { return recovery_; }
  /// Writes the recovery file now if there are unsaved edits; true when written.
  bool write_recovery();
  /// Opens the recovered mesh and deformation as unsaved work; false with the error shown.
  bool recover();
  /// At start: when a recovery file exists, asks whether to recover it (and removes it on No).
  void offer_recovery();
  /// The hint shown below the panel (an extrapolating polynomial, a radius that moves nothing, a
  /// proposed radius), or empty.
  QString hint() const;
  /// Frames a second, measured over the last drag moves (fit, evaluation and drawing); 0 before any.
  double drag_fps() const { return drag_fps_; }
  /// True while a ctrl + drag draws the active-area rectangle.
  bool band_visible() const;

 protected:
  void dragEnterEvent(QDragEnterEvent* e) override;
  void dropEvent(QDropEvent* e) override;
  void closeEvent(QCloseEvent* e) override;

 private:
  friend class PickerStyle;
  friend class StateCommand;
  void build_ui();
  // build_ui's parts, in the panel's order: each adds its widgets to the panel's layout.
  void build_control_table(QWidget* panel, QVBoxLayout* layout);
  void build_area_buttons(QWidget* panel, QVBoxLayout* layout);
  void build_fit_options(QWidget* panel, QVBoxLayout* layout);
  void build_display_switches(QWidget* panel, QVBoxLayout* layout);
  void build_messages(QWidget* panel, QVBoxLayout* layout);
  void build_menus();
  void build_scene();
  /// Shows state s (already applied to the document) everywhere: 3D view, table, option widgets.
  void refresh(const Outcome* outcome = nullptr);
  void refresh_view();
  void refresh_table();
  void refresh_options();
  void show_error(const QString& message);
  void clear_error();
  /// The state for an option change (from the widgets).
  void options_changed(int merge_id, const QString& what);
  /// Restores a state from the undo stack.
  void restore(const State& s);

  // Interaction (called by PickerStyle).
  bool pick_surface(int x, int y, Vec3& hit) const;
  int handle_at(int x, int y) const;  ///< control whose handle is within a few pixels, or -1
  void add_control(const Vec3& at, bool pinned);
  void begin_drag(int control);
  void drag_to(int x, int y);
  void end_drag();
  void select_region(int x0, int y0, int x1, int y1);
  void show_band(int x0, int y0, int x1, int y1);  ///< the rectangle of a ctrl + drag, in display pixels
  void hide_band();
  void refresh_hints();
  void delete_selected();

  Document doc_;
  // Before undo_: its destructor still emits cleanChanged (the destructor disconnects it first).
  /// The recovered deformation: a deformation file beside the recovery file.
  static inline const QString kRecoveredDeformation = ".deformation.json";
  gui::Recovery recovery_{"picker", {kRecoveredDeformation}};
  QUndoStack undo_;
  QVTKOpenGLNativeWidget* view_ = nullptr;
  vtkSmartPointer<vtkGenericOpenGLRenderWindow> window_;
  vtkSmartPointer<vtkRenderer> renderer_;
  vtkSmartPointer<vtkPolyData> mesh_, handles_, lines_, supports_;
  vtkSmartPointer<vtkActor> mesh_actor_, handle_actor_, line_actor_, support_actor_;
  vtkSmartPointer<vtkGlyph3D> handle_glyph_, support_glyph_;
  vtkSmartPointer<PickerStyle> style_;
  vtkSmartPointer<vtkPolyData> band_;
  vtkSmartPointer<vtkActor2D> band_actor_;
  vtkSmartPointer<vtkScalarBarActor> legend_;
  vtkSmartPointer<vtkLookupTable> legend_lut_;

  QTableWidget* table_ = nullptr;
  gui::NumberBox* radius_ = nullptr;
  gui::NumberBox* radius_fraction_ = nullptr;
  QSlider* radius_slider_ = nullptr;
  QComboBox* kernel_ = nullptr;
  QComboBox* polynomial_ = nullptr;
  QSlider* phase_ = nullptr;
  QLabel* phase_label_ = nullptr;
  QCheckBox* show_supports_ = nullptr;
  QCheckBox* colour_displacement_ = nullptr;
  QLabel* error_ = nullptr;
  QLabel* fold_warning_ = nullptr;
  QLabel* timing_ = nullptr;
  QLabel* region_label_ = nullptr;
  QLabel* hint_ = nullptr;
  QAction* wireframe_ = nullptr;
  QString deformation_path_;
  bool area_from_file_ = false;  ///< the active area came with a loaded deformation file (not picked here)
  QString proposal_;             // the last proposed radius, said in the hint until the next edit
  double drag_fps_ = 0;
  std::vector<double> frame_ms_;  // the last drag frames' times

  int selected_ = -1;
  bool updating_ = false;  // widgets being set from the state: their signals are not edits
  int dragging_ = -1;
  double drag_depth_ = 0;
  State drag_start_;
};

}  // namespace csrbf::picker
