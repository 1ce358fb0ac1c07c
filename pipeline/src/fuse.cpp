#include "objscan/pipeline/fuse.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <system_error>

#include "objscan/capture/read_ahead.h"
#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/memory.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "objscan/fusion/marching_cubes.h"
#include "objscan/pipeline/sources.h"

namespace objscan::pipeline {
namespace {

namespace fs = std::filesystem;

/// Peak memory of fusion and meshing per byte of TSDF volume, and the rest of the process
/// (measured on TUM fr2/desk with 4-byte voxels: peaks of 3.5 and 2.9 times the volume at 3 and
/// 2 mm, which 3.2 times plus 150 MB covers; docs/fusion.md, "Memory").
constexpr double kPeakPerVolumeByte = 3.2;
constexpr double kFusionBaseBytes = 150e6;

std::string voxelText(float voxel_m) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f mm", 1e3 * static_cast<double>(voxel_m));
  return text;
}

using Clock = SteadyClock;

/// Frame time stamps and trajectory time stamps pair up within this (the TUM tools' default).
constexpr double kPoseMatchS = 0.02;

}  // namespace

FusedScene fuseSource(const FuseOptions& options, const FuseLimits& limits) {
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
  if (limits.after_open) limits.after_open();
  log::info("fusing " + info.description + (given ? " at the given poses" : " with ICP tracking"));
  if (info.intrinsics_assumed) {
    // Silent wrong scale otherwise: every point's distance from the optical axis depends on fx.
    log::warning("the camera intrinsics are ASSUMED: " + info.intrinsics_origin +
                 "; a different camera makes the mesh the wrong size and shape. Add the "
                 "recording's calibration (intrinsics.json beside it) or pass --intrinsics FILE");
  }

  FusedScene fused;
  FuseStats& out = fused.stats;
  out.source_description = info.description;
  out.intrinsics = info.intrinsics;
  out.intrinsics_origin = info.intrinsics_origin;
  out.intrinsics_assumed = info.intrinsics_assumed;
  out.depth_units = info.depth_units;
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
    // Memory: the volume grows with the surface seen, as about 1/voxel^2; meshing and writing it
    // take about 1.5 times the volume again (measured on TUM fr2/desk: peak 2.3-2.6 times the
    // volume at 2 and 3 mm; at 5.86 mm the rest of the process, about 150 MB, dominates). Fusion stops, and keeps what it has, before that outgrows the machine.
    const std::optional<std::uint64_t> memory = availableMemoryBytes();
    bool memory_warned = false;
    double last_peak = 0.0;
    ProgressBar progress(limits.progress_label, total);
    std::size_t read = 0;
    std::optional<double> last_stamp_s;
    std::int64_t last_device_frame = -1;
    for (;;) {
      if (limits.stop && limits.stop->load()) {
        out.interrupted = true;
        out.stopped_by = "Ctrl-C / SIGTERM";
        if (limits.live_stop_ends_capture && info.live) limits.stop->store(false);
        break;
      }
      if (limits.max_frames && read >= *limits.max_frames) {
        out.stopped_by = "frame limit";
        break;
      }
      if (limits.max_seconds && secondsSince(start) >= *limits.max_seconds) {
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
      RgbdFrame& frame = r.frame;
      if (last_stamp_s && frame.stamp_s < *last_stamp_s) {
        // A trajectory is in time order (its readers, ours and TUM's, refuse anything else).
        log::warning("skipped frame " + std::to_string(frame.index) + ": its time stamp " +
                     std::to_string(frame.stamp_s) + " s is earlier than the frame before");
        ++out.bad_frames;
        continue;
      }
      last_stamp_s = frame.stamp_s;
      ++out.frames_read;
      if (frame.device_frame >= 0) {
        // A gap in the sensor's frame numbers: frames it dropped, or that came while fusion was
        // busy and the sensor (which keeps only a few) let go.
        if (last_device_frame >= 0 && frame.device_frame > last_device_frame + 1) {
          out.frames_dropped +=
              static_cast<std::size_t>(frame.device_frame - last_device_frame - 1);
        }
        last_device_frame = frame.device_frame;
      }
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
      if (limits.on_frame) limits.on_frame(FrameEvent{frame, outcome, *fusion, read, total});
      if (memory) {
        const double volume = static_cast<double>(fusion->volume().memoryBytes());
        const double peak = kPeakPerVolumeByte * volume + kFusionBaseBytes +
                            (limits.extra_memory_bytes ? limits.extra_memory_bytes() : 0.0);
        // Stop while the frames fused so far can still be meshed: before the next frame, if it
        // grows the volume as much as this one did, would take the peak past what is free.
        // (The first frame fills a whole view at once; its growth says nothing of the next's.)
        const double next_peak = last_peak > 0.0 ? peak + std::max(0.0, peak - last_peak) : peak;
        last_peak = peak;
        const double budget = static_cast<double>(*memory);
        if (next_peak > budget) {
          out.sensor_lost =
              "fusion stopped at frame " + std::to_string(frame.index) + ": the volume holds " +
              bytesText(static_cast<std::uint64_t>(volume)) + " at " +
              voxelText(options.config.volume.voxel_size_m) + " voxels; meshing it needs about " +
              bytesText(static_cast<std::uint64_t>(peak)) + ", and after another frame about " +
              bytesText(static_cast<std::uint64_t>(next_peak)) + ", more than " +
              availableMemoryText(*memory) + "; a larger --voxel-size needs less " +
              "(twice the size, about a quarter)";
          out.stopped_by = "memory";
          break;
        }
        if (!memory_warned && next_peak > 0.5 * budget) {
          memory_warned = true;
          log::warning("the volume already needs about half of " + availableMemoryText(*memory) +
                       " at " + voxelText(options.config.volume.voxel_size_m) +
                       " voxels; fusion stops before it runs out");
        }
      }
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
  out.fuse_s = secondsSince(start);
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
  if (out.recording && out.recording->failed) {
    if (out.sensor_lost.empty()) {
      // A nearly full disk ends the stream without an exception.
      out.sensor_lost =
          out.recording_file.string() + ": recording stopped early: " + out.recording->stop_reason;
    } else {
      out.sensor_lost += "; " + out.recording_file.string() + " holds the " +
                         std::to_string(out.recording->depth_frames) + " frames recorded before it";
    }
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

  if (limits.before_meshing) limits.before_meshing();
  const auto mesh_start = Clock::now();
  fused.mesh = fusion::extractMesh(
      fusion->volume(), limits.progress_label.empty() ? std::string() : "meshing the volume");
  out.mesh_s = secondsSince(mesh_start);
  if (fused.mesh.triangles.empty()) {
    throw InputError(options.source, "the fused volume holds no surface to mesh");
  }
  fused.trajectory = fusion->trajectory();
  out.frames_fused = fusion->trajectory().size();
  out.frames_processed = fusion->framesProcessed();
  out.frames_lost = fusion->framesLost();
  out.frames_without_depth = fusion->framesSkipped();
  out.blocks = fusion->volume().blockCount();
  out.volume_mb = static_cast<double>(fusion->volume().memoryBytes()) / 1e6;
  out.voxel_size_m = options.config.volume.voxel_size_m;
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
  return fused;
}

}  // namespace objscan::pipeline
