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

int runFuse(const FuseCommandOptions& options) {
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

  std::optional<fusion::Fusion> fusion;
  fusion::FrameTimings totals;
  std::size_t frames_read = 0, bad_frames = 0, without_pose = 0;
  std::string first_loss, first_skip;
  bool interrupted = false;
  const auto start = Clock::now();
  {
    StopSignals signals;
    ProgressBar progress("fusing frames", info.frame_count.value_or(0));
    for (;;) {
      if (StopSignals::stopRequested()) {
        interrupted = true;
        break;
      }
      capture::FrameResult r = source->next();
      if (r.status == capture::FrameStatus::kEndOfStream) break;
      progress.advance();
      if (r.status == capture::FrameStatus::kBadFrame) {
        log::warning("skipped a frame: " + r.reason);
        ++bad_frames;
        continue;
      }
      ++frames_read;
      RgbdFrame& frame = r.frame;
      if (options.no_color) frame.color_rgb.release();
      std::optional<Pose> pose;
      if (given) {
        pose = nearestPose(*given, frame.stamp_s, kPoseMatchS);
        if (!pose) {
          ++without_pose;
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
        if (first_loss.empty()) {
          first_loss = "frame " + std::to_string(frame.index) + ": " + outcome.reason;
        }
      } else if (outcome.status == fusion::FrameStatus::kNoDepth && first_skip.empty()) {
        first_skip = "frame " + std::to_string(frame.index) + ": " + outcome.reason;
      }
    }
  }
  const double fuse_s = std::chrono::duration<double>(Clock::now() - start).count();
  if (!fusion || fusion->trajectory().empty()) {
    std::string why = frames_read == 0 ? "the source gave no readable frame"
                      : without_pose == frames_read
                          ? "no frame has a pose within 20 ms in " + options.poses
                          : "no frame had usable depth (" + first_skip + ")";
    throw InputError(options.source, "nothing to fuse: " + why);
  }

  const auto mesh_start = Clock::now();
  const TriangleMesh mesh = fusion::extractMesh(fusion->volume());
  const double mesh_s = std::chrono::duration<double>(Clock::now() - mesh_start).count();
  if (mesh.triangles.empty()) {
    throw InputError(options.source, "the fused volume holds no surface to mesh");
  }
  const fs::path mesh_file = options.out / "mesh.ply";
  const fs::path trajectory_file = options.out / "trajectory.txt";
  writePly(mesh_file, mesh);
  writeTumTrajectory(trajectory_file, fusion->trajectory());

  const std::size_t fused = fusion->trajectory().size();
  const double n = static_cast<double>(fusion->framesProcessed());
  std::printf("source        %s\n", info.description.c_str());
  std::printf(
      "frames        %zu read, %zu fused, %zu lost, %zu without depth, %zu unreadable%s\n",
      frames_read, fused, fusion->framesLost(), fusion->framesSkipped(), bad_frames,
      without_pose ? (", " + std::to_string(without_pose) + " without a pose").c_str() : "");
  if (!first_loss.empty()) std::printf("first loss    %s\n", first_loss.c_str());
  std::printf("volume        %zu blocks of 8^3 voxels of %.1f mm, %.1f MB\n",
              fusion->volume().blockCount(), 1e3 * options.config.volume.voxel_size_m,
              static_cast<double>(fusion->volume().memoryBytes()) / 1e6);
  std::printf("mesh          %zu vertices, %zu triangles -> %s\n", mesh.positions.size(),
              mesh.triangles.size(), mesh_file.string().c_str());
  std::printf("trajectory    %zu poses -> %s\n", fused, trajectory_file.string().c_str());
  std::printf(
      "time          %.2f s fusing (%.1f frames/s; per frame: preprocess %.1f ms, track "
      "%.1f ms, integrate %.1f ms, raycast %.1f ms), %.2f s meshing\n",
      fuse_s, n / fuse_s, totals.preprocess_ms / n, totals.track_ms / n, totals.integrate_ms / n,
      totals.raycast_ms / n, mesh_s);
  if (info.ground_truth && !given) {
    try {
      const TrajectoryError ate =
          absoluteTrajectoryError(fusion->trajectory(), *info.ground_truth, kPoseMatchS);
      std::printf(
          "ATE           RMSE %.1f mm, mean %.1f mm, max %.1f mm over %zu poses (vs the "
          "source's ground truth)\n",
          1e3 * ate.rmse_m, 1e3 * ate.mean_m, 1e3 * ate.max_m, ate.matched);
    } catch (const std::invalid_argument& e) {
      log::warning(std::string("no trajectory error: ") + e.what());
    }
  }
  if (interrupted) {
    std::printf("stopped by    Ctrl-C / SIGTERM: the outputs hold the %zu frames fused before it\n",
                fused);
  }
  return kExitSuccess;
}

}  // namespace objscan::app
