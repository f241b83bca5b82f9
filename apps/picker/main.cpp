// csrbf-picker: pick control points on a mesh, drag their destinations, see the deformation live.
//   csrbf-picker [MESH] [--deformation FILE.json | --controls FILE --radius R] [--screenshot FILE.png]
#include "gui_common.hpp"
#include "picker_window.hpp"
#include "csrbf/io/inputs.hpp"

#include <QApplication>
#include <QCommandLineParser>
#include <QSurfaceFormat>
#include <QTimer>
#include <QVTKOpenGLNativeWidget.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <vector>
#include <memory>

int main(int argc, char** argv) {
  // Qt needs X (Debian's VTK renders through X only): without a display, a private Xvfb, as for
  // `csrbf animate`, so that --screenshot works on a server.
  bool have_display = true;
  const auto display = csrbf::gui::ensure_display("csrbf-picker", have_display);
  if (!have_display) return 1;
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  csrbf::gui::SafeApplication app(argc, argv);
  QApplication::setApplicationName("csrbf-picker");
  QCommandLineParser parser;
  parser.setApplicationDescription("Pick control points on a mesh, drag their destinations, see the deformation live");
  parser.addHelpOption();
  parser.addPositionalArgument("mesh", "Mesh to open (OBJ, PLY, OFF, STL, glTF, ...)", "[mesh]");
  const QCommandLineOption deformation("deformation", "Deformation JSON to load", "file");
  const QCommandLineOption controls("controls", "Controls file to load (with --radius, or a radius is proposed)",
                                    "file");
  const QCommandLineOption radius("radius", "Radius of support for --controls", "R");
  const QCommandLineOption screenshot("screenshot", "Render the window once to this PNG and exit", "file");
  const QCommandLineOption size("size", "Window size WIDTHxHEIGHT (default 1280x800)", "WxH", "1280x800");
  parser.addOptions({deformation, controls, radius, screenshot, size});
  if (const int code = csrbf::gui::parse_command_line(parser, app, "csrbf-picker", 1); code >= 0) return code;

  csrbf::picker::PickerWindow w;
  const QStringList wh = parser.value(size).split('x');
  int width = 0, height = 0;
  if (wh.size() == 2) {
    width = wh[0].toInt();
    height = wh[1].toInt();
  }
  if (width < 200 || height < 200 || width > 8192 || height > 8192) {
    std::cerr << "csrbf-picker: error: --size: expected WIDTHxHEIGHT of at least 200x200, got '"
              << parser.value(size).toStdString() << "'\n";
    return 2;
  }
  // --radius belongs to --controls, as in `csrbf deform` (a deformation file holds its own): alone it
  // was ignored without a word.
  for (const QCommandLineOption* once : {&radius, &controls, &deformation, &screenshot, &size})
    if (parser.values(*once).size() > 1) {
      std::cerr << "csrbf-picker: error: --" << once->names().front().toStdString() << " given "
                << parser.values(*once).size() << " times; give it once\n";
      return 2;
    }
  std::optional<double> r;  // without --radius, the Picker proposes one and says so
  if (parser.isSet(radius)) {
    bool number = false;
    r = parser.value(radius).toDouble(&number);
    if (!number || !(*r >= 1e-150 && *r <= 1e150)) {  // as csrbf deform takes it
      std::cerr << "csrbf-picker: error: --radius must be a number in [1e-150, 1e150], got '"
                << parser.value(radius).toStdString() << "'\n";
      return 2;
    }
    if (!parser.isSet(controls)) {
      std::cerr << "csrbf-picker: error: --radius is the radius of the controls of --controls FILE; give that too"
                << (parser.isSet(deformation) ? " (a --deformation file holds its own radius)" : "") << '\n';
      return 2;
    }
  }
  if ((parser.isSet(controls) || parser.isSet(deformation)) && parser.positionalArguments().isEmpty()) {
    std::cerr << "csrbf-picker: error: --" << (parser.isSet(controls) ? "controls" : "deformation")
              << " moves a mesh: give the mesh file too (csrbf-picker MESH --"
              << (parser.isSet(controls) ? "controls" : "deformation") << " FILE)\n";
    return 2;
  }
  if (parser.isSet(screenshot)) {
    // Never one of the files it reads (the trial wrote a PNG over the controls, exit 0).
    std::vector<std::filesystem::path> inputs;
    if (!parser.positionalArguments().isEmpty()) {
      const std::filesystem::path mesh = parser.positionalArguments().front().toStdString();
      inputs = csrbf::io::mesh_side_files(mesh);
      inputs.push_back(mesh);
    }
    if (parser.isSet(controls)) inputs.push_back(parser.value(controls).toStdString());
    if (parser.isSet(deformation)) {
      const auto named = csrbf::io::referenced_files(parser.value(deformation).toStdString());
      inputs.insert(inputs.end(), named.begin(), named.end());
      inputs.push_back(parser.value(deformation).toStdString());
    }
    if (const int code = csrbf::gui::check_screenshot(parser.value(screenshot), inputs, "csrbf-picker"); code >= 0)
      return code;
  }
  if (parser.isSet(controls) && parser.isSet(deformation)) {
    std::cerr << "csrbf-picker: error: give --deformation FILE or --controls FILE, not both\n";
    return 2;
  }
  w.resize(width, height);
  w.show();
  bool ok = true;
  const QStringList args = parser.positionalArguments();
  if (!args.isEmpty()) ok = w.open_mesh(args.front());
  if (ok && parser.isSet(deformation)) ok = w.load_deformation(parser.value(deformation));
  if (ok && parser.isSet(controls)) ok = w.load_controls(parser.value(controls), r);
  if (parser.isSet(screenshot)) {
    if (!ok) {
      std::cerr << "csrbf-picker: error: " << w.error_text().toStdString() << '\n';
      return 1;
    }
    QApplication::processEvents();
    w.reset_camera();
    if (!w.save_screenshot(parser.value(screenshot))) {
      std::cerr << "csrbf-picker: error: cannot write " << parser.value(screenshot).toStdString() << '\n';
      return 1;
    }
    w.setProperty("noPrompt", true);
    return 0;
  }
  w.offer_recovery();
  return QApplication::exec();
}
