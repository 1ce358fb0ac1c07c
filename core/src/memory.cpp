#include "objscan/core/memory.h"

#include <sys/resource.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>

namespace objscan {
namespace {

/// The first number in a file such as memory.max ("max" and unreadable files give nullopt).
std::optional<std::uint64_t> numberInFile(const char* path) {
  std::ifstream in(path);
  std::string text;
  if (!(in >> text)) return std::nullopt;
  std::uint64_t value = 0;
  const auto [ptr, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || ptr != text.data() + text.size()) return std::nullopt;
  return value;
}

std::optional<std::uint64_t> memAvailable() {
  std::ifstream in("/proc/meminfo");
  std::string key, unit;
  std::uint64_t value = 0;
  while (in >> key >> value >> unit) {
    if (key == "MemAvailable:") return value * 1024;
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::uint64_t> availableMemoryBytes() {
  if (const char* limit = std::getenv(kMemoryLimitEnv); limit != nullptr && *limit != '\0') {
    const std::string text(limit);
    double value = 0.0;
    const auto [ptr, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    const std::string suffix(ptr, text.data() + text.size());
    const double scale = suffix.empty()                   ? 1.0
                         : suffix == "k" || suffix == "K" ? 1e3
                         : suffix == "m" || suffix == "M" ? 1e6
                         : suffix == "g" || suffix == "G" ? 1e9
                                                          : -1.0;
    const double bytes = value * scale;
    // Whole bytes from 1 up to 2^63: anything else is a typo, never "no memory" or "unlimited".
    if (error != std::errc() || scale < 0.0 || !std::isfinite(bytes) || bytes < 1.0 ||
        bytes > 9.2e18) {
      throw std::invalid_argument(std::string(kMemoryLimitEnv) + "='" + text +
                                  "' is not a size in bytes from 1 to 9.2e18 (e.g. 2000000000 or "
                                  "2G; k, M and G are powers of 1000)");
    }
    return static_cast<std::uint64_t>(bytes);
  }
  std::optional<std::uint64_t> available = memAvailable();
  const auto lower = [&available](std::uint64_t left) {
    if (!available || left < *available) available = left;
  };
  const std::optional<std::uint64_t> max = numberInFile("/sys/fs/cgroup/memory.max");
  const std::optional<std::uint64_t> used = numberInFile("/sys/fs/cgroup/memory.current");
  if (max && used) lower(*max > *used ? *max - *used : 0);
  // An address-space limit (ulimit -v) ends in std::bad_alloc as surely as a full machine.
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    std::ifstream status("/proc/self/status");
    std::uint64_t kb = 0;
    std::string line;
    while (std::getline(status, line)) {
      if (line.rfind("VmSize:", 0) == 0) {
        kb = std::strtoull(line.c_str() + 7, nullptr, 10);
        break;
      }
    }
    const std::uint64_t in_use = kb * 1024;
    lower(limit.rlim_cur > in_use ? limit.rlim_cur - in_use : 0);
  }
  return available;
}

std::string availableMemoryText(std::uint64_t available) {
  const char* limit = std::getenv(kMemoryLimitEnv);
  if (limit != nullptr && *limit != '\0') {
    return "the " + bytesText(available) + " " + kMemoryLimitEnv + " allows";
  }
  struct rlimit address_space {};
  if (::getrlimit(RLIMIT_AS, &address_space) == 0 && address_space.rlim_cur != RLIM_INFINITY) {
    return "the " + bytesText(available) + " free within this process's limits (ulimit -v)";
  }
  return "the " + bytesText(available) + " this machine has free";
}

std::string bytesText(std::uint64_t bytes) {
  static constexpr const char* kUnits[] = {"bytes", "kB", "MB", "GB", "TB"};
  double value = static_cast<double>(bytes);
  int unit = 0;
  while (value >= 1000.0 && unit < 4) {
    value /= 1000.0;
    ++unit;
  }
  char text[32];
  if (unit == 0) {
    std::snprintf(text, sizeof text, "%ju bytes", static_cast<std::uintmax_t>(bytes));
  } else {
    std::snprintf(text, sizeof text, value < 10.0 ? "%.1f %s" : "%.0f %s", value, kUnits[unit]);
  }
  return text;
}

}  // namespace objscan
