#include "gui_common.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/inputs.hpp"

#include <QAbstractItemView>
#include <QAbstractSpinBox>
#include <QDoubleSpinBox>
#include <QSpinBox>
#include <QAction>
#include <QCommandLineParser>
#include <QKeyEvent>
#include <QStandardPaths>
#include <QTimer>
#include <QDialog>
#include <QDir>
#include <QBuffer>
#include <QByteArray>
#include <QFile>
#include <QJsonDocument>
#include <QJsonObject>
#include <QFileInfo>
#include <QTextBrowser>
#include <QVBoxLayout>
#include <QApplication>
#include <QLabel>
#include <QLineEdit>
#include <QMenu>
#include <QPixmap>
#include <QScrollArea>
#include <QUndoStack>
#include <QVTKOpenGLNativeWidget.h>

#include <vtkCamera.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <limits>

namespace csrbf::gui {

namespace {
QString g_last_caught;
}

QString last_caught_error() { return g_last_caught; }

bool SafeApplication::notify(QObject* receiver, QEvent* event) {
  QString message;
  try {
    return QApplication::notify(receiver, event);
  } catch (const std::exception& e) {
    message = QString::fromStdString(printable(e.what()));
  } catch (...) {
    message = "an unknown error";
  }
  g_last_caught = message;
  std::cerr << applicationName().toStdString() << ": error: " << message.toStdString() << '\n';
  // Shown after this event, not inside it: a box of its own, not modal (a test or a drag goes on).
  QTimer::singleShot(0, [message] {
    auto* box = new QMessageBox(QMessageBox::Critical, applicationName(),
                                "Something went wrong; nothing was lost, and the document is as it was before the "
                                "last action.\n\n" +
                                    message,
                                QMessageBox::Ok, activeWindow());
    box->setObjectName("caughtError");
    box->setAttribute(Qt::WA_DeleteOnClose);
    box->setModal(false);
    box->show();
  });
  return false;
}

Recovery::Recovery(const QString& program, QStringList side) : side_(std::move(side)) {
  const QString dir = QStandardPaths::writableLocation(QStandardPaths::GenericDataLocation) + "/csrbf";
  path_ = dir + "/" + program + "-recovery.json";
}

bool Recovery::exists() const { return QFileInfo(path_).isFile(); }

QDateTime Recovery::when() const { return exists() ? QFileInfo(path_).lastModified() : QDateTime(); }

bool Recovery::write(const std::string& text) const {
  try {
    QDir().mkpath(QFileInfo(path_).absolutePath());
    io::write_atomically(path_.toStdString(), [&](std::ostream& o) { o << text; });
    return true;
  } catch (const std::exception& e) {
    std::cerr << "csrbf: warning: cannot write the recovery file: " << printable(e.what()) << '\n';
    return false;
  }
}

std::string Recovery::read() const {
  std::ifstream in(path_.toStdString(), std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return in ? s.str() : std::string();
}

void Recovery::remove() const {
  QFile::remove(path_);
  for (const QString& s : side_) QFile::remove(side_path(s));
}

bool Recovery::offer(QWidget* parent, const QString& found, const char* key, const QString& unnamed) const {
  if (!exists()) return false;
  // A damaged file names nothing here; recovering it then says what is wrong.
  const QString named = QJsonDocument::fromJson(QByteArray::fromStdString(read())).object().value(key).toString();
  const auto answer = QMessageBox::question(
      parent, "Recover unsaved work?",
      found.arg(named.isEmpty() ? unnamed : named) + " that was not saved when it last closed (" +
          when().toString("yyyy-MM-dd hh:mm:ss") +
          ").\n\nYes opens it in place of what is shown now, as unsaved work (the file on disk stays as it "
          "is until you save).\nNo discards it for good.",
      QMessageBox::Yes | QMessageBox::No, QMessageBox::Yes);
  if (answer == QMessageBox::Yes) return true;
  remove();
  return false;
}

int recovery_seconds() {
  if (const char* e = std::getenv("CSRBF_RECOVERY_SECONDS")) {
    const int v = std::atoi(e);
    if (v >= 1 && v <= 3600) return v;
  }
  return 60;
}

int parse_command_line(QCommandLineParser& parser, const QCoreApplication& app, const char* program,
                       int max_positional) {
  if (!parser.parse(app.arguments())) {
    std::cerr << program << ": error: " << csrbf::printable(parser.errorText().toStdString()) << " (see --help)\n";
    return 2;
  }
  if (parser.isSet("help")) {
    std::cout << parser.helpText().toStdString();
    return 0;
  }
  const QStringList args = parser.positionalArguments();
  if (args.size() > max_positional) {
    std::cerr << program << ": error: unexpected argument '" << csrbf::printable(args[max_positional].toStdString())
              << "': " << (max_positional == 1 ? "one file is opened at a time" : "no file is taken")
              << " (see --help)\n";
    return 2;
  }
  return -1;
}

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

QScrollArea* make_message_box(QWidget* parent, int height) {
  auto* messages = new QWidget;
  auto* layout = new QVBoxLayout(messages);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->addStretch(1);
  auto* box = new QScrollArea(parent);
  box->setObjectName("messages");
  box->setWidget(messages);
  box->setWidgetResizable(true);
  box->setFrameShape(QFrame::StyledPanel);  // seen as the place where messages appear, also when empty
  box->setFixedHeight(height);
  return box;
}

QLabel* add_message(QScrollArea* box, const char* name, const char* background) {
  auto* l = new QLabel(box->widget());
  l->setObjectName(name);
  l->setWordWrap(true);
  const QString text = QString(name) == "error" ? "white" : "black";
  l->setStyleSheet(
      QString("QLabel { color: %1; background: %2; padding: 6px; border-radius: 4px; }").arg(text, background));
  l->hide();
  auto* layout = static_cast<QVBoxLayout*>(box->widget()->layout());
  auto* tip = box->widget()->findChild<QLabel*>("tip");
  layout->insertWidget(tip ? layout->indexOf(tip) : layout->count() - 1, l);  // above the tip and the stretch
  return l;
}

QLabel* add_tip(QScrollArea* box, const QString& text) {
  auto* l = new QLabel(text, box->widget());
  l->setObjectName("tip");
  l->setWordWrap(true);
  l->setStyleSheet("QLabel { color: #707070; padding: 6px; }");
  auto* layout = static_cast<QVBoxLayout*>(box->widget()->layout());
  layout->insertWidget(layout->count() - 1, l);  // below the messages, above the stretch
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
  // As every output of csrbf: a temporary file, checked and renamed (a FIFO, a folder or a device
  // is refused; QImage::save wrote straight into the name, and hung on a FIFO).
  QByteArray png;
  QBuffer buffer(&png);
  buffer.open(QIODevice::WriteOnly);
  if (!window->grab().save(&buffer, "PNG")) return false;
  try {
    io::write_atomically(path.toStdString(),
                         [&](std::ostream& o) { o.write(png.constData(), std::streamsize(png.size())); });
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

int check_screenshot(const QString& shot, const std::vector<std::filesystem::path>& inputs, const char* program) {
  const std::string s = shot.toStdString();
  if (!shot.endsWith(".png", Qt::CaseInsensitive)) {
    std::cerr << program << ": error: --screenshot: a .png file name, got '" << printable(s) << "'\n";
    return 2;
  }
  const std::filesystem::path same = io::same_file_as(s, inputs);
  if (!same.empty()) {
    std::cerr << program << ": error: --screenshot '" << printable(s) << "' is the input '" << printable(same.string())
              << "'; csrbf never writes an input: choose another name\n";
    return 2;
  }
  return -1;
}

void set_view(vtkRenderer* r, const double b[6], View v) {
  vtkCamera* c = r->GetActiveCamera();
  const double centre[3] = {(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2};
  const double dir[3][3] = {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}};  // from the focal point to the camera
  const double up[3][3] = {{0, 1, 0}, {0, 1, 0}, {0, 0, -1}};
  const int k = int(v);
  c->SetFocalPoint(centre);
  c->SetPosition(centre[0] + dir[k][0], centre[1] + dir[k][1], centre[2] + dir[k][2]);
  c->SetViewUp(up[k]);
  r->ResetCamera(b);  // keeps the direction, sets the distance that fits the bounds
}

void add_view_actions(QMenu* menu, QWidget* owner, const std::function<void(View)>& show) {
  const struct {
    const char* text;
    Qt::Key key;
    View view;
  } views[] = {{"&Front view", Qt::Key_1, View::Front},
               {"&Side view (right)", Qt::Key_3, View::Side},
               {"&Top view", Qt::Key_7, View::Top}};
  for (const auto& v : views) {
    QAction* a = menu->addAction(v.text);
    a->setShortcuts({QKeySequence(v.key), QKeySequence(int(Qt::KeypadModifier) | int(v.key))});
    const View view = v.view;
    QObject::connect(a, &QAction::triggered, owner, [show, view] { show(view); });
  }
}

void commit_pending_edit() {
  QWidget* w = QApplication::focusWidget();
  for (QWidget* p = w; p; p = p->parentWidget()) {
    if (auto* spin = qobject_cast<QAbstractSpinBox*>(p)) {
      spin->interpretText();  // valueChanged, as Enter would
      return;
    }
    if (auto* view = qobject_cast<QAbstractItemView*>(p)) {
      if (p != w) {  // an editor inside the view: leaving it commits it (the delegate's commitData)
        w->clearFocus();
        view->setFocus();
      }
      return;
    }
  }
}

NumberBox::NumberBox(QWidget* parent) : QDoubleSpinBox(parent) { setDecimals(12); }

QValidator::State NumberBox::validate(QString& text, int&) const {
  const QString t = text.trimmed();
  if (t.isEmpty() || t == "-" || t == "+" || t.endsWith('e', Qt::CaseInsensitive) || t.endsWith("e-") ||
      t.endsWith("e+") || t == ".")
    return QValidator::Intermediate;
  bool ok = false;
  const double v = t.toDouble(&ok);
  if (!ok || !std::isfinite(v)) return QValidator::Invalid;
  return v >= minimum() && v <= maximum() ? QValidator::Acceptable : QValidator::Intermediate;
}

double NumberBox::valueFromText(const QString& text) const { return text.trimmed().toDouble(); }

QString NumberBox::textFromValue(double value) const { return QString::number(value, 'g', 6); }

void NumberBox::fixup(QString& text) const {
  bool ok = false;
  const QString typed = text.trimmed();
  const double v = typed.toDouble(&ok);
  text = textFromValue(value());  // unchanged: a number out of range is refused, never clamped
  if (ok && std::isfinite(v) && refused)
    refused(QString("%1 refused: %2 is %3 %4")
                .arg(typed, what, v < minimum() ? "at least" : "at most",
                     textFromValue(v < minimum() ? minimum() : maximum())));
}

NumberBox* number_box(QWidget* parent, const char* name, double lo, double hi, const QString& what,
                      std::function<void(const QString&)> refused) {
  auto* box = new NumberBox(parent);
  box->setObjectName(name);
  box->setRange(lo, hi);
  box->setKeyboardTracking(false);
  box->what = what;
  box->refused = std::move(refused);
  return box;
}

namespace {
/// Whether text typed into a spin box is pending (typed, not yet entered): the "typing" property that
/// pass_letters_to_shortcuts keeps (the box's value alone cannot say: it follows the keys as typed).
bool typing(QObject* box) { return box && box->property("typing").toBool(); }

/// Lets ShortcutOverride of letters other than E pass a number box unaccepted (pass_letters_to_shortcuts),
/// and of Undo and Redo while nothing typed is pending there (typing): the box's own undo of its text had
/// made Ctrl+Z inert (the new user's trial), where the program's undo was meant.
class LetterPass : public QObject {
 public:
  using QObject::QObject;
  bool eventFilter(QObject* o, QEvent* e) override {
    if (e->type() != QEvent::ShortcutOverride) return false;
    const auto* k = static_cast<QKeyEvent*>(e);
    const bool ctrl_y = k->key() == Qt::Key_Y && k->modifiers() == Qt::ControlModifier;
    QObject* box = qobject_cast<QAbstractSpinBox*>(o) ? o : o->parent();  // the box or its line edit
    if ((k->matches(QKeySequence::Undo) || k->matches(QKeySequence::Redo) || ctrl_y) && !typing(box)) return true;
    const bool letter = k->key() >= Qt::Key_A && k->key() <= Qt::Key_Z && k->key() != Qt::Key_E;
    return letter && (k->modifiers() & ~Qt::ShiftModifier) == Qt::NoModifier;
  }
};
}  // namespace

void pass_letters_to_shortcuts(QWidget* root) {
  auto* filter = new LetterPass(root);
  for (auto* box : root->findChildren<QAbstractSpinBox*>()) {
    box->installEventFilter(filter);
    // Keys reach the line edit inside when it is the focus widget (a click into the text).
    if (auto* edit = box->findChild<QLineEdit*>()) {
      edit->installEventFilter(filter);
      QObject::connect(edit, &QLineEdit::textEdited, box, [box] { box->setProperty("typing", true); });
    }
    QObject::connect(box, &QAbstractSpinBox::editingFinished, box, [box] { box->setProperty("typing", false); });
  }
}

QMessageBox::StandardButton ask_unsaved(QWidget* parent, const QString& what) {
  return QMessageBox::question(parent, QApplication::applicationName(), what + " Save, Discard or Cancel?",
                               QMessageBox::Save | QMessageBox::Discard | QMessageBox::Cancel, QMessageBox::Save);
}

namespace {
QString& last_folder() {
  static QString folder;
  return folder;
}
}  // namespace

QString dialog_folder(const QString& current) {
  if (!current.isEmpty()) return QFileInfo(current).absolutePath();
  if (!last_folder().isEmpty()) return last_folder();
  return QDir::currentPath();
}

void remember_folder(const QString& file) {
  if (!file.isEmpty()) last_folder() = QFileInfo(file).absolutePath();
}

void show_reference(QWidget* parent, const QString& title, const QString& html) {
  auto* d = new QDialog(parent);
  d->setObjectName("reference");
  d->setAttribute(Qt::WA_DeleteOnClose);
  d->setWindowTitle(title);
  auto* l = new QVBoxLayout(d);
  auto* text = new QTextBrowser(d);
  text->setHtml(html);
  l->addWidget(text);
  d->resize(620, 560);
  d->show();
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
