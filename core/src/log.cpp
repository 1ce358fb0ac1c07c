#include "objscan/core/log.h"

#include <atomic>
#include <cstdio>
#include <mutex>

namespace objscan::log {
namespace {

std::atomic<Level> g_level{Level::kInfo};
std::mutex g_mutex;

void emit(Level at, const char* prefix, std::string_view message) {
  if (!enabled(at)) return;
  std::lock_guard lock(g_mutex);
  std::fprintf(stderr, "%s%.*s\n", prefix, static_cast<int>(message.size()), message.data());
}

}  // namespace

void setLevel(Level level) { g_level.store(level); }
Level level() { return g_level.load(); }
bool enabled(Level at) { return static_cast<int>(at) <= static_cast<int>(g_level.load()); }

void error(std::string_view message) { emit(Level::kError, "error: ", message); }
void warning(std::string_view message) { emit(Level::kWarning, "warning: ", message); }
void info(std::string_view message) { emit(Level::kInfo, "", message); }
void debug(std::string_view message) { emit(Level::kDebug, "debug: ", message); }

}  // namespace objscan::log
