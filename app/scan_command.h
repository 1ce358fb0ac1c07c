#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "discover_command.h"
#include "fuse_command.h"
#include "render_command.h"

namespace objscan::app {

struct ScanCommandOptions {
  std::string source;  ///< as fuse takes it; empty: the first live sensor
  std::filesystem::path out;
  FuseCommandOptions fuse;          ///< source and out are set from the above
  FuseLimits limits;                ///< --frames, --seconds
  DiscoverCommandOptions discover;  ///< meshes and out are set by the scan
  RenderCommandOptions render;      ///< dir is set by the scan
  /// A ground-truth scene mesh with per-vertex object_id (objscan synth's scene_gt.ply). Empty:
  /// X.scene_gt.ply beside a recording X.oni, or scene_gt.ply in a recording folder, if present.
  std::filesystem::path ground_truth;
  bool no_ground_truth = false;
  double min_iou = 0.7;  ///< a hypothesis finds an object at this IoU (the paper's label)
};

/// `objscan scan`: fuse, discover, render and report into OUT in one run (see the README's
/// "objscan scan"). Returns the exit code.
int runScan(ScanCommandOptions options);

}  // namespace objscan::app
