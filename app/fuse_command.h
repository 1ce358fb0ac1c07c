#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "objscan/capture/openni.h"
#include "objscan/core/trajectory.h"
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
  /// Record the live source's raw streams to this .oni while fusing (scan --record).
  std::optional<capture::LiveRecording> record;
};

/// What a fusion run did, for the summary and for `objscan scan`'s timings.
struct FuseOutcome {
  std::string source_description;
  bool live = false;
  std::size_t frames_read = 0, frames_fused = 0, frames_lost = 0, frames_without_depth = 0;
  std::size_t frames_processed = 0;  ///< handed to fusion (fused, lost or without depth)
  std::size_t bad_frames = 0, without_pose = 0;
  std::string first_loss;  ///< "frame N: why", empty when tracking never failed
  std::size_t blocks = 0;
  double volume_mb = 0.0;
  float voxel_size_m = 0.0f;
  std::size_t mesh_vertices = 0, mesh_triangles = 0;
  std::filesystem::path mesh_file, trajectory_file;
  double fuse_s = 0.0, mesh_s = 0.0;
  fusion::FrameTimings per_frame_ms;   ///< mean over the frames processed
  std::optional<TrajectoryError> ate;  ///< against the source's ground truth, when it has one
  /// Stopped by Ctrl-C / SIGTERM (or, with `stop_after`, by a limit): the outputs hold the frames
  /// fused before it.
  bool interrupted = false;
  std::string stopped_by;  ///< "Ctrl-C / SIGTERM", "frame limit", "time limit"; empty at the end
  /// A live sensor stopped delivering (unplugged), or the recording stopped early (a lost sensor,
  /// a nearly full disk): the error. The outputs hold what came before.
  std::string sensor_lost;
  std::optional<capture::RecordSummary> recording;  ///< with FuseCommandOptions::record
  std::filesystem::path recording_file;
};

/// Limits of a fusion run besides the source's end.
struct FuseLimits {
  std::optional<std::size_t> max_frames;  ///< frames read (not fused) before stopping
  std::optional<double> max_seconds;      ///< wall time of reading before stopping
  std::string progress_label = "fusing frames";
  /// Ctrl-C ends capture on a live source and is then forgotten (StopSignals::clear), so that only
  /// a later one stops what follows (scan).
  bool live_stop_ends_capture = false;
  /// Called once the frames are fused, just before mesh.ply and trajectory.txt are written.
  std::function<void()> before_writing;
};

/// Fuses options.source into OUT/mesh.ply and OUT/trajectory.txt. Polls StopSignals (the caller
/// installs them): a stop ends reading, and what was fused is still written. Throws InputError
/// when nothing could be fused, OutputError when the files cannot be written.
FuseOutcome fuseSource(const FuseCommandOptions& options, const FuseLimits& limits = {});

/// For a run whose sensor was lost: prints the one error line (after the summary) and returns
/// exit code 1; otherwise returns 0.
int reportSensorLoss(const FuseOutcome& outcome);

/// Prints fuse's summary lines (source, frames, volume, mesh, trajectory, time, ATE) to stdout.
void printFuseSummary(const FuseOutcome& outcome);

/// `objscan fuse`: fuses a source into OUT/mesh.ply and OUT/trajectory.txt and prints a summary
/// (frames, lost frames, blocks, memory, time per stage; trajectory error when the source has
/// ground truth). Ctrl-C stops reading and still writes what was fused. Returns the exit code.
int runFuse(const FuseCommandOptions& options);

}  // namespace objscan::app
