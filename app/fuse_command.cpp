#include "fuse_command.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <system_error>

#include "exit_codes.h"
#include "frame_sources.h"
#include "objscan/capture/read_ahead.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "objscan/fusion/marching_cubes.h"
#include "output_folder.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// Frame time stamps and trajectory time stamps pair up within this (the TUM tools' default).
constexpr double kPoseMatchS = 0.02;

}  // namespace

FuseOutcome fuseSource(const FuseCommandOptions& options, const FuseLimits& limits) {
  options.config.validate();  // a bad setting is reported before anything is opened
  SourceOptions source_options;
  source_options.selection.start = options.start;
  source_options.selection.end = options.end;
  source_options.selection.every = options.every;
  source_options.selection.validate();
  if (!options.intrinsics.empty()) {
    source_options.intrinsics = readIntrinsicsJson(options.intrinsics);
    source_options.intrinsics_origin = options.intrinsics.string();
  }
  source_options.record = options.record;
  std::unique_ptr<capture::FrameSource> source = openFrameSource(options.source, source_options);
  // A recording or folder is decoded a few frames ahead, on a thread of its own, while the
  // previous frames are fused; a sensor is read directly, so that the freshest frame is fused.
  if (!source->info().live) {
    source = std::make_unique<capture::ReadAheadSource>(std::move(source));
  }
  const capture::SourceInfo& info = source->info();

  std::optional<Trajectory> given;
  if (options.poses == "groundtruth") {
    if (!info.ground_truth || info.ground_truth->empty()) {
      throw InputError(options.source, "--poses groundtruth: this source carries no ground truth");
    }
    given = info.ground_truth;
  } else if (!options.poses.empty()) {
    given = readTumTrajectory(options.poses);
  }
  prepareOutputFolder(options.out);
  log::info("fusing " + info.description + (given ? " at the given poses" : " with ICP tracking"));

  FuseOutcome out;
  out.source_description = info.description;
  out.live = info.live;
  std::optional<fusion::Fusion> fusion;
  fusion::FrameTimings totals;
  std::string first_skip;
  const auto start = Clock::now();
  {
    std::size_t total = info.frame_count.value_or(0);
    if (limits.max_frames && (total == 0 || *limits.max_frames < total)) {
      total = *limits.max_frames;
    }
    ProgressBar progress(limits.progress_label, total);
    std::size_t read = 0;
    for (;;) {
      if (StopSignals::stopRequested()) {
        out.interrupted = true;
        out.stopped_by = "Ctrl-C / SIGTERM";
        if (limits.live_stop_ends_capture && info.live) StopSignals::clear();
        break;
      }
      if (limits.max_frames && read >= *limits.max_frames) {
        out.stopped_by = "frame limit";
        break;
      }
      if (limits.max_seconds &&
          std::chrono::duration<double>(Clock::now() - start).count() >= *limits.max_seconds) {
        out.stopped_by = "time limit";
        break;
      }
      capture::FrameResult r;
      try {
        r = source->next();
      } catch (const std::runtime_error& e) {
        if (!info.live) throw;
        // A sensor unplugged mid-capture: what was fused (and recorded) so far is kept.
        out.sensor_lost = e.what();
        out.stopped_by = "sensor lost";
        break;
      }
      if (r.status == capture::FrameStatus::kEndOfStream) break;
      ++read;
      progress.advance();
      if (r.status == capture::FrameStatus::kBadFrame) {
        log::warning("skipped a frame: " + r.reason);
        ++out.bad_frames;
        continue;
      }
      ++out.frames_read;
      RgbdFrame& frame = r.frame;
      if (options.no_color) frame.color_rgb.release();
      std::optional<Pose> pose;
      if (given) {
        pose = nearestPose(*given, frame.stamp_s, kPoseMatchS);
        if (!pose) {
          ++out.without_pose;
          continue;
        }
      }
      if (!fusion) {
        // With ground truth, start where it says the first frame was, so that the mesh and the
        // trajectory land in the dataset's world frame (and line up with its scene model).
        Pose initial = Pose::Identity();
        if (info.ground_truth) {
          initial = nearestPose(*info.ground_truth, frame.stamp_s, kPoseMatchS).value_or(initial);
        }
        fusion.emplace(options.config, frame.intrinsics, initial);
      }
      const fusion::FrameOutcome outcome = fusion->process(frame, pose);
      totals += outcome.timings;
      if (outcome.status == fusion::FrameStatus::kLost) {
        log::debug("frame " + std::to_string(frame.index) + ": tracking lost: " + outcome.reason);
        if (out.first_loss.empty()) {
          out.first_loss = "frame " + std::to_string(frame.index) + ": " + outcome.reason;
        }
      } else if (outcome.status == fusion::FrameStatus::kNoDepth && first_skip.empty()) {
        first_skip = "frame " + std::to_string(frame.index) + ": " + outcome.reason;
      }
    }
  }
  out.fuse_s = std::chrono::duration<double>(Clock::now() - start).count();
  if (out.interrupted && (!fusion || fusion->trajectory().empty())) {
    std::string recorded;
    try {  // a recording of the frames that came keeps them; with none, no file is left
      if (const auto r = capture::finishRecording(*source, "interrupted")) {
        recorded = "; the " + std::to_string(r->depth_frames) + " frames recorded are in " +
                   options.record->out.string();
      }
    } catch (const std::runtime_error&) {
    }
    throw Interrupted("stopped by Ctrl-C / SIGTERM before a frame was fused: nothing was fused" +
                      recorded);
  }
  // The recording is closed (and renamed into place) before anything else can fail.
  out.recording = capture::finishRecording(*source, out.interrupted          ? "interrupted"
                                                    : out.stopped_by.empty() ? "end of source"
                                                                             : out.stopped_by);
  if (options.record) out.recording_file = options.record->out;
  if (out.recording && out.recording->failed && out.sensor_lost.empty()) {
    // An unplugged virtual sensor or a nearly full disk ends the stream without an exception.
    out.sensor_lost =
        out.recording_file.string() + ": recording stopped early: " + out.recording->stop_reason;
  }
  if ((!fusion || fusion->trajectory().empty()) && !out.sensor_lost.empty()) {
    throw std::runtime_error(out.sensor_lost);
  }
  if (!fusion || fusion->trajectory().empty()) {
    std::string why = out.frames_read == 0 ? "the source gave no readable frame"
                      : out.without_pose == out.frames_read
                          ? "no frame has a pose within 20 ms in " + options.poses
                          : "no frame had usable depth (" + first_skip + ")";
    throw InputError(options.source, "nothing to fuse: " + why);
  }

  const auto mesh_start = Clock::now();
  const TriangleMesh mesh = fusion::extractMesh(fusion->volume());
  out.mesh_s = std::chrono::duration<double>(Clock::now() - mesh_start).count();
  if (mesh.triangles.empty()) {
    throw InputError(options.source, "the fused volume holds no surface to mesh");
  }
  if (limits.before_writing) limits.before_writing();
  out.mesh_file = options.out / "mesh.ply";
  out.trajectory_file = options.out / "trajectory.txt";
  writePly(out.mesh_file, mesh);
  writeTumTrajectory(out.trajectory_file, fusion->trajectory());

  out.frames_fused = fusion->trajectory().size();
  out.frames_processed = fusion->framesProcessed();
  out.frames_lost = fusion->framesLost();
  out.frames_without_depth = fusion->framesSkipped();
  out.blocks = fusion->volume().blockCount();
  out.volume_mb = static_cast<double>(fusion->volume().memoryBytes()) / 1e6;
  out.voxel_size_m = options.config.volume.voxel_size_m;
  out.mesh_vertices = mesh.positions.size();
  out.mesh_triangles = mesh.triangles.size();
  const double n = static_cast<double>(std::max<std::size_t>(1, out.frames_processed));
  out.per_frame_ms.preprocess_ms = totals.preprocess_ms / n;
  out.per_frame_ms.track_ms = totals.track_ms / n;
  out.per_frame_ms.integrate_ms = totals.integrate_ms / n;
  out.per_frame_ms.raycast_ms = totals.raycast_ms / n;
  if (info.ground_truth && !given) {
    try {
      out.ate = absoluteTrajectoryError(fusion->trajectory(), *info.ground_truth, kPoseMatchS);
    } catch (const std::invalid_argument& e) {
      log::warning(std::string("no trajectory error: ") + e.what());
    }
  }
  return out;
}

