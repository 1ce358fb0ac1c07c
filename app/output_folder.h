#pragma once

#include <filesystem>
#include <string>
#include <system_error>

#include "objscan/core/error.h"

namespace objscan::app {

/// Creates `out` (and its parents) if needed; throws OutputError naming it when it cannot be a
/// folder (no permission, a file in the way).
inline void prepareOutputFolder(const std::filesystem::path& out) {
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec || !std::filesystem::is_directory(out)) {
    throw OutputError(out, "cannot create the output folder" +
                               (ec ? ": " + ec.message() : std::string(" (a file is in the way)")));
  }
}

}  // namespace objscan::app
