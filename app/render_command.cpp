#include "render_command.h"

#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "exit_codes.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/ply_io.h"
#include "objscan/render/snapshots.h"
#include "objscan/report/report.h"
#include "objscan/report/results_io.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// The folder's results with the scene mesh the hypotheses were cut from (the first scene's).
report::ScanResults readForRendering(const fs::path& dir) {
  // Not the old pictures: they are being replaced, and a damaged one must not stop that.
  report::ResultsParts parts;
  parts.pictures = false;
  report::ScanResults results = report::readResults(dir, parts);
  const std::vector<report::SceneRecord>& scenes = results.hypotheses->scenes;
  if (scenes.empty()) throw InputError(dir / report::kHypothesesFile, "lists no scene");
  fs::path place;
  results.mesh = report::readSceneMesh(dir, scenes[0], &place);
  if (scenes.size() > 1) {
    log::warning("hypotheses.json holds " + std::to_string(scenes.size()) +
                 " scenes; rendering the first, " + place.string());
  }
  return results;
}

/// Renders the pictures of the folder's first scene (its mesh, trajectory and hypotheses) and
/// writes DIR/renders/ (swapped in whole; left as it was when stopped).
pipeline::PicturesOutcome renderAndWritePictures(const fs::path& dir,
                                                 const report::ScanResults& results,
                                                 const pipeline::PictureOptions& options) {
  std::vector<report::HypothesisRecord> first_scene;
  const std::string scene =
      results.hypotheses->scenes.empty() ? std::string() : results.hypotheses->scenes[0].mesh;
  for (const report::HypothesisRecord& h : results.hypotheses->hypotheses) {
    if (h.scene == scene) first_scene.push_back(h);
  }
  pipeline::PicturesOutcome outcome =
      pipeline::renderPictures(*results.mesh, results.trajectory ? &*results.trajectory : nullptr,
                               first_scene, options, (dir / report::kHypothesesFile).string());
  if (!outcome.interrupted) report::writePictures(dir, outcome.pictures);
  return outcome;
}

}  // namespace

void printPictures(const char* label, const pipeline::PicturesOutcome& o, const fs::path& dir) {
  std::string visible;
  for (std::size_t rank : o.pictures.visible) {
    visible += (visible.empty() ? "#" : ", #") + std::to_string(rank);
  }
  std::printf("%-14s%zu %s (%s view; painted top %zu, visible: %s) -> %s in %.1f s\n", label,
              o.images, o.images == 1 ? "picture" : "pictures", render::toString(o.view), o.painted,
              visible.empty() ? "none" : visible.c_str(), (dir / report::kRendersFolder).c_str(),
              o.seconds);
}

int runRender(const RenderCommandOptions& options) {
  options.pictures.validate();
  // Held while the folder is read and written: a discover or scan into it waits its turn.
  OutputFolderLock lock;
  if (fs::is_directory(options.dir)) lock = OutputFolderLock(options.dir);
  report::ScanResults results = readForRendering(options.dir);
  pipeline::PicturesOutcome outcome;
  {
    StopSignals signals;
    pipeline::PictureOptions pictures = options.pictures;
    pictures.stop = &StopSignals::flag();
    outcome = renderAndWritePictures(options.dir, results, pictures);
  }
  if (outcome.interrupted) {
    std::printf("stopped by    Ctrl-C / SIGTERM: %s was left as it was\n",
                (options.dir / report::kRendersFolder).c_str());
    return kExitInterrupted;
  }
  printPictures("written", outcome, options.dir);
  results.pictures = std::move(outcome.pictures);
  if (results.settings) {
    // The folder's settings now say how its pictures were made (scan --config repeats them).
    for (report::OptionSetting& o : results.settings->options) {
      for (const report::OptionSetting& r : options.settings.options) {
        if (r.name == o.name && r.name != "dir") o = r;
      }
    }
    report::writeSettings(options.dir / report::kSettingsFile, *results.settings);
  }
  std::printf("report        %s\n", report::writeReport(results, options.dir).c_str());
  return kExitSuccess;
}

}  // namespace objscan::app
