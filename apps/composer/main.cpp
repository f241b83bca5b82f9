// csrbf-composer: build an animation scene by hand, play it, export a movie.
//   csrbf-composer [SCENE.json] [--screenshot FILE.png] [--size WxH]
#include "composer_window.hpp"
#include "gui_common.hpp"
#include "csrbf/io/inputs.hpp"

#include <QApplication>
#include <QCommandLineParser>
#include <QSurfaceFormat>
#include <QVTKOpenGLNativeWidget.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <vector>

int main(int argc, char** argv) {
  // Qt needs X: without a display, a private Xvfb (as `csrbf animate` does), for --screenshot on servers.
  bool have_display = true;
  const auto display = csrbf::gui::ensure_display("csrbf-composer", have_display);
  if (!have_display) return 1;
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  csrbf::gui::SafeApplication app(argc, argv);
  QApplication::setApplicationName("csrbf-composer");
  QCommandLineParser parser;
  parser.setApplicationDescription("Build an animation scene by hand, play it, export a movie");
  parser.addHelpOption();
  parser.addPositionalArgument("scene", "Scene JSON to open", "[scene]");
  const QCommandLineOption screenshot("screenshot", "Render the window once to this PNG and exit", "file");
  const QCommandLineOption time("time", "Time shown, in seconds (default 0)", "t", "0");
  const QCommandLineOption size("size", "Window size WIDTHxHEIGHT (default 1280x820)", "WxH", "1280x820");
  parser.addOptions({screenshot, time, size});
  if (const int code = csrbf::gui::parse_command_line(parser, app, "csrbf-composer", 1); code >= 0) return code;
  bool time_ok = false;
  const double t = parser.value(time).toDouble(&time_ok);
  if (!time_ok || !(std::abs(t) <= 1e6)) {
    std::cerr << "csrbf-composer: error: --time: expected seconds, a number in [-1e6, 1e6], got '"
              << parser.value(time).toStdString() << "'\n";
    return 2;
  }
  if (parser.isSet(screenshot)) {
    // Never the scene or a file it names (the trial wrote a PNG over the scene, exit 0).
    std::vector<std::filesystem::path> inputs;
    if (!parser.positionalArguments().isEmpty())
      inputs = csrbf::io::referenced_files(parser.positionalArguments().front().toStdString());
    if (const int code = csrbf::gui::check_screenshot(parser.value(screenshot), inputs, "csrbf-composer"); code >= 0)
      return code;
  }
  const QStringList wh = parser.value(size).split('x');
  const int width = wh.size() == 2 ? wh[0].toInt() : 0, height = wh.size() == 2 ? wh[1].toInt() : 0;
  if (width < 200 || height < 200 || width > 8192 || height > 8192) {
    std::cerr << "csrbf-composer: error: --size: expected WIDTHxHEIGHT of at least 200x200, got '"
              << parser.value(size).toStdString() << "'\n";
    return 2;
  }
  csrbf::composer::ComposerWindow w;
  w.resize(width, height);
  w.show();
  const QStringList args = parser.positionalArguments();
  const bool ok = args.isEmpty() || w.open_scene(args.front());
  w.set_time(t);
  if (parser.isSet(screenshot)) {
    if (!ok) {
      std::cerr << "csrbf-composer: error: " << w.error_text().toStdString() << '\n';
      return 1;
    }
    QApplication::processEvents();
    if (!w.save_screenshot(parser.value(screenshot))) {
      std::cerr << "csrbf-composer: error: cannot write " << parser.value(screenshot).toStdString() << '\n';
      return 1;
    }
    w.setProperty("noPrompt", true);
    return 0;
  }
  w.offer_recovery();
  return QApplication::exec();
}
