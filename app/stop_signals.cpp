#include "stop_signals.h"

#include <chrono>
#include <thread>

#include "objscan/core/clock.h"

namespace objscan::app {
namespace {

std::atomic<bool> g_stop{false};

extern "C" void onStopSignal(int) { g_stop.store(true); }

}  // namespace

StopSignals::StopSignals() {
  g_stop.store(false);
  struct sigaction action {};
  action.sa_handler = onStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &old_int_);
  sigaction(SIGTERM, &action, &old_term_);
}

StopSignals::~StopSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

std::atomic<bool>& StopSignals::flag() { return g_stop; }

void StopSignals::clear() { g_stop.store(false); }

void StopSignals::waitForStop(std::optional<double> max_s) {
  const auto start = SteadyClock::now();
  while (!stopRequested() && (!max_s || secondsSince(start) < *max_s)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

}  // namespace objscan::app
