#include "scan_command.h"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <set>
#include <system_error>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scoring.h"
#include "output_folder.h"
#include "report.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Fails now, not after minutes of fusing, when OUT cannot take files (permissions, a read-only
/// file system): creates and removes a probe file.
void requireWritableFolder(const fs::path& out) {
  prepareOutputFolder(out);
  if (const int error = probeWritableFolder(out); error != 0) {
    throw OutputError(out,
                      std::string("cannot write into the output folder: ") + std::strerror(error));
  }
}

/// The ground-truth scene mesh that comes with a source: X.scene_gt.ply beside X.oni, or
/// scene_gt.ply in a recording folder (objscan synth writes both).
fs::path findGroundTruth(const std::string& source) {
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

/// Checks, before any work, that `path` is a mesh whose vertices carry object ids.
void requireLabelledMesh(const fs::path& path) {
  if (!readPly(path).hasLabels()) {
    throw InputError(path,
                     "no per-vertex object_id: not a ground-truth scene (objscan synth's "
                     "scene_gt.ply is one)");
  }
}

/// Object names from the scene_gt.json beside a scene_gt.ply, by id; empty when there is none.
std::unordered_map<std::int32_t, std::string> objectNames(const fs::path& truth_ply) {
  std::unordered_map<std::int32_t, std::string> names;
  fs::path json = truth_ply;
  json.replace_extension(".json");
  std::error_code ec;
  if (!fs::is_regular_file(json, ec)) return names;
  try {
    const nlohmann::json doc = nlohmann::json::parse(readWholeFile(json));
    for (const nlohmann::json& o : doc.at("objects")) {
      names[o.at("id").get<std::int32_t>()] = o.value("name", std::string());
    }
  } catch (const nlohmann::json::exception& e) {
    log::warning(json.string() + ": object names not read (" + e.what() + ")");
  }
  return names;
}

struct Evaluation {
  nlohmann::json json;
  std::size_t objects = 0, found = 0;
  double ap = 0.0;
};

/// Matches the ranked hypotheses, best first, with the ground-truth objects: a hypothesis finds
/// an object when their vertex IoU reaches min_iou and no better-ranked one found it already.
/// Precision and recall after each rank; AP is the mean, over the objects, of the precision at
/// the rank where each was found (0 for the objects never found).
Evaluation evaluateAgainstTruth(const fs::path& truth_path, const DiscoverOutcome& discovered,
                                double min_iou) {
  const LoadedScene& scene = discovered.set.scenes.at(0);
  const discovery::GroundTruthObjects truth(labelsFromTruthMesh(truth_path, scene.mesh));
  const auto names = objectNames(truth_path);
  Evaluation e;
  e.objects = truth.objectIds().size();
  std::set<std::int32_t> found;
  nlohmann::json curve = nlohmann::json::array(), matches = nlohmann::json::array();
  double precision_sum = 0.0;
  for (std::size_t k = 0; k < discovered.ranked.size(); ++k) {
    const discovery::ObjectMatch m =
        truth.bestMatch(discovered.ranked[k].hypothesis.segment.vertices);
    const bool hit = discovery::isObject(m, min_iou) && found.insert(m.object_id).second;
    const double precision = static_cast<double>(found.size()) / static_cast<double>(k + 1);
    if (hit) precision_sum += precision;
    curve.push_back(
        {{"rank", k + 1},
         {"recall",
          e.objects ? static_cast<double>(found.size()) / static_cast<double>(e.objects) : 0.0},
         {"precision", precision}});
    const auto name = names.find(m.object_id);
    matches.push_back(
        {{"rank", k + 1},
         {"object_id", m.object_id},
         {"object", m.object_id != 0 && name != names.end() ? nlohmann::json(name->second)
                                                            : nlohmann::json(nullptr)},
         {"iou", m.iou},
         {"found", hit}});
  }
  e.found = found.size();
  e.ap = e.objects ? precision_sum / static_cast<double>(e.objects) : 0.0;
  e.json = {{"ground_truth", truth_path.string()},
            {"objects", e.objects},
            {"min_iou", min_iou},
            {"found", e.found},
            {"ap", e.ap},
            {"curve", curve},
            {"hypotheses", matches}};
  return e;
}

/// The outputs of the stages after fusion; a new mesh makes an earlier run's stale.
const std::vector<std::string> kLaterOutputs = {"hypotheses.json", "objects",     "renders",
                                                "evaluation.json", "report.html", "timings.json"};

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

}  // namespace

