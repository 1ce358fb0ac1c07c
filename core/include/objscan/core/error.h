#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace objscan {

/// A file or argument given to objscan cannot be used: missing, a directory, empty, truncated,
/// corrupt, or in a format objscan does not read. The message names the path and the problem in one
/// line, e.g. "scan.ply: face 12 refers to vertex 99, but the file has 8 vertices".
/// The command line maps it to exit code 2 (bad usage or bad input).
class InputError : public std::runtime_error {
 public:
  InputError(const std::filesystem::path& path, const std::string& problem)
      : std::runtime_error(path.string() + ": " + problem), path_(path) {}

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// Writing an output failed (disk full, permission denied, directory missing). The command line
/// maps it to exit code 1 (runtime failure).
class OutputError : public std::runtime_error {
 public:
  OutputError(const std::filesystem::path& path, const std::string& problem)
      : std::runtime_error(path.string() + ": " + problem) {}
};

/// Another run (another process, or another command of this one) is writing the results folder.
/// The message names the folder and the process holding it. The command line maps it to exit
/// code 1 (runtime failure): nothing is wrong with the input, and the same command works later.
class FolderBusyError : public OutputError {
 public:
  using OutputError::OutputError;
};

/// Live capture was asked of "the first sensor", but OpenNI2 finds none attached. The message says
/// what to connect or name instead. The command line maps it to exit code 3 (no sensor).
/// A device URI that names no device is an InputError instead.
class NoSensorError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace objscan
