#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdio>
#include <mutex>
#include <string>

namespace objscan {

/// Progress of a long stage, drawn on stderr.
/// On a terminal it redraws one line in place (at most 10 times a second); otherwise (a log file,
/// CI) it prints a plain line at every 10 % and at least every 10 s, so logs stay short and
/// readable. Silent when the log level is below Info (--quiet). advance() is thread-safe and cheap
/// enough to call once per item from parallel loops.
class ProgressBar {
 public:
  enum class Style {
    kAuto,    ///< kRedraw when the stream is a terminal, kLines otherwise
    kRedraw,  ///< "\r"-redrawn bar
    kLines,   ///< one line per 10 % step
  };

  /// `total` = 0 means the total is unknown: only the count and rate are shown. An empty `label`
  /// draws nothing.
  ProgressBar(std::string label, std::size_t total, Style style = Style::kAuto,
              std::FILE* out = stderr);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void advance(std::size_t n = 1);
  /// Prints the final line ("label: 100 % (N) in T s"). Called by the destructor if not called,
  /// except while an exception unwinds the stage: then a redrawn bar is cleared and nothing is
  /// printed, so the error that follows stands alone.
  void finish();

  std::size_t done() const { return done_.load(); }

 private:
  void draw(std::size_t done, bool final);

  std::string label_;
  std::size_t total_;
  bool redraw_;
  bool silent_;
  std::FILE* out_;
  std::atomic<std::size_t> done_{0};
  std::atomic<bool> finished_{false};
  std::mutex draw_mutex_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  int last_decile_ = -1;
  bool drawn_ = false;
  int uncaught_at_start_ = 0;
};

}  // namespace objscan
