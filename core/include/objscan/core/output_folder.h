#pragma once

#include <filesystem>
#include <string>
#include <system_error>

#include "objscan/core/error.h"

/// Results folders: created up front, and folder outputs (objects/, renders/) staged beside their
/// final name and swapped in whole, so a folder never mixes two runs' files.
namespace objscan {

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

/// Creates OUT/NAME.partial empty (removing what an interrupted run left there) and returns it.
/// Outputs that are folders are written there and moved into place by swapInFolder.
inline std::filesystem::path freshPartialFolder(const std::filesystem::path& out,
                                                const std::string& name) {
  const std::filesystem::path partial = out / (name + ".partial");
  std::error_code ec;
  std::filesystem::remove_all(partial, ec);
  if (!std::filesystem::create_directory(partial, ec) || ec) {
    throw OutputError(partial, "cannot create a folder" + (ec ? ": " + ec.message() : ""));
  }
  return partial;
}

/// Replaces OUT/NAME with OUT/NAME.partial, so OUT/NAME never mixes one run's files with
/// another's.
inline void swapInFolder(const std::filesystem::path& out, const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path target = out / name, partial = out / (name + ".partial"),
                 old = out / (name + ".old");
  std::error_code ec;
  fs::remove_all(old, ec);
  if (fs::exists(target)) {
    fs::rename(target, old, ec);
    if (ec) throw OutputError(target, "cannot replace the folder: " + ec.message());
  }
  fs::rename(partial, target, ec);
  if (ec) throw OutputError(target, "cannot move the new folder into place: " + ec.message());
  fs::remove_all(old, ec);
}

}  // namespace objscan
