#pragma once

#include <atomic>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "objscan/capture/openni.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/trajectory.h"
#include "objscan/core/triangle_mesh.h"
#include "objscan/fusion/pipeline.h"

/// The fusion stage: a <source> read frame by frame into the TSDF volume, tracked by ICP (or at
/// given poses), meshed by marching cubes. Returns values; writing them is the caller's.
namespace objscan::pipeline {

struct FuseOptions {
  std::string source;  ///< a <source> as openFrameSource takes it
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

/// One frame handed to fusion, for a watcher (the live page): valid during the call only.
struct FrameEvent {
  const RgbdFrame& frame;
  const fusion::FrameOutcome& outcome;
  const fusion::Fusion& fusion;
  std::size_t frames_read = 0;   ///< so far, this frame included
  std::size_t frames_total = 0;  ///< the source's known length (within the limits); 0: unknown
};

/// Limits of a fusion run besides the source's end.
struct FuseLimits {
  std::optional<std::size_t> max_frames;  ///< frames read (not fused) before stopping
  std::optional<double> max_seconds;      ///< wall time of reading before stopping
  std::string progress_label = "fusing frames";
  /// Polled once per frame: set (by a signal handler, or another thread), reading stops and what
  /// was fused is kept. Nothing: no stop.
  std::atomic<bool>* stop = nullptr;
  /// A stop ends capture on a live source and is then cleared, so that only a later one stops what
  /// follows (scan: Ctrl-C is how a live capture ends).
  bool live_stop_ends_capture = false;
  /// Called once the source is open and the poses read, before the first frame (the command
  /// prepares its output folder there, so that a source that cannot be opened leaves nothing).
  std::function<void()> after_open;
  /// Called on the fusing thread after every frame handed to fusion; it must return quickly
  /// (copy what it needs, hand work to its own threads). Nothing: no call.
  std::function<void(const FrameEvent&)> on_frame;
  /// Memory the caller holds or is about to take while fusion runs (the live page's volume copy
  /// and its discovery), added to fusion's own when it checks that the volume still fits.
  std::function<double()> extra_memory_bytes;
  /// Called once the frames are read, before the volume is meshed.
  std::function<void()> before_meshing;
};

/// What a fusion run did, besides the mesh and trajectory.
struct FuseStats {
  std::string source_description;
  bool live = false;
  Intrinsics intrinsics;          ///< of the frames fused
  std::string intrinsics_origin;  ///< where they came from
  bool intrinsics_assumed = false;  ///< a default, not the recording's calibration (warned)
  std::string depth_units;          ///< how the source's depth becomes metres
  std::size_t frames_read = 0, frames_fused = 0, frames_lost = 0, frames_without_depth = 0;
  std::size_t frames_processed = 0;  ///< handed to fusion (fused, lost or without depth)
  std::size_t bad_frames = 0, without_pose = 0;
  /// A live sensor's frames never read: gaps in its frame numbers (RgbdFrame::device_frame).
  std::size_t frames_dropped = 0;
  std::string first_loss;  ///< "frame N: why", empty when tracking never failed
  std::size_t blocks = 0;
  double volume_mb = 0.0;
  float voxel_size_m = 0.0f;
  double fuse_s = 0.0, mesh_s = 0.0;
  fusion::FrameTimings per_frame_ms;   ///< mean over the frames processed
  std::optional<TrajectoryError> ate;  ///< against the source's ground truth, when it has one
  /// Stopped by the stop flag (or by a limit): the results hold the frames fused before it.
  bool interrupted = false;
  std::string stopped_by;  ///< "Ctrl-C / SIGTERM", "frame limit", "time limit"; empty at the end
  /// A live sensor stopped delivering (unplugged), or the recording stopped early (a lost sensor,
  /// a nearly full disk): the error. The results hold what came before.
  std::string sensor_lost;
  std::optional<capture::RecordSummary> recording;  ///< with FuseOptions::record
  std::filesystem::path recording_file;
};

struct FusedScene {
  TriangleMesh mesh;
  Trajectory trajectory;  ///< T_W_C of every fused frame
  FuseStats stats;
};

/// Stopped by Ctrl-C / SIGTERM before there was anything to keep (no frame fused yet). The
/// command line maps it to exit code 130.
class Interrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Fuses options.source. Throws InputError when nothing could be fused, Interrupted when stopped
/// before the first frame was fused, std::runtime_error when a sensor was lost before it.
FusedScene fuseSource(const FuseOptions& options, const FuseLimits& limits = {});

}  // namespace objscan::pipeline
