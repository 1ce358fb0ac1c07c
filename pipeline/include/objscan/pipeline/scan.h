#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "objscan/core/mesh_formats.h"
#include "objscan/core/output_folder.h"
#include "objscan/discovery/scenes.h"
#include "objscan/pipeline/fuse.h"
#include "objscan/pipeline/pictures.h"
#include "objscan/report/results.h"

/// The whole scan, as one call: a source fused, its objects discovered, evaluated against ground
/// truth where there is one, pictured and reported into one results folder. `objscan scan` and
/// `objscan fuse` are its callers; they print, serve the live page and turn the outcome into an
/// exit code through observers (ScanObserver).
namespace objscan::pipeline {

/// What a scan is asked to do.
struct ScanRequest {
  FuseOptions fuse;  ///< the source and how to fuse it
  /// --frames, --seconds, and `stop` (a Ctrl-C flag). The scan sets after_open, and for a whole
  /// scan the progress label and live_stop_ends_capture; observers' hooks (FusionHooks) are
  /// called after any the request holds.
  FuseLimits limits;
  /// false: fuse only (`objscan fuse`): mesh.ply, trajectory.txt and settings.json, whatever else
  /// the folder holds left as it is. true: the whole scan, which first removes what an earlier
  /// run derived from an earlier mesh.
  bool discover = true;
  discovery::SceneDiscoveryOptions discovery;  ///< config, model, catalog (checked by the caller)
  std::string model_name;  ///< the model file hypotheses.json names; empty: the average
  MeshFormat object_format = MeshFormat::kPly;  ///< objects/rank_NNN.<format>
  PictureOptions pictures;                      ///< the scan sets its label and stop
  std::filesystem::path out;
  /// A labelled mesh, already checked (requireLabelledMesh); empty: no evaluation.
  std::filesystem::path ground_truth;
  double min_iou = 0.7;       ///< a hypothesis finds an object at this IoU
  report::Settings settings;  ///< the caller's, completed with what fusion resolved
};

/// The stages a scan announces, in order.
enum class ScanStage { kFusing, kWritingMesh, kDiscovering, kRendering, kReporting };
const char* toString(ScanStage stage);  ///< "fusing frames", "writing the mesh", ...

/// What a scan produced. A stopped scan (interrupted) lists what it did not write.
struct ScanOutcome {
  report::ScanResults results;  ///< settings, timings, trajectory, hypotheses, evaluation, pictures
  FuseStats fuse;
  std::size_t mesh_vertices = 0, mesh_faces = 0;
  /// The discovery run (its scenes hold the mesh); nothing for fuse only or a scan stopped
  /// before it.
  std::optional<discovery::SceneDiscovery> discovery;
  bool interrupted = false;
  std::vector<std::string> not_produced;  ///< when interrupted
  std::filesystem::path report;           ///< report.html; empty when not written
  /// The results folder's lock, held from when the source was opened (empty when it never was):
  /// a caller that goes on serving the folder keeps it, so no other run writes there meanwhile.
  OutputFolderLock folder_lock;
};

/// What an observer may hook into fusion (FuseLimits' fields of the same names). Each observer
/// gets its own; the scan calls every observer's.
struct FusionHooks {
  std::function<void(const FrameEvent&)> on_frame;  ///< on the fusing thread: return quickly
  std::function<double()> extra_memory_bytes;       ///< memory it holds while fusion runs
  std::function<void()> before_meshing;
};

/// Whoever watches a scan: the command line's printing, the live page. Called on the scan's
/// thread, in stage order; every call has an empty default.
class ScanObserver {
 public:
  virtual ~ScanObserver() = default;
  /// Before fusion starts: a chance to take every frame and to count the memory it holds.
  virtual void watchFusion(FusionHooks& /*hooks*/) {}
  virtual void stageStarted(ScanStage /*stage*/) {}
  /// mesh.ply and trajectory.txt are written.
  virtual void fused(const FusedScene& /*fused*/, const std::filesystem::path& /*out*/) {}
  /// hypotheses.json and objects/ are written.
  virtual void discovered(const discovery::SceneDiscovery& /*run*/,
                          const std::filesystem::path& /*out*/) {}
  /// evaluation.json is written.
  virtual void evaluated(const report::Evaluation& /*evaluation*/,
                         const std::filesystem::path& /*truth*/) {}
  /// renders/ is written; with no hypotheses there is nothing to picture, and `outcome` holds
  /// no images (renders/ is not written).
  virtual void pictured(const PicturesOutcome& /*outcome*/, const std::filesystem::path& /*out*/) {}
  /// The scan is over, stopped or not: everything it wrote is in `outcome`.
  virtual void finished(const ScanOutcome& /*outcome*/) {}
};

/// Runs the scan: opens the source (the output folder is prepared and locked only once it is
/// open, so a source that cannot be opened leaves nothing behind), fuses it and writes mesh.ply
/// and trajectory.txt; then, unless fuse only, discovers (hypotheses.json, objects/), evaluates
/// (evaluation.json), renders (renders/) and reports (report.html, timings.json), and writes
/// settings.json. A stop (request.limits.stop) ends it where it is: what is written stays, a
/// stopped scan with hypotheses still gets its report, and the outcome lists what was not
/// produced; on a live source the first stop ends capture instead and the scan goes on. Throws
/// what the stages throw (InputError, OutputError, std::invalid_argument, ...).
ScanOutcome runScan(ScanRequest request, const std::vector<ScanObserver*>& observers = {});

}  // namespace objscan::pipeline
