#pragma once

#include <atomic>
#include <csignal>
#include <optional>

namespace objscan::app {

/// While alive, Ctrl-C (SIGINT) and SIGTERM set stopRequested() instead of killing the process, so
/// a long command can finish what it has and write valid outputs; the previous handlers come back
/// when it goes.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  /// Set by the handler; an atomic that library calls (capture::recordSession, the pipeline's
  /// stages) poll, and that fusion clears when a stop ends a live capture.
  static std::atomic<bool>& flag();
  static bool stopRequested() { return flag().load(); }
  /// Forgets a stop already requested: `objscan scan` on a sensor takes the first Ctrl-C as the
  /// end of capture and goes on, so only a later one stops the run.
  static void clear();
  /// Waits (with a StopSignals alive) until a stop is requested, or `max_s` seconds have passed
  /// when given: how a server keeps serving until Ctrl-C or its --serve-wait.
  static void waitForStop(std::optional<double> max_s);

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

}  // namespace objscan::app
