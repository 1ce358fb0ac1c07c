// Peak-memory figures the benchmarks share: the kernel's counters for this process.
#pragma once

#include <cstdlib>
#include <fstream>
#include <string>

namespace objscan::bench {

/// A field of /proc/self/status in bytes (VmRSS, VmHWM); 0 when absent.
inline double statusBytes(const std::string& field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind(field + ":", 0) == 0) return 1024.0 * std::atof(line.c_str() + field.size() + 1);
  }
  return 0.0;
}

/// Resets the high-water mark of the resident set to the current size (Linux 4.0+); false when
/// the kernel does not let this process do it (then there is no peak to report).
inline bool resetPeakMemory() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  clear.flush();
  return clear.good();
}

}  // namespace objscan::bench
