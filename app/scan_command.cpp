#include "scan_command.h"

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "exit_codes.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/mesh_formats.h"
#include "objscan/pipeline/ground_truth.h"
#include "objscan/pipeline/scan.h"
#include "objscan/report/results_io.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// The items of a list, joined with commas.
std::string joined(const std::vector<std::string>& items) {
  std::string list;
  for (const std::string& m : items) list += (list.empty() ? "" : ", ") + m;
  return list;
}

/// The ground truth to evaluate against, checked before any work; empty for none.
fs::path groundTruthOf(const ScanCommandOptions& options) {
  fs::path truth = options.ground_truth;
  if (!truth.empty()) {
    requireGroundTruthFile(truth);
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

/// scan's lines on stdout, stage by stage.
class ScanPrinter : public pipeline::ScanObserver {
 public:
  ScanPrinter(fs::path out, double min_iou) : out_(std::move(out)), min_iou_(min_iou) {}

  void fused(const pipeline::FusedScene& fused, const fs::path& out) override {
    printFuseSummary(fused, out);
    if (fused.stats.interrupted && fused.stats.live) {
      std::printf("capture       ended by Ctrl-C after %zu frames\n", fused.stats.frames_read);
    }
  }

  void discovered(const discovery::SceneDiscovery& run, const fs::path& out) override {
    std::printf("hypotheses    %zu ranked -> %s, %s\n", run.ranked.size(),
                (out / report::kHypothesesFile).c_str(), (out / report::kObjectsFolder).c_str());
    printCatalogUse(run);
  }

  void evaluated(const report::Evaluation& evaluation, const fs::path& truth) override {
    std::printf("ground truth  %zu of %zu objects found at IoU %.1f, AP %.3f (%s)\n",
                *evaluation.found, *evaluation.objects, min_iou_, evaluation.ap, truth.c_str());
  }

  void pictured(const pipeline::PicturesOutcome& outcome, const fs::path& out) override {
    if (outcome.images == 0) {
      std::printf("renders       none: no hypothesis to show\n");
      return;
    }
    printPictures("renders", outcome, out);
  }

  void finished(const pipeline::ScanOutcome& outcome) override {
    const report::Timings& timings = *outcome.results.timings;
    if (outcome.interrupted) {
      std::printf("stopped by    Ctrl-C / SIGTERM; not produced: %s\n",
                  joined(outcome.not_produced).c_str());
      std::printf("timings       %s\n", (out_ / report::kTimingsFile).c_str());
      return;
    }
    std::string per_stage;
    for (const report::StageTime& s : timings.stages) {
      char part[64];
      std::snprintf(part, sizeof part, "%s%s %.1f s", per_stage.empty() ? "" : ", ", s.name.c_str(),
                    s.seconds);
      per_stage += part;
    }
    std::printf("time          %s; total %.1f s\n", per_stage.c_str(), *timings.total_s);
    std::printf("report        %s\n", outcome.report.c_str());
  }

 private:
  fs::path out_;
  double min_iou_;
};

/// What a stopped scan tells the page: it ends at once, showing what was written.
server::LiveFinal stoppedFinal(const std::vector<std::string>& missing) {
  return server::LiveFinal::without("stopped by Ctrl-C / SIGTERM; not produced: " +
                                    joined(missing));
}

}  // namespace

void requireGroundTruthFile(const fs::path& truth) {
  if (!fs::is_regular_file(truth)) {
    throw InputError(truth, fs::exists(truth) ? "not a file" : "missing");
  }
  pipeline::requireLabelledMesh(truth);
}

int runScan(ScanCommandOptions options) {
  if (options.source.empty()) options.source = "live";
  options.fuse.source = options.source;
  // Settings, the ground truth and the model are checked before anything is opened or written.
  options.fuse.config.validate();
  options.pictures.validate();
  pipeline::ScanRequest request;
  request.ground_truth = groundTruthOf(options);
  request.discovery = sceneDiscoveryOptions(options.discover);
  request.fuse = options.fuse;
  request.limits = options.limits;
  request.model_name = options.discover.model.string();
  request.object_format = meshFormatFromName(options.discover.object_format);
  request.pictures = options.pictures;
  request.out = options.out;
  request.min_iou = options.min_iou;
  request.settings = options.settings;
  server::LiveSettings live_settings;
  live_settings.command = "scan";
  live_settings.source = options.source;
  live_settings.results = options.out;
  live_settings.discovery_config = options.discover.config;
  // Before the folder is touched: a port that cannot be had leaves nothing behind.
  const std::unique_ptr<LiveRun> live = LiveRun::start(options.serve, live_settings);
  try {
    StopSignals signals;
    request.limits.stop = &StopSignals::flag();
    ScanPrinter printer(options.out, options.min_iou);
    std::vector<pipeline::ScanObserver*> observers = {&printer};
    if (live) observers.push_back(live.get());
    const pipeline::ScanOutcome outcome = pipeline::runScan(std::move(request), observers);
    if (outcome.interrupted) {
      if (live) live->finish(stoppedFinal(outcome.not_produced), false);
      return kExitInterrupted;
    }
    // A sensor lost mid-capture still gives every output, from the frames before it, and exit 1.
    const int code = reportSensorLoss(outcome.fuse);
    if (live) {
      server::LiveFinal final;
      final.outcome = code == kExitSuccess
                          ? "finished: " + std::to_string(outcome.discovery->ranked.size()) +
                                " hypotheses ranked"
                          : "sensor lost: " + outcome.fuse.sensor_lost;
      final.failed = code != kExitSuccess;
      final.addHypotheses(*outcome.discovery, live_settings.shown_hypotheses);
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