int runScan(ScanCommandOptions options) {
  const auto start = Clock::now();
  if (options.source.empty()) options.source = "live";
  const fs::path& out = options.out;
  options.fuse.source = options.source;
  options.fuse.out = out;
  options.discover.meshes = {out / "mesh.ply"};
  options.discover.out = out;
  options.render.dir = out;
  // Settings and the ground-truth file are checked before anything is opened or written.
  options.fuse.config.validate();
  options.discover.config.validate();
  fs::path truth = options.ground_truth;
  if (!truth.empty() && !fs::is_regular_file(truth)) {
    throw InputError(truth, fs::exists(truth) ? "not a file" : "missing");
  }
  if (!truth.empty()) {
    requireLabelledMesh(truth);
  } else if (!options.no_ground_truth) {
    truth = findGroundTruth(options.source);
    if (!truth.empty()) {
      try {
        requireLabelledMesh(truth);
      } catch (const InputError& e) {
        log::warning(std::string("ground truth beside the source not used: ") + e.what());
        truth.clear();
      }
    }
  }
  if (!options.discover.model.empty()) {
    (void)discovery::ObjectnessModel::load(options.discover.model);  // reported now, not later
  }
  requireWritableFolder(out);

  nlohmann::json timings = {{"source", options.source}, {"interrupted", false}};
  nlohmann::json stages = nlohmann::json::array();
  std::vector<std::string> not_produced;
  const auto writeTimings = [&] {
    timings["stages"] = stages;
    timings["total_s"] = secondsSince(start);
    timings["not_produced"] = not_produced;
    writeFileAtomically(out / "timings.json", timings.dump(1) + "\n");
  };
  // Stops the run after a Ctrl-C: what is written stays, the rest is listed as not produced. Once
  // hypotheses.json exists, the report is written too, with a notice of what is missing.
  const auto stopHere = [&](std::vector<std::string> missing) {
    timings["interrupted"] = true;
    const bool report = fs::exists(out / "hypotheses.json");
    if (report) std::erase(missing, std::string("report.html"));
    not_produced = missing;
    writeTimings();
    if (report) writeReport(out);
    std::string list;
    for (const std::string& m : missing) list += (list.empty() ? "" : ", ") + m;
    std::printf("stopped by    Ctrl-C / SIGTERM; not produced: %s\n", list.c_str());
    std::printf("timings       %s\n", (out / "timings.json").string().c_str());
    return kExitInterrupted;
  };

  StopSignals signals;
  options.limits.progress_label = "scan [1/4] fusing frames";
  options.limits.live_stop_ends_capture = true;
  options.limits.before_writing = [&out] { removeStaleOutputs(out); };
  const FuseOutcome fused = fuseSource(options.fuse, options.limits);
  stages.push_back({{"name", "fuse"}, {"seconds", fused.fuse_s}});
  stages.push_back({{"name", "mesh"}, {"seconds", fused.mesh_s}});
  timings["source"] = fused.source_description;
  timings["frames"] = {{"read", fused.frames_read},
                       {"fused", fused.frames_fused},
                       {"lost", fused.frames_lost},
                       {"without_depth", fused.frames_without_depth},
                       {"unreadable", fused.bad_frames}};
  timings["mesh"] = {{"vertices", fused.mesh_vertices}, {"faces", fused.mesh_triangles}};
  printFuseSummary(fused);
  if (fused.interrupted) {
    // On a sensor, Ctrl-C is how capture ends: the scan goes on with what was fused.
    if (!fused.live) {
      std::vector<std::string> missing = {"hypotheses.json", "objects/", "renders/", "report.html"};
      if (!truth.empty()) missing.insert(missing.begin() + 2, "evaluation.json");
      return stopHere(missing);
    }
    std::printf("capture       ended by Ctrl-C after %zu frames\n", fused.frames_read);
  }
  if (!fused.sensor_lost.empty()) timings["sensor_lost"] = fused.sensor_lost;

  log::info("scan [2/4] discovering objects");
  const DiscoverOutcome discovered = discoverScenes(options.discover);
  stages.push_back({{"name", "discover"}, {"seconds", discovered.seconds}});
  timings["hypotheses"] = discovered.ranked.size();
  std::printf("hypotheses    %zu ranked -> %s, %s\n", discovered.ranked.size(),
              (out / "hypotheses.json").string().c_str(), (out / "objects").string().c_str());

  std::optional<Evaluation> evaluation;
  if (!truth.empty()) {
    const auto eval_start = Clock::now();
    evaluation = evaluateAgainstTruth(truth, discovered, options.min_iou);
    writeFileAtomically(out / "evaluation.json", evaluation->json.dump(1) + "\n");
    stages.push_back({{"name", "evaluation"}, {"seconds", secondsSince(eval_start)}});
    std::printf("ground truth  %zu of %zu objects found at IoU %.1f, AP %.3f (%s)\n",
                evaluation->found, evaluation->objects, options.min_iou, evaluation->ap,
                truth.string().c_str());
  }
  if (StopSignals::stopRequested()) return stopHere({"renders/", "report.html"});

  RenderOutcome rendered;
  if (discovered.ranked.empty()) {
    std::printf("renders       none: no hypothesis to show\n");
  } else {
    log::info("scan [3/4] rendering pictures");
    options.render.progress_label = "scan [3/4] rendering pictures";
    rendered = renderResults(options.render);
    stages.push_back({{"name", "render"}, {"seconds", rendered.seconds}});
    if (rendered.interrupted) return stopHere({"renders/", "report.html"});
    std::string visible;
    for (std::size_t rank : rendered.visible) {
      visible += (visible.empty() ? "#" : ", #") + std::to_string(rank);
    }
    std::printf("renders       %zu pictures (%s view; painted top %zu, visible: %s) -> %s\n",
                rendered.images, render::toString(rendered.view), rendered.painted,
                visible.empty() ? "none" : visible.c_str(), rendered.renders.string().c_str());
  }

  log::info("scan [4/4] writing the report");
  const auto report_start = Clock::now();
  stages.push_back({{"name", "report"}, {"seconds", 0.0}});
  writeTimings();  // the report shows the timings, so they exist before it
  const fs::path report = writeReport(out);
  stages.back()["seconds"] = secondsSince(report_start);
  writeTimings();

  std::string per_stage;
  for (const nlohmann::json& s : stages) {
    char part[64];
    std::snprintf(part, sizeof part, "%s%s %.1f s", per_stage.empty() ? "" : ", ",
                  s["name"].get<std::string>().c_str(), s["seconds"].get<double>());
    per_stage += part;
  }
  std::printf("time          %s; total %.1f s\n", per_stage.c_str(), secondsSince(start));
  std::printf("report        %s\n", report.string().c_str());
  // A sensor lost mid-capture still gives every output, from the frames before it, and exit 1.
  return reportSensorLoss(fused);
}

}  // namespace objscan::app
