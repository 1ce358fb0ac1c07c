#pragma once

#include <filesystem>

#include "objscan/pipeline/fuse.h"
#include "objscan/report/results.h"
#include "serve.h"

namespace objscan::app {

struct FuseCommandOptions {
  pipeline::FuseOptions fuse;
  std::filesystem::path out;
  report::Settings settings;  ///< the command line's, for OUT/settings.json
  ServeOptions serve;         ///< --serve: the live page
};

/// For a run whose sensor was lost: prints the one error line (after the summary) and returns
/// exit code 1; otherwise returns 0.
int reportSensorLoss(const pipeline::FuseStats& stats);

/// Prints fuse's summary lines (source, frames, volume, mesh, trajectory, time, ATE) to stdout.
void printFuseSummary(const pipeline::FusedScene& fused, const std::filesystem::path& out);

/// `objscan fuse`: fuses a source into OUT/mesh.ply and OUT/trajectory.txt and prints a summary
/// (frames, lost frames, blocks, memory, time per stage; trajectory error when the source has
/// ground truth). Ctrl-C stops reading and still writes what was fused. Returns the exit code.
int runFuse(const FuseCommandOptions& options);

}  // namespace objscan::app
