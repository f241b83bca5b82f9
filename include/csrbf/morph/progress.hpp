// What a long morph tells its user while it runs: `csrbf morph` draws it on a terminal (a bar per
// phase with the time left), nothing elsewhere. A morph calls these from the thread that runs it.
#pragma once

#include <string>

namespace csrbf::morph {

class Progress {
 public:
  virtual ~Progress() = default;
  /// A line of information: the radius chosen and why, the prediction of the fit's size and time.
  virtual void note(const std::string& line) { (void)line; }
  /// A phase begins ("read", "fit", "evaluate", "quality", "write", "greedy"): `total` units of
  /// work (0: unknown), predicted to take about `seconds` (0: unknown).
  virtual void begin(const std::string& phase, double total = 0, double seconds = 0) {
    (void)phase;
    (void)total;
    (void)seconds;
  }
  /// `done` units of the current phase are done (of its total).
  virtual void advance(double done) { (void)done; }
  /// The current phase has ended.
  virtual void end() {}
};

}  // namespace csrbf::morph
