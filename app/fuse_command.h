#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "objscan/fusion/pipeline.h"

namespace objscan::app {

struct FuseCommandOptions {
  std::string source;  ///< a <source> as openFrameSource takes it
  std::filesystem::path out;
  fusion::FusionConfig config;
  /// Empty: track with ICP. "groundtruth": the poses the source carries. Otherwise a TUM
  /// trajectory file; each frame takes the pose nearest in time (within 20 ms).
  std::string poses;
  std::size_t start = 0;
  std::optional<std::size_t> end;
  std::size_t every = 1;
  std::filesystem::path intrinsics;  ///< optional intrinsics.json replacing the source's
  bool no_color = false;
};

/// `objscan fuse`: fuses a source into OUT/mesh.ply and OUT/trajectory.txt and prints a summary
/// (frames, lost frames, blocks, memory, time per stage; trajectory error when the source has
/// ground truth). Ctrl-C stops reading and still writes what was fused. Returns the exit code.
int runFuse(const FuseCommandOptions& options);

}  // namespace objscan::app
