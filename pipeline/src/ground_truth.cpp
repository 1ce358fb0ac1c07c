#include "objscan/pipeline/ground_truth.h"

#include <map>
#include <system_error>
#include <vector>

#include "objscan/capture/synthetic/synthetic_recording.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/discovery/evaluation.h"
#include "objscan/pipeline/sources.h"
#include "objscan/report/results_io.h"

namespace objscan::pipeline {

namespace fs = std::filesystem;

fs::path findGroundTruth(const std::string& source) {
  if (isLiveSource(source)) return {};  // a sensor, not the folder `live` (./live)
  const fs::path p = source;
  fs::path candidate;
  std::error_code ec;
  if (p.extension() == ".oni") {
    candidate = p.parent_path() / (p.stem().string() + ".scene_gt.ply");
  } else if (fs::is_directory(p, ec)) {
    candidate = p / "scene_gt.ply";
  }
  return !candidate.empty() && fs::is_regular_file(candidate, ec) ? candidate : fs::path();
}

void requireLabelledMesh(const fs::path& path) {
  if (!readPly(path).hasLabels()) {
    throw InputError(path,
                     "no per-vertex object_id or label: not a ground-truth scene (objscan synth's "
                     "scene_gt.ply is one)");
  }
}

report::Evaluation evaluateAgainstTruth(const fs::path& truth, const discovery::SceneDiscovery& run,
                                        double min_iou) {
  const discovery::DiscoveredScene& scene = run.scenes.at(0);
  const discovery::GroundTruthObjects objects = discovery::truthFromMesh(truth, scene.mesh);
  std::vector<std::vector<std::int32_t>> ranked;
  for (const discovery::RankedHypothesis& r : run.ranked) {
    if (r.scene == 0) ranked.push_back(r.hypothesis.segment.vertices);
  }
  std::map<std::int32_t, std::string> names;
  // Names: scene_gt.json beside scene_gt.ply, or a labelled mesh's objects.json.
  fs::path json = truth;
  json.replace_extension(".json");
  std::error_code ec;
  if (!fs::is_regular_file(json, ec)) json = truth.parent_path() / "objects.json";
  if (fs::is_regular_file(json, ec)) {
    try {
      names = capture::readSceneObjectNames(json);
    } catch (const InputError& e) {
      log::warning(std::string("object names not read: ") + e.what());
    }
  }
  return report::evaluationFrom(discovery::evaluateRanking(objects, ranked, min_iou),
                                truth.string(), names);
}

}  // namespace objscan::pipeline
