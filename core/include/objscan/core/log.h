#pragma once

#include <string_view>

/// Logging to stderr for every stage. The command line sets the level once (--quiet / --verbose);
/// library code only calls the functions below. Thread-safe: lines from several threads never mix.
namespace objscan::log {

enum class Level {
  kError = 0,    ///< --quiet: errors only
  kWarning = 1,  ///< also warnings
  kInfo = 2,     ///< default: also progress and what each stage did
  kDebug = 3,    ///< --verbose: also details useful when something looks wrong
};

void setLevel(Level level);
Level level();
bool enabled(Level level);

void error(std::string_view message);
void warning(std::string_view message);
void info(std::string_view message);
void debug(std::string_view message);

}  // namespace objscan::log
