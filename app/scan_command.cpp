#include "scan_command.h"

#include <cstdio>
#include <cstring>
#include <functional>
#include <system_error>
#include <utility>
#include <vector>

#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/output_folder.h"
#include "objscan/discovery/catalog.h"
#include "objscan/pipeline/ground_truth.h"
#include "objscan/report/report.h"
#include "objscan/report/results_io.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// The outputs of the stages after fusion; a new mesh makes an earlier run's stale.
const std::vector<std::string> kLaterOutputs = {"hypotheses.json", "objects",     "renders",
                                                "evaluation.json", "report.html", "timings.json",
                                                "settings.json"};

void removeStaleOutputs(const fs::path& out) {
  for (const std::string& name : kLaterOutputs) {
    std::error_code ec;
    if (fs::exists(out / name, ec)) {
      fs::remove_all(out / name, ec);
      if (ec)
        throw OutputError(out / name, "cannot remove an earlier run's output: " + ec.message());
    }
  }
}

/// Fails now, not after minutes of fusing, when OUT cannot take files (permissions, a read-only
/// file system: creates and removes a probe file) or another run is writing it; returns the
/// folder's lock, held for the whole scan.
OutputFolderLock requireWritableFolder(const fs::path& out) {
  OutputFolderLock lock = prepareOutputFolder(out);
  if (const int error = probeWritableFolder(out); error != 0) {
    throw OutputError(out,
                      std::string("cannot write into the output folder: ") + std::strerror(error));
  }
  return lock;
}

/// The ground truth to evaluate against, checked before any work; empty for none.
fs::path groundTruthOf(const ScanCommandOptions& options) {
  fs::path truth = options.ground_truth;
  if (!truth.empty()) {
    if (!fs::is_regular_file(truth)) {
      throw InputError(truth, fs::exists(truth) ? "not a file" : "missing");
    }
    pipeline::requireLabelledMesh(truth);
    return truth;
  }
  if (options.no_ground_truth) return {};
  truth = pipeline::findGroundTruth(options.source);
  if (truth.empty()) return {};
  try {
    pipeline::requireLabelledMesh(truth);
  } catch (const InputError& e) {
    log::warning(std::string("ground truth beside the source not used: ") + e.what());
    truth.clear();
  }
  return truth;
}

/// One scan: the results so far, in memory, and the timings of its stages.
class ScanRun {
 public:
  ScanRun(const ScanCommandOptions& options, LiveRun* live)
      : options_(options), out_(options.out), start_(SteadyClock::now()), live_(live) {
    results_.timings.emplace().source = options.source;
    results_.settings = options.settings;
  }

  void stage(const char* name, double seconds) { timings().stages.push_back({name, seconds}); }

  /// After a Ctrl-C: what is written stays, the rest is listed as not produced. Once
  /// hypotheses.json exists, the report is written too, with a notice of what is missing.
  int stopHere(std::vector<std::string> missing) {
    timings().interrupted = true;
    const bool report = results_.hypotheses.has_value();
    if (report) std::erase(missing, std::string("report.html"));
    timings().not_produced = missing;
    finishTimings();
    report::writeSettings(out_ / report::kSettingsFile, *results_.settings);
    report::writeTimings(out_ / report::kTimingsFile, timings());
    if (report) report::writeReport(results_, out_);
    std::string list;
    for (const std::string& m : missing) list += (list.empty() ? "" : ", ") + m;
    std::printf("stopped by    Ctrl-C / SIGTERM; not produced: %s\n", list.c_str());
    std::printf("timings       %s\n", (out_ / report::kTimingsFile).c_str());
    return kExitInterrupted;
  }

  /// `after_open` runs once the source is open: where the output folder is prepared, so that a
  /// source that cannot be opened (no sensor) leaves nothing behind.
  pipeline::FusedScene fuse(std::function<void()> after_open) {
    pipeline::FuseLimits limits = options_.limits;
    limits.after_open = std::move(after_open);
    limits.progress_label = "scan [1/4] fusing frames";
    limits.live_stop_ends_capture = true;
    limits.stop = &StopSignals::flag();
    if (live_) live_->watch(limits);
    pipeline::FusedScene fused = pipeline::fuseSource(options_.fuse, limits);
    if (live_) live_->stage("writing the mesh");
    const pipeline::FuseStats& s = fused.stats;
    stage("fuse", s.fuse_s);
    stage("mesh", s.mesh_s);
    timings().source = s.source_description;
    timings().frames = report::FrameCounts{s.frames_read, s.frames_fused, s.frames_lost,
                                           s.frames_without_depth, s.bad_frames};
    timings().mesh_vertices = fused.mesh.positions.size();
    timings().mesh_faces = fused.mesh.triangles.size();
    timings().sensor_lost = s.sensor_lost;
    removeStaleOutputs(out_);
    mesh_bytes_ = writeFused(out_, fused);
    addFusionSettings(*results_.settings, fused, options_.fuse);
    results_.trajectory = fused.trajectory;
    printFuseSummary(fused, out_);
    return fused;
  }

