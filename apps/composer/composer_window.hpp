// The Animation Composer's main window (Qt 5 + VTK 9): build a scene by hand (objects, trajectory
// keys dragged in 3D, orientation keys, deformations on a schedule), play it, export a movie. Its
// members are defined by part: composer_window.cpp (menus, files, undo, playback), composer_view.cpp
// (the 3D view), composer_panel.cpp (the side panel).
#pragma once

#include "composer_document.hpp"
#include "composer_timeline.hpp"
#include "gui_common.hpp"

#include <QMainWindow>
#include <QUndoStack>

#include <vtkSmartPointer.h>

#include <chrono>
#include <functional>
#include <memory>
#include <optional>

class QAction;
class QCheckBox;
class QComboBox;
class QGroupBox;
class QLineEdit;
class QScrollArea;
class QDoubleSpinBox;
class QLabel;
class QListWidget;
class QPushButton;
class QSlider;
class QTabWidget;
class QTimer;
class QVBoxLayout;
class QVTKOpenGLNativeWidget;
class vtkActor;
class vtkCameraActor;
class vtkGenericOpenGLRenderWindow;
class vtkPolyData;
class vtkRenderer;

namespace csrbf::anim {
class Player;
}
namespace csrbf::render {
class SceneRenderer;
}

namespace csrbf::composer {

class ComposerStyle;
class JsonCommand;

class ComposerWindow : public QMainWindow {
  Q_OBJECT

 public:
  explicit ComposerWindow(QWidget* parent = nullptr);
  ~ComposerWindow() override;

  // File operations (the menu's actions, without their dialogs). False with the error shown.
  bool new_scene();
  bool open_scene(const QString& path);
  bool save_scene(const QString& path);
  /// Save, Discard or Cancel when the scene has unsaved edits: true to go on.
  bool maybe_save();
  /// Unsaved work kept for the next start (gui::Recovery): written every recovery_seconds() while
  /// there are unsaved edits, removed when they are saved or discarded.
  const gui::Recovery& recovery() const { return recovery_; }
  /// Writes the recovery file now if there are unsaved edits; true when written.
  bool write_recovery();
  /// Loads the recovery file as an unsaved scene (the file it came from stays as it was); false with
  /// the error shown when it cannot be read.
  bool recover();
  /// At start: when a recovery file exists, asks whether to recover it (and removes it on No).
  void offer_recovery();
  bool add_object(const QString& mesh);
  bool attach_deformation(const QString& file);
  /// Renders the scene to a movie with a progress dialog, through the renderer `csrbf animate` uses.
  bool export_movie(const QString& path, int width, int height);

  /// Applies an edit to a copy of the document; if the scene it gives can be built, it becomes the
  /// document as one undoable step. Otherwise the error is shown and nothing changes.
  bool edit(const QString& what, const std::function<void(Document&)>& change);

  const Document& document() const { return doc_; }
  QUndoStack& undo_stack() { return undo_; }
  int selected_object() const { return object_; }
  void select_object(int i);
  int selected_key() const { return key_; }
  void select_key(int key);
  double time() const { return time_; }
  void set_time(double t);
  bool playing() const;
  void play(bool on);
  /// Frames shown since the window opened (the play loop counts them).
  std::size_t frames_shown() const { return frames_shown_; }
  QString error_text() const;
  QVTKOpenGLNativeWidget* view() const { return view_; }
  Timeline* timeline() const { return timeline_; }
  QPointF to_display(const Vec3& world) const;
  /// World position of the selected object's trajectory key k.
  Vec3 key_position(int k) const;
  bool save_screenshot(const QString& path);
  /// The last message of a finished action (an export), or empty.
  QString info_text() const;
  /// The selected deformation of the selected object and its selected phase key (-1: none).
  int selected_deformation() const { return deformation_; }
  int selected_phase_key() const { return phase_key_; }
  void select_phase_key(int deformation, int key);
  /// R: front view fitted to the scene at the current time; 1 / 3 / 7 side and top.
  void reset_camera(gui::View view = gui::View::Front);
  /// Home: the whole scene in view, from where the camera looks now (Blender's View All).
  void frame_all();
  /// "Set scene camera from view": the movie's camera becomes the view's (one undoable edit).
  bool set_scene_camera_from_view();
  /// "Look through scene camera": the view's camera becomes the movie's.
  void look_through_scene_camera();
  /// The scene camera's frame (its frustum up to the focal point) as drawn in the view.
  vtkCameraActor* scene_camera_actor() const;

 protected:
  void closeEvent(QCloseEvent* e) override;

