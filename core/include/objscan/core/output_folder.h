#pragma once

#include <filesystem>
#include <string>
#include <system_error>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

/// Results folders: created up front, and folder outputs (objects/, renders/) staged beside their
/// final name and swapped in whole, so a folder never mixes two runs' files.
namespace objscan {

/// One run's hold on a results folder: an exclusive lock (flock) on the folder itself, so that
/// nothing is left in it. Released when the object goes or the process ends, however it ends.
class OutputFolderLock {
 public:
  OutputFolderLock() = default;
  /// Takes the lock of the existing folder `out`. Throws FolderBusyError naming the process
  /// that holds it (from /proc/locks), OutputError when the folder cannot be opened.
  explicit OutputFolderLock(const std::filesystem::path& out);
  ~OutputFolderLock();
  OutputFolderLock(OutputFolderLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  OutputFolderLock& operator=(OutputFolderLock&& other) noexcept;
  OutputFolderLock(const OutputFolderLock&) = delete;
  OutputFolderLock& operator=(const OutputFolderLock&) = delete;

  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

/// Creates `out` (and its parents) if needed and locks it for this run (OutputFolderLock), so
/// that two runs never write one folder. Throws OutputError naming it when it cannot be a folder
/// (no permission, a file in the way), FolderBusyError when another run holds it.
[[nodiscard]] OutputFolderLock prepareOutputFolder(const std::filesystem::path& out);

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
/// another's; the staged files are made durable first (makeStagedFolderDurable).
inline void swapInFolder(const std::filesystem::path& out, const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path target = out / name, partial = out / (name + ".partial"),
                 old = out / (name + ".old");
  makeStagedFolderDurable(partial);
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