  discovery::SceneDiscovery discover(TriangleMesh mesh, const fs::path& truth,
                                     const discovery::SceneDiscoveryOptions& library) {
    log::info("scan [2/4] discovering objects");
    if (live_) live_->stage("discovering objects");
    DiscoverCommandOptions options = options_.discover;
    options.out = out_;
    std::vector<discovery::SceneInput> scenes;
    scenes.push_back(discovery::sceneFromMesh(
        (out_ / report::kMeshFile).string(), std::move(mesh),
        library.catalog ? discovery::contentHashOfBytes(mesh_bytes_) : std::string()));
    if (results_.trajectory) scenes.back().view_up = viewUp(*results_.trajectory);
    mesh_bytes_.clear();
    discovery::SceneDiscovery run = discovery::discoverScenes(std::move(scenes), library);
    results_.hypotheses = writeDiscoveryResults(options, run);
    results_.settings->catalog = report::catalogUseOf(run);
    stage("discover", run.seconds);
    timings().hypotheses = run.ranked.size();
    std::printf("hypotheses    %zu ranked -> %s, %s\n", run.ranked.size(),
                (out_ / report::kHypothesesFile).c_str(), (out_ / report::kObjectsFolder).c_str());
    printCatalogUse(run);
    if (!truth.empty()) evaluate(truth, run);
    return run;
  }

  /// Renders and writes the pictures; false when stopped.
  bool pictures(const TriangleMesh& mesh) {
    if (results_.hypotheses->hypotheses.empty()) {
      std::printf("renders       none: no hypothesis to show\n");
      return true;
    }
    log::info("scan [3/4] rendering pictures");
    if (live_) live_->stage("rendering pictures");
    pipeline::PictureOptions pictures = options_.pictures;
    pictures.progress_label = "scan [3/4] rendering pictures";
    pictures.stop = &StopSignals::flag();
    pipeline::PicturesOutcome outcome =
        pipeline::renderPictures(mesh, &*results_.trajectory, results_.hypotheses->hypotheses,
                                 pictures, (out_ / report::kHypothesesFile).string());
    stage("render", outcome.seconds);
    if (outcome.interrupted) return false;
    report::writePictures(out_, outcome.pictures);
    printPictures("renders", outcome, out_);
    results_.pictures = std::move(outcome.pictures);
    return true;
  }

  /// `mesh`: the scene mesh, for the report's 3-D view.
  fs::path reportAndTimings(const TriangleMesh* mesh) {
    log::info("scan [4/4] writing the report");
    if (live_) live_->stage("writing the report");
    const auto report_start = SteadyClock::now();
    finishTimings();  // the report shows the timings up to it
    report::writeSettings(out_ / report::kSettingsFile, *results_.settings);
    const fs::path report = report::writeReport(results_, out_, mesh);
    stage("report", secondsSince(report_start));
    finishTimings();
    report::writeTimings(out_ / report::kTimingsFile, timings());
    std::string per_stage;
    for (const report::StageTime& s : timings().stages) {
      char part[64];
      std::snprintf(part, sizeof part, "%s%s %.1f s", per_stage.empty() ? "" : ", ", s.name.c_str(),
                    s.seconds);
      per_stage += part;
    }
    std::printf("time          %s; total %.1f s\n", per_stage.c_str(), *timings().total_s);
    return report;
  }

 private:
  void evaluate(const fs::path& truth, const discovery::SceneDiscovery& run) {
    const auto start = SteadyClock::now();
    results_.evaluation = pipeline::evaluateAgainstTruth(truth, run, options_.min_iou);
    report::writeEvaluation(out_ / report::kEvaluationFile, *results_.evaluation);
    stage("evaluation", secondsSince(start));
    std::printf("ground truth  %zu of %zu objects found at IoU %.1f, AP %.3f (%s)\n",
                *results_.evaluation->found, *results_.evaluation->objects, options_.min_iou,
                results_.evaluation->ap, truth.c_str());
  }

  /// timings.json as far as the run has come; the report shows it.
  report::Timings& timings() { return *results_.timings; }

  void finishTimings() { timings().total_s = secondsSince(start_); }

