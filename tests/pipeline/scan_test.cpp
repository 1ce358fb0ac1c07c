// The whole scan as one library call (pipeline/scan.h): the stages in order, told to observers,
// the results folder it writes matching what it returns, a stop, and fusion alone.
#include <algorithm>
#include <atomic>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "objscan/pipeline/scan.h"
#include "objscan/report/results_io.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using pipeline::ScanStage;

/// A synthetic desk of three objects, ten frames: a scan of a few seconds.
constexpr const char* kSource = "synth:5,frames=10,objects=3";

/// Writes down what it is told, as short words, in order; can stop the scan once it has the
/// hypotheses.
class Recorder : public pipeline::ScanObserver {
 public:
  std::vector<std::string> events;
  std::atomic<bool>* stop_after_discovery = nullptr;
  std::size_t frames = 0;

  void watchFusion(pipeline::FusionHooks& hooks) override {
    events.push_back("watch");
    hooks.on_frame = [this](const pipeline::FrameEvent&) { ++frames; };
    hooks.before_meshing = [this] { events.push_back("meshing"); };
  }
  void stageStarted(ScanStage stage) override {
    events.push_back(std::string("stage:") + pipeline::toString(stage));
  }
  void fused(const pipeline::FusedScene& fused, const fs::path& out) override {
    events.push_back("fused");
    // Told once the files are there.
    EXPECT_EQ(readPly(out / report::kMeshFile).positions.size(), fused.mesh.positions.size());
  }
  void discovered(const discovery::SceneDiscovery& run, const fs::path& out) override {
    events.push_back("discovered");
    EXPECT_EQ(report::readHypotheses(out / report::kHypothesesFile).hypotheses.size(),
              run.ranked.size());
    if (stop_after_discovery) stop_after_discovery->store(true);
  }
  void evaluated(const report::Evaluation&, const fs::path&) override {
    events.push_back("evaluated");
  }
  void pictured(const pipeline::PicturesOutcome& outcome, const fs::path& out) override {
    events.push_back("pictured");
    EXPECT_GT(outcome.images, 0u);
    EXPECT_TRUE(fs::is_directory(out / report::kRendersFolder));
  }
  void finished(const pipeline::ScanOutcome& outcome) override {
    events.push_back("finished");
    // The folder is still the scan's: no other run can take it until the caller lets it go.
    EXPECT_TRUE(outcome.folder_lock.held());
    EXPECT_THROW(OutputFolderLock{folder}, FolderBusyError);
  }
  fs::path folder;  ///< the scan's output folder
};

pipeline::ScanRequest requestInto(const fs::path& out) {
  pipeline::ScanRequest request;
  request.fuse.source = kSource;
  request.out = out;
  request.settings.command = "scan";
  return request;  // no catalog: SceneDiscoveryOptions' default
}

TEST(ScanFlow, TellsItsObserversEachStageInOrderAndWritesWhatItReturns) {
  testing::TempDir dir;
  const fs::path out = dir / "scan";
  fs::create_directories(out);
  // What an earlier run derived from an earlier mesh goes: it would not match the new one.
  testing::writeBytes(out / report::kEvaluationFile, "{}");
  fs::create_directories(out / report::kObjectsFolder / "rank_099.ply");
  Recorder a, b;
  a.folder = b.folder = out;
  const pipeline::ScanOutcome outcome = pipeline::runScan(requestInto(out), {&a, &b});

  const std::vector<std::string> expected = {
      "watch",    "stage:fusing frames",       "meshing",    "stage:writing the mesh",
      "fused",    "stage:discovering objects", "discovered", "stage:rendering pictures",
      "pictured", "stage:writing the report",  "finished"};
  EXPECT_EQ(a.events, expected);
  EXPECT_EQ(b.events, expected);
  EXPECT_EQ(a.frames, 10u);  // each observer's own per-frame call, both kept
  EXPECT_EQ(b.frames, 10u);

  EXPECT_FALSE(outcome.interrupted);
  EXPECT_EQ(outcome.fuse.frames_read, 10u);
  ASSERT_TRUE(outcome.discovery.has_value());
  ASSERT_TRUE(outcome.results.hypotheses.has_value());
  EXPECT_GT(outcome.discovery->ranked.size(), 0u);
  EXPECT_EQ(outcome.results.hypotheses->hypotheses.size(), outcome.discovery->ranked.size());
  EXPECT_EQ(outcome.report, out / report::kReportFile);
  // The earlier run's outputs are gone (this one had no ground truth to evaluate against).
  EXPECT_FALSE(fs::exists(out / report::kEvaluationFile));
  EXPECT_FALSE(fs::exists(out / report::kObjectsFolder / "rank_099.ply"));

  // The folder holds what the outcome says, read back by the results model's own readers.
  EXPECT_EQ(readPly(out / report::kMeshFile).positions.size(), outcome.mesh_vertices);
  EXPECT_EQ(report::readHypotheses(out / report::kHypothesesFile).hypotheses.size(),
            outcome.discovery->ranked.size());
  const report::Timings timings = report::readTimings(out / report::kTimingsFile);
  std::vector<std::string> stages;
  for (const report::StageTime& s : timings.stages) stages.push_back(s.name);
  EXPECT_EQ(stages, (std::vector<std::string>{"fuse", "mesh", "discover", "render", "report"}));
  EXPECT_FALSE(timings.interrupted);
  const report::Settings settings = report::readSettings(out / report::kSettingsFile);
  EXPECT_EQ(settings.command, "scan");
  ASSERT_TRUE(settings.intrinsics.has_value());  // what fusion resolved is added
  EXPECT_GT(settings.intrinsics->fx_px, 0.0f);
  EXPECT_TRUE(fs::is_regular_file(out / report::kReportFile));
}

