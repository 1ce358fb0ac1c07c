#include "objscan/pipeline/scan.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/trajectory.h"
#include "objscan/discovery/catalog.h"
#include "objscan/pipeline/ground_truth.h"
#include "objscan/report/report.h"
#include "objscan/report/results_io.h"

namespace objscan::pipeline {
namespace {

namespace fs = std::filesystem;

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

/// Completes `settings` with what fusion resolved (the truncation used, whether the volume
/// carved, the intrinsics and where they came from).
void addFusionSettings(report::Settings& settings, const FusedScene& fused,
                       const FuseOptions& options) {
  if (!options.config.volume.truncation_m) {
    settings.resolved.push_back(
        {"truncation", {report::exactText(options.config.volume.truncation())}});
  }
  // The flags record what was given; whether the volume carved is what was used.
  settings.resolved.push_back(
      {"carve", {options.config.volume.carve_free_space ? "true" : "false"}});
  settings.intrinsics = fused.stats.intrinsics;
  settings.intrinsics_origin = fused.stats.intrinsics_origin;
}

/// One scan: what it has produced so far and the timings of its stages.
class Scan {
 public:
  Scan(ScanRequest request, const std::vector<ScanObserver*>& observers)
      : request_(std::move(request)), observers_(observers), start_(SteadyClock::now()) {
    outcome_.results.timings.emplace().source = request_.fuse.source;
    outcome_.results.settings = request_.settings;
  }

  ScanOutcome run() {
    FusedScene fused = fuse();
    if (!request_.discover) {
      outcome_.interrupted = fused.stats.interrupted;
      report::writeSettings(out() / report::kSettingsFile, *outcome_.results.settings);
      return finish();
    }
    if (fused.stats.interrupted) {
      // On a sensor, a stop is how capture ends: the scan goes on with what was fused.
      if (!fused.stats.live) {
        std::vector<std::string> missing = {"hypotheses.json", "objects/", "renders/",
                                            "report.html"};
        if (!request_.ground_truth.empty()) missing.insert(missing.begin() + 2, "evaluation.json");
        return stopHere(std::move(missing));
      }
    }
    discover(std::move(fused.mesh));
    if (stopRequested()) return stopHere({"renders/", "report.html"});
    const TriangleMesh& mesh = outcome_.discovery->scenes.at(0).mesh;
    if (!pictures(mesh)) return stopHere({"renders/", "report.html"});
    reportAndTimings(mesh);
    return finish();
  }

 private:
  const fs::path& out() const { return request_.out; }
  report::Timings& timings() { return *outcome_.results.timings; }
  void finishTimings() { timings().total_s = secondsSince(start_); }
  void stage(const char* name, double seconds) { timings().stages.push_back({name, seconds}); }
  bool stopRequested() const { return request_.limits.stop && request_.limits.stop->load(); }

  template <typename Call>
  void tell(Call call) {
    for (ScanObserver* o : observers_) call(*o);
  }

  ScanOutcome finish() {
    tell([&](ScanObserver& o) { o.finished(outcome_); });
    return std::move(outcome_);
  }

  /// After a stop: what is written stays, the rest is listed as not produced. Once
  /// hypotheses.json exists, the report is written too, with a notice of what is missing.
  ScanOutcome stopHere(std::vector<std::string> missing) {
    timings().interrupted = true;
    const bool report = outcome_.results.hypotheses.has_value();
    if (report) std::erase(missing, std::string("report.html"));
    timings().not_produced = missing;
    finishTimings();
    report::writeSettings(out() / report::kSettingsFile, *outcome_.results.settings);
    report::writeTimings(out() / report::kTimingsFile, timings());
    if (report) outcome_.report = report::writeReport(outcome_.results, out());
    outcome_.interrupted = true;
    outcome_.not_produced = std::move(missing);
    return finish();
  }

  /// The request's own hooks into fusion, then every observer's.
  void addHooks(FuseLimits& limits) {
    std::vector<FusionHooks> hooks(1 + observers_.size());
    hooks[0] = {limits.on_frame, limits.extra_memory_bytes, limits.before_meshing};
    for (std::size_t i = 0; i < observers_.size(); ++i) observers_[i]->watchFusion(hooks[1 + i]);
    const auto any = [&hooks](auto member) {
      return std::any_of(hooks.begin(), hooks.end(),
                         [member](const FusionHooks& h) { return bool(h.*member); });
    };
    // Each set only where a hook wants it: fusion does work for a frame event someone takes.
    if (any(&FusionHooks::on_frame)) {
      limits.on_frame = [hooks](const FrameEvent& e) {
        for (const FusionHooks& h : hooks) {
          if (h.on_frame) h.on_frame(e);
        }
      };
    }
    if (any(&FusionHooks::extra_memory_bytes)) {
      limits.extra_memory_bytes = [hooks] {
        double bytes = 0.0;
        for (const FusionHooks& h : hooks) {
          if (h.extra_memory_bytes) bytes += h.extra_memory_bytes();
        }
        return bytes;
      };
    }
    if (any(&FusionHooks::before_meshing)) {
      limits.before_meshing = [hooks] {
        for (const FusionHooks& h : hooks) {
          if (h.before_meshing) h.before_meshing();
        }
      };
    }
  }

