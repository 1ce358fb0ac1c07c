#pragma once

#include <time.h>

#include "objscan/core/clock.h"

/// Wall and CPU time of discovery's stages (DiscoveryTimings), private to discovery.
namespace objscan::discovery {

/// CPU time of the process (all threads) or of the calling thread, milliseconds.
inline double cpuMs(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

/// Wall and process CPU time of one stage.
struct Stopwatch {
  SteadyClock::time_point wall = SteadyClock::now();
  double cpu = cpuMs(CLOCK_PROCESS_CPUTIME_ID);
  void stop(double* wall_ms, double* cpu_ms) {
    *wall_ms = millisecondsSince(wall);
    *cpu_ms = cpuMs(CLOCK_PROCESS_CPUTIME_ID) - cpu;
    wall = SteadyClock::now();
    cpu = cpuMs(CLOCK_PROCESS_CPUTIME_ID);
  }
};

}  // namespace objscan::discovery