TEST(ScanFlow, AStopAfterDiscoveryKeepsTheHypothesesAndSaysWhatIsMissing) {
  testing::TempDir dir;
  const fs::path out = dir / "scan";
  std::atomic<bool> stop{false};
  Recorder recorder;
  recorder.folder = out;
  recorder.stop_after_discovery = &stop;
  pipeline::ScanRequest request = requestInto(out);
  request.limits.stop = &stop;
  const pipeline::ScanOutcome outcome = pipeline::runScan(std::move(request), {&recorder});

  EXPECT_EQ(recorder.events.back(), "finished");
  EXPECT_EQ(std::count(recorder.events.begin(), recorder.events.end(), "pictured"), 0);
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_EQ(outcome.not_produced, std::vector<std::string>{"renders/"});
  EXPECT_FALSE(fs::exists(out / report::kRendersFolder));
  // The hypotheses stay, and the report shows them with a notice of what is missing.
  EXPECT_TRUE(fs::is_regular_file(out / report::kHypothesesFile));
  EXPECT_EQ(outcome.report, out / report::kReportFile);
  const report::Timings timings = report::readTimings(out / report::kTimingsFile);
  EXPECT_TRUE(timings.interrupted);
  EXPECT_EQ(timings.not_produced, std::vector<std::string>{"renders/"});
}

TEST(ScanFlow, AStopWhileARecordingIsFusedKeepsTheMeshAndNothingAfterIt) {
  testing::TempDir dir;
  const fs::path out = dir / "scan";
  std::atomic<bool> stop{false};
  std::size_t frames = 0;
  pipeline::ScanRequest request = requestInto(out);
  request.limits.stop = &stop;
  // The request's own hook runs beside the observers': the fourth frame asks to stop.
  request.limits.on_frame = [&](const pipeline::FrameEvent&) {
    if (++frames == 4) stop.store(true);
  };
  Recorder recorder;
  recorder.folder = out;
  const pipeline::ScanOutcome outcome = pipeline::runScan(std::move(request), {&recorder});

  EXPECT_EQ(recorder.events,
            (std::vector<std::string>{"watch", "stage:fusing frames", "meshing",
                                      "stage:writing the mesh", "fused", "finished"}));
  EXPECT_EQ(recorder.frames, frames);
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_LT(outcome.fuse.frames_read, 10u);
  // A recording is not a sensor: a stop ends the scan, not just the capture.
  EXPECT_EQ(outcome.not_produced,
            (std::vector<std::string>{"hypotheses.json", "objects/", "renders/", "report.html"}));
  EXPECT_FALSE(outcome.discovery.has_value());
  EXPECT_TRUE(outcome.report.empty());
  EXPECT_EQ(readPly(out / report::kMeshFile).positions.size(), outcome.mesh_vertices);
  EXPECT_GT(outcome.mesh_vertices, 0u);
  EXPECT_FALSE(fs::exists(out / report::kHypothesesFile));
  EXPECT_FALSE(fs::exists(out / report::kReportFile));
  EXPECT_TRUE(report::readTimings(out / report::kTimingsFile).interrupted);
}

TEST(ScanFlow, FusionAloneWritesTheMeshAndLeavesTheRestOfTheFolder) {
  testing::TempDir dir;
  const fs::path out = dir / "fused";
  fs::create_directories(out);
  testing::writeBytes(out / report::kHypothesesFile, "kept");
  Recorder recorder;
  recorder.folder = out;
  pipeline::ScanRequest request = requestInto(out);
  request.discover = false;
  request.settings.command = "fuse";
  const pipeline::ScanOutcome outcome = pipeline::runScan(std::move(request), {&recorder});

  EXPECT_EQ(recorder.events,
            (std::vector<std::string>{"watch", "stage:fusing frames", "meshing",
                                      "stage:writing the mesh", "fused", "finished"}));
  EXPECT_FALSE(outcome.interrupted);
  EXPECT_FALSE(outcome.discovery.has_value());
  EXPECT_TRUE(outcome.report.empty());
  EXPECT_EQ(readPly(out / report::kMeshFile).positions.size(), outcome.mesh_vertices);
  EXPECT_EQ(readTumTrajectory(out / report::kTrajectoryFile).size(), 10u);
  EXPECT_EQ(report::readSettings(out / report::kSettingsFile).command, "fuse");
  EXPECT_EQ(readWholeFile(out / report::kHypothesesFile), "kept");
  EXPECT_FALSE(fs::exists(out / report::kTimingsFile));
}

}  // namespace
}  // namespace objscan
