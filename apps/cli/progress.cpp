#include "progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace csrbf::cli {

namespace {

std::string duration(double s) {
  char b[32];
  if (s < 60)
    std::snprintf(b, sizeof b, "%.0f s", std::ceil(s));
  else if (s < 3600)
    std::snprintf(b, sizeof b, "%d min %02d s", int(s) / 60, int(s) % 60);
  else
    std::snprintf(b, sizeof b, "%d h %02d min", int(s) / 3600, int(s) / 60 % 60);
  return b;
}

}  // namespace

bool TerminalProgress::terminal() { return isatty(STDERR_FILENO) == 1; }

TerminalProgress::TerminalProgress(bool enabled) : enabled_(enabled) {
  if (!enabled_) return;
  if (const char* d = std::getenv("CSRBF_PROGRESS_DELAY_MS")) {
    char* end = nullptr;
    const long ms = std::strtol(d, &end, 10);
    if (end != d && *end == 0 && ms >= 0 && ms <= 60000) delay_ = std::chrono::milliseconds(ms);
  }
  ticker_ = std::thread([this] { tick(); });
}

TerminalProgress::~TerminalProgress() {
  if (!enabled_) return;
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
    clear();
  }
  cv_.notify_all();
  ticker_.join();
}

void TerminalProgress::note(const std::string& text) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(m_);
  clear();
  std::fprintf(stderr, "csrbf: %s\n", text.c_str());
  std::fflush(stderr);
}

void TerminalProgress::begin(const std::string& phase, double total, double seconds) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(m_);
  clear();
  phase_ = phase;
  total_ = total;
  seconds_ = seconds;
  done_ = 0;
  start_ = Clock::now();
  active_ = true;
}

void TerminalProgress::advance(double done) {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(m_);
  done_ = done;
}

void TerminalProgress::end() {
  if (!enabled_) return;
  std::lock_guard<std::mutex> lock(m_);
  clear();
  active_ = false;
}

void TerminalProgress::clear() {
  if (!shown_) return;
  std::fputs("\r\033[K", stderr);
  std::fflush(stderr);
  shown_ = false;
}

std::string TerminalProgress::line() const {
  const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
  // The fraction done: counted work where there is some, else the time against the prediction
  // (held below 1: a prediction is not a promise).
  double fraction = -1, left = -1;
  if (total_ > 0 && done_ > 0) {
    fraction = std::min(done_ / total_, 1.0);
    left = elapsed * (total_ - done_) / done_;
  } else if (seconds_ > 0) {
    fraction = std::min(elapsed / seconds_, 0.99);
    left = std::max(seconds_ - elapsed, 0.0);
  }
  char b[160];
  if (fraction < 0) {
    if (total_ == 0 && done_ > 0)
      std::snprintf(b, sizeof b, "  %-10s %.0f, %s", phase_.c_str(), done_, duration(elapsed).c_str());
    else
      std::snprintf(b, sizeof b, "  %-10s %s", phase_.c_str(), duration(elapsed).c_str());
    return b;
  }
  constexpr int kWidth = 30;
  const int filled = int(fraction * kWidth);
  const std::string bar = std::string(std::size_t(filled), '#') + std::string(std::size_t(kWidth - filled), '.');
  const bool predicted = !(total_ > 0 && done_ > 0);
  const std::string when = predicted && elapsed > seconds_ ? "over the " + duration(seconds_) + " predicted"
                           : left < 1                      ? "almost done"
                                                           : "about " + duration(left) + " left";
  std::snprintf(b, sizeof b, "  %-10s [%s] %3.0f%%  %s, %s", phase_.c_str(), bar.c_str(), 100 * fraction,
                duration(elapsed).c_str(), when.c_str());
  return b;
}

void TerminalProgress::tick() {
  std::unique_lock<std::mutex> lock(m_);
  while (!stop_) {
    cv_.wait_for(lock, std::chrono::milliseconds(delay_.count() == 0 ? 20 : 200));
    if (stop_ || !active_ || Clock::now() - start_ < delay_) continue;
    std::fprintf(stderr, "\r\033[K%s", line().c_str());
    std::fflush(stderr);
    shown_ = true;
  }
}

}  // namespace csrbf::cli