 private:
  friend class ComposerStyle;
  friend class Timeline;
  friend class JsonCommand;
  void build_ui();
  void build_view();    // the 3D view, its mouse and its overlays
  void build_centre();  // the view above the timeline and the play / scrub bar
  // The side panel, a part at a time (objects, then a group box each).
  void build_object_list(QWidget* panel, QVBoxLayout* layout);
  QGroupBox* build_key_box(QWidget* panel);
  QGroupBox* build_orientation_box(QWidget* panel);
  QGroupBox* build_scene_box(QWidget* panel);
  QGroupBox* build_deformation_box(QWidget* panel);
  QGroupBox* build_look_box(QWidget* panel);
  void build_menus();
  void rebuild();     // scene from the document: renderer, player, overlays
  void show_frame();  // evaluate at time_, draw
  void refresh_panel();
  void refresh_overlays();
  void show_error(const QString& m);
  QDoubleSpinBox* number_box(QWidget* parent, const char* name, double lo, double hi, double step);
  void clear_error();
  void restore(const nlohmann::json& j, const std::filesystem::path& base);
  bool has_object() const;  ///< object_ names an object of the built scene
  void refresh_deformation_panel();
  void refresh_look_panel();
  void apply_wireframe();
  void show_info(const QString& m);
  void tick();

  // 3D interaction
  int key_at(int x, int y) const;
  void begin_key_drag(int key);
  void drag_key_to(int x, int y);
  void end_key_drag();
  void add_key_at_display(int x, int y);
  void rotate_by(double dyaw, double dpitch);
  /// An edit made while dragging: applied at once, no undo step (end_key_drag makes one).
  void live_edit(const std::function<void(Document&)>& change);

  Document doc_;
  // Before undo_: its destructor still emits cleanChanged (the destructor disconnects it first).
  gui::Recovery recovery_{"composer"};
  QTimer* recovery_timer_ = nullptr;
  QUndoStack undo_;
  std::unique_ptr<anim::Scene> scene_;
  std::unique_ptr<anim::Player> player_;
  std::unique_ptr<render::SceneRenderer> scene_renderer_;
  QVTKOpenGLNativeWidget* view_ = nullptr;
  vtkSmartPointer<vtkGenericOpenGLRenderWindow> window_;
  vtkSmartPointer<vtkRenderer> overlay_;  // trajectory curves, key handles, orientation marks
  vtkSmartPointer<vtkPolyData> curve_, handles_, frames_;
  vtkSmartPointer<vtkActor> curve_actor_, handle_actor_, frame_actor_;
  vtkSmartPointer<ComposerStyle> style_;
  vtkSmartPointer<vtkCameraActor> camera_actor_;

  QListWidget* objects_ = nullptr;
  QDoubleSpinBox* key_time_ = nullptr;
  QDoubleSpinBox* key_pos_[3] = {};
  QDoubleSpinBox* tcb_[3] = {};
  QDoubleSpinBox* angles_[3] = {};
  QDoubleSpinBox* duration_ = nullptr;
  QDoubleSpinBox* fps_ = nullptr;
  QSlider* scrub_ = nullptr;
  QLabel* time_label_ = nullptr;
  QPushButton* play_ = nullptr;
  QCheckBox* loop_ = nullptr;
  QLabel* rates_ = nullptr;
  QLabel* error_ = nullptr;
  QLabel* info_ = nullptr;
  Timeline* timeline_ = nullptr;
  QScrollArea* timeline_scroll_ = nullptr;
  QTabWidget* tabs_ = nullptr;  // the side panel's tabs: Object, Deformations, Scene
  static constexpr int kObjectTab = 0, kDeformationsTab = 1, kSceneTab = 2;
  QListWidget* deformations_ = nullptr;
  QLineEdit* def_name_ = nullptr;
  QComboBox* combine_ = nullptr;
  QComboBox* easing_ = nullptr;
  QDoubleSpinBox* phase_time_ = nullptr;
  QDoubleSpinBox* phase_value_ = nullptr;
  QListWidget* lights_ = nullptr;
  QDoubleSpinBox* light_intensity_ = nullptr;
  QDoubleSpinBox* view_angle_ = nullptr;
  QAction* wireframe_ = nullptr;
  QTimer* timer_ = nullptr;

  int object_ = -1, key_ = -1, deformation_ = -1, phase_key_ = -1;
  double time_ = 0;
  bool updating_ = false;
  int dragging_ = -1;
  double drag_depth_ = 0;
  nlohmann::json drag_start_;
  std::size_t frames_shown_ = 0;
  double compute_s_ = 0, render_s_ = 0;
  std::size_t rate_frames_ = 0;
  std::chrono::steady_clock::time_point last_tick_;
};

}  // namespace csrbf::composer