  const ScanCommandOptions& options_;
  fs::path out_;
  SteadyClock::time_point start_;
  report::ScanResults results_;  ///< everything written so far, and the timings
  std::string mesh_bytes_;       ///< mesh.ply's, until discovery has hashed them
  LiveRun* live_;                ///< --serve's, or none
};

/// The final ranking for the live page: the first `shown` hypotheses, and their vertices to
/// paint.
void addLiveHypotheses(const discovery::SceneDiscovery& found, std::size_t shown,
                       server::LiveFinal& final) {
  for (std::size_t i = 0; i < found.ranked.size() && i < shown; ++i) {
    const discovery::Hypothesis& h = found.ranked[i].hypothesis;
    final.hypotheses.push_back({static_cast<int>(i) + 1, h.score, h.segment.vertices.size(),
                                h.segment.centroid, h.segment.extents});
    const TriangleMesh& mesh = found.scenes.at(found.ranked[i].scene).mesh;
    std::vector<Eigen::Vector3f>& painted = final.painted.emplace_back();
    painted.reserve(h.segment.vertices.size());
    for (const std::int32_t v : h.segment.vertices) {
      painted.push_back(mesh.positions[static_cast<std::size_t>(v)]);
    }
  }
}

/// What a stopped scan tells the page: it ends at once, showing what was written.
server::LiveFinal stoppedFinal(const std::vector<std::string>& missing) {
  std::string list;
  for (const std::string& m : missing) list += (list.empty() ? "" : ", ") + m;
  return server::LiveFinal::without("stopped by Ctrl-C / SIGTERM; not produced: " + list);
}

}  // namespace

int runScan(ScanCommandOptions options) {
  if (options.source.empty()) options.source = "live";
  options.fuse.source = options.source;
  // Settings, the ground truth and the model are checked before anything is opened or written.
  options.fuse.config.validate();
  options.pictures.validate();
  const fs::path truth = groundTruthOf(options);
  const discovery::SceneDiscoveryOptions library = sceneDiscoveryOptions(options.discover);
  server::LiveSettings live_settings;
  live_settings.command = "scan";
  live_settings.source = options.source;
  live_settings.results = options.out;
  live_settings.discovery_config = options.discover.config;
  // Before the folder is touched: a port that cannot be had leaves nothing behind.
  const std::unique_ptr<LiveRun> live = LiveRun::start(options.serve, live_settings);
  try {
    OutputFolderLock lock;  // held from when the source is open to the end of the scan
    StopSignals signals;
    ScanRun run(options, live.get());
    const auto stop = [&](std::vector<std::string> missing) {
      if (live) live->finish(stoppedFinal(missing), false);
      return run.stopHere(std::move(missing));
    };
    pipeline::FusedScene fused =
        run.fuse([&lock, &options] { lock = requireWritableFolder(options.out); });
    if (fused.stats.interrupted) {
      // On a sensor, Ctrl-C is how capture ends: the scan goes on with what was fused.
      if (!fused.stats.live) {
        std::vector<std::string> missing = {"hypotheses.json", "objects/", "renders/",
                                            "report.html"};
        if (!truth.empty()) missing.insert(missing.begin() + 2, "evaluation.json");
        return stop(missing);
      }
      std::printf("capture       ended by Ctrl-C after %zu frames\n", fused.stats.frames_read);
    }
    const discovery::SceneDiscovery found = run.discover(std::move(fused.mesh), truth, library);
    if (StopSignals::stopRequested()) return stop({"renders/", "report.html"});
    if (!run.pictures(found.scenes.at(0).mesh)) return stop({"renders/", "report.html"});
    const fs::path report = run.reportAndTimings(&found.scenes.at(0).mesh);
    std::printf("report        %s\n", report.c_str());
    // A sensor lost mid-capture still gives every output, from the frames before it, and exit 1.
    const int code = reportSensorLoss(fused.stats);
    if (live) {
      server::LiveFinal final;
      final.outcome = code == kExitSuccess ? "finished: " + std::to_string(found.ranked.size()) +
                                                 " hypotheses ranked"
                                           : "sensor lost: " + fused.stats.sensor_lost;
      final.failed = code != kExitSuccess;
      addLiveHypotheses(found, live_settings.shown_hypotheses, final);
      final.files = {{"report", report::kReportFile},
                     {"mesh", report::kMeshFile},
                     {"hypotheses", report::kHypothesesFile},
                     {"trajectory", report::kTrajectoryFile},
                     {"timings", report::kTimingsFile}};
      live->finish(std::move(final));
    }
    return code;
  } catch (const std::exception& e) {
    if (live) live->finish(server::LiveFinal::without(std::string("failed: ") + e.what()), false);
    throw;
  }
}

}  // namespace objscan::app
