#include "fuse_command.h"

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "exit_codes.h"
#include "objscan/capture/openni.h"
#include "objscan/fusion/pipeline.h"
#include "objscan/pipeline/scan.h"
#include "objscan/report/results_io.h"
#include "stop_signals.h"

namespace objscan::app {

int reportSensorLoss(const pipeline::FuseStats& o) {
  if (o.sensor_lost.empty()) return kExitSuccess;
  std::fflush(stdout);
  std::fprintf(stderr, "objscan: error: %s; the outputs hold the %zu frames fused before it\n",
               o.sensor_lost.c_str(), o.frames_fused);
  return kExitRuntimeFailure;
}

void printFuseSummary(const pipeline::FusedScene& fused, const std::filesystem::path& out) {
  const pipeline::FuseStats& o = fused.stats;
  std::printf("source        %s\n", o.source_description.c_str());
  const Intrinsics& k = o.intrinsics;
  std::printf("intrinsics    fx %.2f fy %.2f cx %.2f cy %.2f, %dx%d (%s%s)%s%s\n", k.fx_px, k.fy_px,
              k.cx_px, k.cy_px, k.width_px, k.height_px, o.intrinsics_assumed ? "ASSUMED: " : "",
              o.intrinsics_origin.c_str(),
              o.depth_units.empty() ? "" : "; depth: ", o.depth_units.c_str());
  std::printf(
      "frames        %zu read, %zu fused, %zu lost, %zu without depth, %zu unreadable%s%s\n",
      o.frames_read, o.frames_fused, o.frames_lost, o.frames_without_depth, o.bad_frames,
      o.without_pose ? (", " + std::to_string(o.without_pose) + " without a pose").c_str() : "",
      o.live ? (", " + std::to_string(o.frames_dropped) + " dropped").c_str() : "");
  if (!o.first_loss.empty()) std::printf("first loss    %s\n", o.first_loss.c_str());
  std::printf("volume        %zu blocks of 8^3 voxels of %.1f mm, %.1f MB\n", o.blocks,
              1e3 * o.voxel_size_m, o.volume_mb);
  std::printf("mesh          %zu vertices, %zu triangles -> %s\n", fused.mesh.positions.size(),
              fused.mesh.triangles.size(), (out / report::kMeshFile).c_str());
  std::printf("trajectory    %zu poses -> %s\n", o.frames_fused,
              (out / report::kTrajectoryFile).c_str());
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

namespace {

/// fuse's lines on stdout.
class FusePrinter : public pipeline::ScanObserver {
 public:
  void fused(const pipeline::FusedScene& fused, const std::filesystem::path& out) override {
    printFuseSummary(fused, out);
  }
  void finished(const pipeline::ScanOutcome& outcome) override {
    if (outcome.interrupted) {
      std::printf(
          "stopped by    Ctrl-C / SIGTERM: the outputs hold the %zu frames fused before "
          "it\n",
          outcome.fuse.frames_fused);
    }
  }
};

}  // namespace

int runFuse(const FuseCommandOptions& options) {
  // The server first: a port that cannot be had is refused before anything is opened or written.
  server::LiveSettings live_settings;
  live_settings.command = "fuse";
  live_settings.source = options.fuse.source;
  live_settings.results = options.out;
  const std::unique_ptr<LiveRun> live = LiveRun::start(options.serve, live_settings);
  pipeline::ScanOutcome outcome;
  try {
    pipeline::ScanRequest request;
    request.fuse = options.fuse;
    request.discover = false;
    request.out = options.out;
    request.settings = options.settings;
    FusePrinter printer;
    std::vector<pipeline::ScanObserver*> observers = {&printer};
    if (live) observers.push_back(live.get());
    StopSignals signals;
    request.limits.stop = &StopSignals::flag();
    outcome = pipeline::runScan(std::move(request), observers);
  } catch (const std::exception& e) {
    if (live) live->finish(server::LiveFinal::without(std::string("failed: ") + e.what()), false);
    throw;
  }
  const int code = reportSensorLoss(outcome.fuse);
  if (live) {
    server::LiveFinal final;
    final.outcome = outcome.interrupted ? "stopped by Ctrl-C: the mesh holds the frames fused"
                    : outcome.fuse.sensor_lost.empty() ? "finished"
                                                       : "sensor lost: " + outcome.fuse.sensor_lost;
    final.failed = code != kExitSuccess;
    final.files = {{"mesh", report::kMeshFile},
                   {"trajectory", report::kTrajectoryFile},
                   {"settings", report::kSettingsFile}};
    live->finish(std::move(final), !outcome.interrupted);
  }
  return code;
}

}  // namespace objscan::app
