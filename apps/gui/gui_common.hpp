// Pieces the Qt programs (Picker, Composer) share: the display at start-up, the error box, the undo
// actions, screenshots, and conversions between world, VTK display and Qt widget coordinates.
#pragma once

#include "csrbf/neighbor_index.hpp"
#include "csrbf/render/process.hpp"

#include <QApplication>
#include <QDateTime>
#include <QDoubleSpinBox>
#include <QMessageBox>
#include <QPoint>
#include <QString>
#include <QStringList>

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

class QLabel;
class QMenu;
class QScrollArea;
class QCommandLineParser;
class QCoreApplication;
class QUndoStack;
class QWidget;
class QVTKOpenGLNativeWidget;
class vtkRenderer;

namespace csrbf::gui {

/// A QApplication whose event delivery catches what a handler throws: the message is shown in a
/// box (not modal, after the event) and the program goes on, instead of Qt ending it with
/// std::terminate and the unsaved work with it. Handlers that edit a document keep it as it was
/// before the edit themselves (the Composer's and the Picker's edit()).
class SafeApplication : public QApplication {
 public:
  SafeApplication(int& argc, char** argv) : QApplication(argc, argv) {}
  bool notify(QObject* receiver, QEvent* event) override;
};
/// The last message SafeApplication caught, or empty; for tests.
QString last_caught_error();

/// Unsaved work kept aside for the next start, as office programs and Blender do: a program writes
/// it every recovery_seconds() while it has unsaved changes, removes it once they are saved or
/// discarded, and offers it at its next start (so a crash loses at most that long). The file is
/// <AppDataLocation>/<program>-recovery.json (~/.local/share/csrbf-composer/...), written atomically.
class Recovery {
 public:
  /// side: suffixes of files kept beside it (the Picker's deformation, ".deformation.json").
  explicit Recovery(const QString& program, QStringList side = {});
  QString path() const { return path_; }
  /// path() with one of the side suffixes.
  QString side_path(const QString& suffix) const { return path_ + suffix; }
  bool exists() const;
  /// When the file was written (invalid when there is none).
  QDateTime when() const;
  /// Writes text; false (and nothing changed) when it cannot.
  bool write(const std::string& text) const;
  /// The file's text; empty when there is none or it cannot be read.
  std::string read() const;
  /// Removes the file and its side files.
  void remove() const;
  /// At a program's start, when the file exists: asks whether to recover it, in `found` with %1 the
  /// document its JSON names under `key` (else `unnamed`). True for Yes; on No the file (and its
  /// side files) are removed, the work discarded.
  bool offer(QWidget* parent, const QString& found, const char* key, const QString& unnamed) const;