int reportSensorLoss(const FuseOutcome& o) {
  if (o.sensor_lost.empty()) return kExitSuccess;
  std::fflush(stdout);
  std::fprintf(stderr, "objscan: error: %s; the outputs hold the %zu frames fused before it\n",
               o.sensor_lost.c_str(), o.frames_fused);
  return kExitRuntimeFailure;
}

void printFuseSummary(const FuseOutcome& o) {
  std::printf("source        %s\n", o.source_description.c_str());
  std::printf(
      "frames        %zu read, %zu fused, %zu lost, %zu without depth, %zu unreadable%s\n",
      o.frames_read, o.frames_fused, o.frames_lost, o.frames_without_depth, o.bad_frames,
      o.without_pose ? (", " + std::to_string(o.without_pose) + " without a pose").c_str() : "");
  if (!o.first_loss.empty()) std::printf("first loss    %s\n", o.first_loss.c_str());
  std::printf("volume        %zu blocks of 8^3 voxels of %.1f mm, %.1f MB\n", o.blocks,
              1e3 * o.voxel_size_m, o.volume_mb);
  std::printf("mesh          %zu vertices, %zu triangles -> %s\n", o.mesh_vertices,
              o.mesh_triangles, o.mesh_file.string().c_str());
  std::printf("trajectory    %zu poses -> %s\n", o.frames_fused,
              o.trajectory_file.string().c_str());
  const fusion::FrameTimings& t = o.per_frame_ms;
  std::printf(
      "time          %.2f s fusing (%.1f frames/s; per frame: preprocess %.1f ms, track "
      "%.1f ms, integrate %.1f ms, raycast %.1f ms), %.2f s meshing\n",
      o.fuse_s, static_cast<double>(o.frames_processed) / o.fuse_s, t.preprocess_ms, t.track_ms,
      t.integrate_ms, t.raycast_ms, o.mesh_s);
  if (o.recording) {
    const capture::RecordSummary& r = *o.recording;
    std::printf("recording     %zu depth, %zu colour frames, %zu dropped -> %s%s\n", r.depth_frames,
                r.color_frames, r.dropped, o.recording_file.string().c_str(),
                r.failed ? (" (stopped early: " + r.stop_reason + ")").c_str() : "");
  }
  if (o.ate) {
    std::printf(
        "ATE           RMSE %.1f mm, mean %.1f mm, max %.1f mm over %zu poses (vs the "
        "source's ground truth)\n",
        1e3 * o.ate->rmse_m, 1e3 * o.ate->mean_m, 1e3 * o.ate->max_m, o.ate->matched);
  }
}

int runFuse(const FuseCommandOptions& options) {
  FuseOutcome outcome;
  {
    StopSignals signals;
    outcome = fuseSource(options);
  }
  printFuseSummary(outcome);
  if (outcome.interrupted) {
    std::printf("stopped by    Ctrl-C / SIGTERM: the outputs hold the %zu frames fused before it\n",
                outcome.frames_fused);
  }
  return reportSensorLoss(outcome);
}

}  // namespace objscan::app
