#pragma once

#include <chrono>

/// Wall-clock timing of stages: one steady clock and its two conversions, for the whole project.
namespace objscan {

using SteadyClock = std::chrono::steady_clock;

/// Seconds of wall time since `start`.
inline double secondsSince(SteadyClock::time_point start) {
  return std::chrono::duration<double>(SteadyClock::now() - start).count();
}

/// Milliseconds of wall time since `start`.
inline double millisecondsSince(SteadyClock::time_point start) {
  return std::chrono::duration<double, std::milli>(SteadyClock::now() - start).count();
}

}  // namespace objscan
