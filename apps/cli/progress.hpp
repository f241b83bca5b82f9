// The progress of a long `csrbf morph` on a terminal: after a phase has run a second, a bar on
// standard error with the fraction done and the time left (from the work done, or from the
// prediction where the work cannot be counted), redrawn 5 times a second by a thread of its own,
// and the notes (the radius chosen, the prediction) as lines above it. Off where standard error
// is not a terminal, and under --quiet; never in the report or --json.
#pragma once

#include "csrbf/morph/progress.hpp"

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace csrbf::cli {

class TerminalProgress final : public morph::Progress {
 public:
  /// enabled: false draws nothing. A bar shows after a phase has run `delay` (1 s; the
  /// CSRBF_PROGRESS_DELAY_MS environment variable sets it, for tests; at 0 the bar is redrawn every
  /// 20 ms).
  explicit TerminalProgress(bool enabled);
  ~TerminalProgress() override;
  TerminalProgress(const TerminalProgress&) = delete;
  TerminalProgress& operator=(const TerminalProgress&) = delete;

  /// True where standard error is a terminal.
  static bool terminal();

  void note(const std::string& line) override;
  void begin(const std::string& phase, double total, double seconds) override;
  void advance(double done) override;
  void end() override;

 private:
  using Clock = std::chrono::steady_clock;
  void tick();
  std::string line() const;  // the bar of the current phase (the mutex held)
  void clear();              // the bar's line erased (the mutex held)

  bool enabled_;
  std::chrono::milliseconds delay_{1000};
  std::mutex m_;
  std::condition_variable cv_;
  std::thread ticker_;
  bool stop_ = false, active_ = false, shown_ = false;
  std::string phase_;
  double total_ = 0, seconds_ = 0, done_ = 0;
  Clock::time_point start_;
};

}  // namespace csrbf::cli
