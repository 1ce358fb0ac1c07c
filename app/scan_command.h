#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "discover_command.h"
#include "fuse_command.h"
#include "render_command.h"

namespace objscan::app {

struct ScanCommandOptions {
  std::string source;  ///< as fuse takes it; empty: the first live sensor
  std::filesystem::path out;
  pipeline::FuseOptions fuse;         ///< source is set from the above
  pipeline::FuseLimits limits;        ///< --frames, --seconds
  DiscoverCommandOptions discover;    ///< meshes and out are set by the scan
  pipeline::PictureOptions pictures;  ///< --top, --size, --view, --ranks-image
  /// A ground-truth scene mesh with per-vertex object_id (objscan synth's scene_gt.ply). Empty:
  /// X.scene_gt.ply beside a recording X.oni, or scene_gt.ply in a recording folder, if present.
  std::filesystem::path ground_truth;
  bool no_ground_truth = false;
  double min_iou = 0.7;       ///< a hypothesis finds an object at this IoU (the paper's label)
  report::Settings settings;  ///< the command line's, for OUT/settings.json
  ServeOptions serve;         ///< --serve: the live page
};

/// --ground-truth FILE as scan checks it before any work: a regular file, a mesh with per-vertex
/// object ids. Throws InputError naming it.
void requireGroundTruthFile(const std::filesystem::path& truth);

/// scan's options as `objscan scan ARGS` gives them (ARGS: what follows the command's name).
/// Throws CLI::ParseError (CLI::CallForHelp for --help) for options scan does not take.
ScanCommandOptions parseScanOptions(const std::vector<std::string>& args);

/// `objscan scan`: fuse, discover, evaluate, render and report into OUT in one run, passing the
/// values from stage to stage and writing each file once (see docs/scan_and_report.md). Returns
/// the exit code.
int runScan(ScanCommandOptions options);

}  // namespace objscan::app