 private:
  QString path_;
  QStringList side_;
};
/// Seconds between recovery writes: CSRBF_RECOVERY_SECONDS (1 to 3600) or 60.
int recovery_seconds();

/// Call before QApplication: without DISPLAY, starts a private Xvfb (Qt and Debian's VTK need X).
/// Returns null when DISPLAY is set; prints "program: error: ..." and returns null with ok = false
/// when no display can be had.
std::unique_ptr<render::Display> ensure_display(const char* program, bool& ok);

/// Parses the command line as csrbf's commands do: an unknown option, a missing value or more than
/// max_positional arguments print "program: error: ..." and give exit status 2 (QCommandLineParser's
/// process() exits 1, and ignored extra arguments without a word); --help prints and gives 0.
/// Returns -1 when the program goes on.
int parse_command_line(QCommandLineParser& parser, const QCoreApplication& app, const char* program,
                       int max_positional);

/// --screenshot FILE: a .png name that is none of the inputs (by device and inode, links followed);
/// else prints "program: error: ..." and gives 2. -1 when it is fine.
int check_screenshot(const QString& shot, const std::vector<std::filesystem::path>& inputs, const char* program);

/// A box of fixed height for message labels, one above another, scrolling when they are long: a
/// message coming or going never moves the panel or resizes the view under the mouse.
QScrollArea* make_message_box(QWidget* parent, int height);
/// A word-wrapped label in such a box, hidden until shown: black text on `background` ("#f0c040"),
/// or white on red for the error box (name "error").
QLabel* add_message(QScrollArea* box, const char* name, const char* background);
/// A line of advice in grey at the foot of such a box (name "tip"), always shown, below the
/// messages: an empty box read as a grey band to a new user.
QLabel* add_tip(QScrollArea* box, const QString& text);
/// Undo (Ctrl+Z) and redo (Ctrl+Shift+Z, Ctrl+Y) of a stack, added to a menu.
void add_undo_actions(QMenu* menu, QUndoStack& stack, QWidget* owner);
/// Renders the VTK view and saves the whole window as a PNG.
bool save_window_png(QWidget* window, QVTKOpenGLNativeWidget* view, const QString& path);

/// Standard views, as Blender's numpad 1 / 3 / 7 (y is up, as in OBJ and glTF): front looks down
/// -z, side (from the right) down -x, top down -y.
enum class View { Front, Side, Top };
/// Points the renderer's camera along `v` at the centre of `bounds` (xmin, xmax, ymin, ...) and zooms
/// to fit them. Bounds are passed in, not taken from the props: a pipeline not yet re-run would give
/// the previous mesh's.
void set_view(vtkRenderer* r, const double bounds[6], View v);
/// Adds "Front / Side / Top view" with the keys 1 / 3 / 7, on the number row and the keypad.
void add_view_actions(QMenu* menu, QWidget* owner, const std::function<void(View)>& show);

/// A spin box that also reads and writes scientific notation ("1e9", "2.5e-3"), for values over many
/// decades (a radius). Qt's own box drops the 'e' and turns "1e9" into 19.
class NumberBox : public QDoubleSpinBox {
 public:
  explicit NumberBox(QWidget* parent = nullptr);
  QValidator::State validate(QString& text, int& pos) const override;
  double valueFromText(const QString& text) const override;
  QString textFromValue(double value) const override;
  /// Text that is a number outside the range is refused, not clamped: the box keeps its value and
  /// refused(message) is called (a program shows it), e.g. "0 refused: Radius R is at least 1e-09".
  void fixup(QString& text) const override;
  QString what = "the value";  // its name in that message
  std::function<void(const QString&)> refused;
};

/// A number box as both programs make them: named (tests find it), in [lo, hi], its value an edit when
/// typing is done (Enter or focus), not at each key; `what` names it in the message refused() gets.
NumberBox* number_box(QWidget* parent, const char* name, double lo, double hi, const QString& what,
                      std::function<void(const QString&)> refused);

/// Letters that are never part of a number (all but E) typed while a number box of root has focus
/// go to the window's single-letter shortcuts (View > Wireframe W and the like), as they do while the
/// view has focus; a number box would otherwise swallow them.
void pass_letters_to_shortcuts(QWidget* root);

/// Applies what is being typed (a number box's text, a table cell's open editor) as if the user had
/// pressed Enter: Save and Quit by shortcut leave the focus where it is, and dropped it ("Saved"
/// with the old value in the file). Call before saving, and before asking about unsaved changes.
void commit_pending_edit();

/// Asks "<what> Save, Discard or Cancel?": the button pressed.
QMessageBox::StandardButton ask_unsaved(QWidget* parent, const QString& what);
/// The folder a file dialog starts in: that of `current` (the open document) when it has one, else
/// the folder last used in this program, else the working folder.
QString dialog_folder(const QString& current);
/// Remembers the folder of a file chosen in a dialog.
void remember_folder(const QString& file);
/// A window of text (the mouse and key reference), not modal.
void show_reference(QWidget* parent, const QString& title, const QString& html);

/// VTK display coordinates (pixels from the bottom left, z the depth) of a world point.
Vec3 world_to_display(vtkRenderer* r, const Vec3& world);
/// The world point at display (x, y) and depth z; empty at infinity.
std::optional<Vec3> display_to_world(vtkRenderer* r, double x, double y, double z);
/// Qt widget coordinates of VTK display coordinates in a view.
QPoint widget_point(QVTKOpenGLNativeWidget* view, double display_x, double display_y);

}  // namespace csrbf::gui
