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

/// A phase on a Progress (nothing where null), begun here and ended when it goes out of scope.
class ProgressPhase {
 public:
  ProgressPhase(Progress* p, const std::string& phase, double total = 0, double seconds = 0) : p_(p) {
    if (p_) p_->begin(phase, total, seconds);
  }
  ~ProgressPhase() {
    if (p_) p_->end();
  }
  ProgressPhase(const ProgressPhase&) = delete;
  ProgressPhase& operator=(const ProgressPhase&) = delete;
  void advance(double done) {
    if (p_) p_->advance(done);
  }

 private:
  Progress* p_;
};

}  // namespace csrbf::morph