  FusedScene fuse() {
    FuseLimits limits = request_.limits;
    // Held from when the source is open to the end of the scan, and then by the caller.
    limits.after_open = [this] { outcome_.folder_lock = requireWritableFolder(out()); };
    if (request_.discover) {
      limits.progress_label = "scan [1/4] fusing frames";
      limits.live_stop_ends_capture = true;
    }
    addHooks(limits);
    tell([](ScanObserver& o) { o.stageStarted(ScanStage::kFusing); });
    FusedScene fused = fuseSource(request_.fuse, limits);
    tell([](ScanObserver& o) { o.stageStarted(ScanStage::kWritingMesh); });
    const FuseStats& s = fused.stats;
    outcome_.fuse = s;
    outcome_.mesh_vertices = fused.mesh.positions.size();
    outcome_.mesh_faces = fused.mesh.triangles.size();
    stage("fuse", s.fuse_s);
    stage("mesh", s.mesh_s);
    timings().source = s.source_description;
    timings().frames = report::FrameCounts{s.frames_read, s.frames_fused, s.frames_lost,
                                           s.frames_without_depth, s.bad_frames};
    timings().mesh_vertices = outcome_.mesh_vertices;
    timings().mesh_faces = outcome_.mesh_faces;
    timings().sensor_lost = s.sensor_lost;
    if (request_.discover) report::removeOutputsAfterTheMesh(out());
    mesh_bytes_ = report::writeMeshAndTrajectory(out(), fused.mesh, fused.trajectory);
    addFusionSettings(*outcome_.results.settings, fused, request_.fuse);
    outcome_.results.trajectory = fused.trajectory;
    tell([&](ScanObserver& o) { o.fused(fused, out()); });
    return fused;
  }

  void discover(TriangleMesh mesh) {
    log::info("scan [2/4] discovering objects");
    tell([](ScanObserver& o) { o.stageStarted(ScanStage::kDiscovering); });
    const discovery::SceneDiscoveryOptions& library = request_.discovery;
    std::vector<discovery::SceneInput> scenes;
    scenes.push_back(discovery::sceneFromMesh(
        (out() / report::kMeshFile).string(), std::move(mesh),
        library.catalog ? discovery::contentHashOfBytes(mesh_bytes_) : std::string()));
    if (outcome_.results.trajectory) {
      scenes.back().view_up = viewUp(*outcome_.results.trajectory);
    }
    mesh_bytes_.clear();
    discovery::SceneDiscovery run = discovery::discoverScenes(std::move(scenes), library);
    report::Hypotheses hypotheses =
        report::hypothesesFrom(run, request_.model_name, out(), request_.object_format);
    report::writeDiscovery(out(), hypotheses, run, request_.object_format);
    outcome_.results.hypotheses = std::move(hypotheses);
    outcome_.results.settings->catalog = report::catalogUseOf(run);
    stage("discover", run.seconds);
    timings().hypotheses = run.ranked.size();
    tell([&](ScanObserver& o) { o.discovered(run, out()); });
    if (!request_.ground_truth.empty()) evaluate(run);
    outcome_.discovery = std::move(run);
  }

  void evaluate(const discovery::SceneDiscovery& run) {
    const auto start = SteadyClock::now();
    outcome_.results.evaluation =
        evaluateAgainstTruth(request_.ground_truth, run, request_.min_iou);
    report::writeEvaluation(out() / report::kEvaluationFile, *outcome_.results.evaluation);
    stage("evaluation", secondsSince(start));
    tell(
        [&](ScanObserver& o) { o.evaluated(*outcome_.results.evaluation, request_.ground_truth); });
  }

  /// Renders and writes the pictures; false when stopped.
  bool pictures(const TriangleMesh& mesh) {
    if (outcome_.results.hypotheses->hypotheses.empty()) {
      tell([&](ScanObserver& o) { o.pictured(PicturesOutcome{}, out()); });
      return true;
    }
    log::info("scan [3/4] rendering pictures");
    tell([](ScanObserver& o) { o.stageStarted(ScanStage::kRendering); });
    PictureOptions options = request_.pictures;
    options.progress_label = "scan [3/4] rendering pictures";
    options.stop = request_.limits.stop;
    PicturesOutcome pictured =
        renderPictures(mesh, &*outcome_.results.trajectory, outcome_.results.hypotheses->hypotheses,
                       options, (out() / report::kHypothesesFile).string());
    stage("render", pictured.seconds);
    if (pictured.interrupted) return false;
    report::writePictures(out(), pictured.pictures);
    tell([&](ScanObserver& o) { o.pictured(pictured, out()); });
    outcome_.results.pictures = std::move(pictured.pictures);
    return true;
  }

  /// report.html (with the scene mesh's 3-D view), settings.json and timings.json.
  void reportAndTimings(const TriangleMesh& mesh) {
    log::info("scan [4/4] writing the report");
    tell([](ScanObserver& o) { o.stageStarted(ScanStage::kReporting); });
    const auto report_start = SteadyClock::now();
    finishTimings();  // the report shows the timings up to it
    report::writeSettings(out() / report::kSettingsFile, *outcome_.results.settings);
    outcome_.report = report::writeReport(outcome_.results, out(), &mesh);
    stage("report", secondsSince(report_start));
    finishTimings();
    report::writeTimings(out() / report::kTimingsFile, timings());
  }

  ScanRequest request_;
  std::vector<ScanObserver*> observers_;
  SteadyClock::time_point start_;
  ScanOutcome outcome_;
  std::string mesh_bytes_;  ///< mesh.ply's, until discovery has hashed them
};

}  // namespace

const char* toString(ScanStage stage) {
  switch (stage) {
    case ScanStage::kFusing:
      return "fusing frames";
    case ScanStage::kWritingMesh:
      return "writing the mesh";
    case ScanStage::kDiscovering:
      return "discovering objects";
    case ScanStage::kRendering:
      return "rendering pictures";
    case ScanStage::kReporting:
      return "writing the report";
  }
  return "?";
}

ScanOutcome runScan(ScanRequest request, const std::vector<ScanObserver*>& observers) {
  request.fuse.config.validate();
  request.pictures.validate();
  return Scan(std::move(request), observers).run();
}

}  // namespace objscan::pipeline
