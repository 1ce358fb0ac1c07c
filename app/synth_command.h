#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace objscan::app {

struct SynthOptions {
  std::filesystem::path out;
  std::string preset = "desk";
  int objects = 10;
  std::filesystem::path object_dir;
  int frames = 300;
  std::uint64_t seed = 1;
  std::string noise = "on";
  std::string clutter = "plain";     ///< "plain" or "hard" (SceneConfig::hard_clutter)
  std::filesystem::path intrinsics;  ///< optional intrinsics.json; Xtion defaults otherwise
  /// Frames also written as labelled single views (views/*.pcd; writeSyntheticRecording).
  int views = 0;
};

/// `objscan synth`: composes a scene, renders it along a hand-held path and writes the recording
/// with its ground truth; prints a summary to stdout.
void runSynth(const SynthOptions& options);

}  // namespace objscan::app
