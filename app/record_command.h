#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

namespace objscan::app {

struct RecordCommandOptions {
  std::filesystem::path out;
  std::string device;  ///< URI; empty = the first sensor
  std::optional<std::size_t> frames;
  std::optional<double> seconds;
  bool compress_color = false;
  std::filesystem::path intrinsics;  ///< optional intrinsics.json stored with the recording
};

/// `objscan devices`: one line per sensor OpenNI2 finds (URI, vendor, name, USB ids), or a note
/// that none is attached. Exit 0 either way.
void runDevices();

/// `objscan record`: records a sensor to an .oni (see capture::recordSession), writes the
/// sidecars, prints the summary. Returns the exit code: 0, or 1 when the recording stopped on a
/// fault (the frames before it are in the file and the error line says so).
int runRecord(const RecordCommandOptions& options);

}  // namespace objscan::app
