#include "discover_command.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <system_error>

#include <nlohmann/json.hpp>

#include "discovery_scenes.h"
#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/discovery/scoring.h"
#include "output_folder.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

nlohmann::json vectorJson(const Eigen::Vector3f& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json measuresJson(const discovery::ShapeMeasures& m) {
  nlohmann::json j;
  const auto values = discovery::measureValues(m);
  // null: unknown (recurrence without another scene to compare with).
  for (std::size_t k = 0; k < values.size(); ++k) {
    j[discovery::kMeasureNames[k]] =
        std::isfinite(values[k]) ? nlohmann::json(values[k]) : nlohmann::json(nullptr);
  }
  return j;
}

/// The oriented box of a segment: centre, axes (unit, as rows) and the extent along each, metres.
/// The centre is the middle of the extents, not the centroid.
nlohmann::json boxJson(const TriangleMesh& mesh, const discovery::Segment& s) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (std::int32_t v : s.vertices) {
    const Eigen::Vector3f p = s.axes.transpose() * (mesh.positions[v] - s.centroid);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3f centre = s.centroid + s.axes * (0.5f * (lo + hi));
  nlohmann::json j;
  j["centre"] = vectorJson(centre);
  j["axes"] = {vectorJson(s.axes.col(0)), vectorJson(s.axes.col(1)), vectorJson(s.axes.col(2))};
  j["extents"] = vectorJson(hi - lo);
  return j;
}

std::string rankFile(std::size_t rank) { return "objects/" + rankFileName(rank, ".ply"); }

/// Writes the sub-meshes into OUT/objects.partial (a fresh folder).
void stageObjects(const fs::path& out, const std::vector<RankedHypothesis>& ranked,
                  const std::vector<LoadedScene>& scenes) {
  const fs::path partial = freshPartialFolder(out, "objects");
  for (std::size_t i = 0; i < ranked.size(); ++i) {
    const TriangleMesh& mesh = scenes[ranked[i].scene].mesh;
    writePly(partial / fs::path(rankFile(i + 1)).filename(),
             mesh.subset(ranked[i].hypothesis.segment.vertices));
  }
}

}  // namespace

DiscoverOutcome discoverScenes(const DiscoverCommandOptions& options) {
  const auto start = Clock::now();
  options.config.validate();
  std::optional<discovery::ObjectnessModel> model;
  if (!options.model.empty()) model = discovery::ObjectnessModel::load(options.model);
  SceneSetOptions set_options;
  set_options.config = options.config;
  if (!options.no_catalog) set_options.catalog = options.catalog.value_or(defaultCatalogPath());
  prepareOutputFolder(options.out);
  DiscoverOutcome outcome;
  SceneSet& set = outcome.set;
  set = readScenes(options.meshes, set_options);
  const discovery::ObjectnessModel scorer =
      model ? *model
            : discovery::ObjectnessModel::average(set.normaliser,
                                                  discovery::varyingMeasures(set.normaliser));

  std::vector<RankedHypothesis>& ranked = outcome.ranked;
  std::vector<std::size_t> per_scene(set.scenes.size(), 0);
  for (std::size_t s = 0; s < set.scenes.size(); ++s) {
    for (discovery::Hypothesis& h :
         discovery::rankCandidates(set.scenes[s].candidates, scorer, options.config.max_iou)) {
      ranked.push_back({s, std::move(h)});
      ++per_scene[s];
    }
  }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const RankedHypothesis& a, const RankedHypothesis& b) {
                     return a.hypothesis.score > b.hypothesis.score;
                   });
  // The sub-meshes are staged first, then the JSON that names them is written, then they are
  // swapped in: a failure before the swap leaves the previous run's pair as it was.
  stageObjects(options.out, ranked, set.scenes);

  nlohmann::json doc;
  doc["scoring"] = {
      {"kind", discovery::toString(scorer.kind())},
      {"model", options.model.empty() ? nullptr : nlohmann::json(options.model.string())},
      {"normalised_over", model                 ? "the model's training segments"
                          : set_options.catalog ? "catalog"
                                                : "these scenes"}};
  if (set_options.catalog) {
    doc["catalog"] = {{"path", set_options.catalog->string()},
                      {"scenes", set.catalog_scenes},
                      {"segments", set.catalog_segments}};
  }
  nlohmann::json scenes = nlohmann::json::array();
  for (std::size_t s = 0; s < set.scenes.size(); ++s) {
    const LoadedScene& scene = set.scenes[s];
    const discovery::DiscoveryTimings& t = scene.candidates.timings;
    nlohmann::json j = {
        {"mesh", scene.mesh_path.string()},     {"vertices", scene.mesh.positions.size()},
        {"faces", scene.mesh.triangles.size()}, {"candidates", scene.candidates.segments.size()},
        {"hypotheses", per_scene[s]},           {"from_catalog", scene.from_catalog}};
    if (!scene.from_catalog) {
      j["median_edge_m"] = scene.candidates.effective.median_edge_m;
      j["min_size"] = scene.candidates.effective.min_size;
      j["support_planes"] = scene.candidates.support_planes;
      j["support_vertices"] = scene.candidates.support_vertices;
      j["timings_ms"] = {{"graph", t.graph_ms},
                         {"supports", t.support_ms},
                         {"segmentation", t.segment_ms},
                         {"filters", t.filter_ms},
                         {"measures", t.measure_ms}};
    }
    scenes.push_back(j);
  }
  doc["scenes"] = scenes;
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t i = 0; i < ranked.size(); ++i) {
    const LoadedScene& scene = set.scenes[ranked[i].scene];
    const discovery::Hypothesis& h = ranked[i].hypothesis;
    list.push_back({{"rank", i + 1},
                    {"score", h.score},
                    {"scene", scene.mesh_path.string()},
                    {"measures", measuresJson(h.measures)},
                    {"box", boxJson(scene.mesh, h.segment)},
                    {"scale", h.segment.scale},
                    {"vertex_count", h.segment.vertices.size()},
                    {"vertices", h.segment.vertices},
                    {"file", rankFile(i + 1)}});
  }
  doc["hypotheses"] = list;
  writeFileAtomically(options.out / "hypotheses.json", doc.dump(1) + "\n");
  swapInFolder(options.out, "objects");
  outcome.scorer = scorer.kind();
  outcome.catalog = set_options.catalog;
  outcome.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return outcome;
}

void printDiscoverSummary(const DiscoverCommandOptions& options, const DiscoverOutcome& outcome) {
  const SceneSet& set = outcome.set;
  const std::vector<RankedHypothesis>& ranked = outcome.ranked;

  std::size_t candidates = 0, cached = 0;
  for (const LoadedScene& s : set.scenes) {
    candidates += s.candidates.segments.size();
    cached += s.from_catalog ? 1 : 0;
  }
  std::printf("scenes        %zu (%zu from the catalog)\n", set.scenes.size(), cached);
  std::printf("candidates    %zu after the filters; %zu hypotheses after suppression\n", candidates,
              ranked.size());
  std::printf("scored by     %s%s\n", discovery::toString(outcome.scorer),
              options.model.empty() ? " of the z-normalised measures"
                                    : (" (" + options.model.string() + ")").c_str());
  if (outcome.catalog) {
    std::printf("catalog       %s: %zu scenes, %zu segments\n", outcome.catalog->c_str(),
                set.catalog_scenes, set.catalog_segments);
  }
  if (ranked.empty()) std::printf("no object candidates\n");
  for (std::size_t i = 0; i < std::min<std::size_t>(ranked.size(), 10); ++i) {
    const discovery::Hypothesis& h = ranked[i].hypothesis;
    std::printf("  #%-3zu score %+.3f  %5zu vertices  %.0f x %.0f x %.0f mm%s%s\n", i + 1, h.score,
                h.segment.vertices.size(), 1e3 * h.segment.extents[0], 1e3 * h.segment.extents[1],
                1e3 * h.segment.extents[2], set.scenes.size() > 1 ? "  " : "",
                set.scenes.size() > 1 ? set.scenes[ranked[i].scene].mesh_path.c_str() : "");
  }
  if (options.timings) {
    for (const LoadedScene& s : set.scenes) {
      if (s.from_catalog) {
        std::printf("time          %s: from the catalog\n", s.mesh_path.c_str());
        continue;
      }
      const discovery::DiscoveryTimings& t = s.candidates.timings;
      std::printf(
          "time          %s: graph %.0f ms, supports %.0f ms, segmentation %.0f ms, "
          "filters %.0f ms, measures %.0f ms\n",
          s.mesh_path.c_str(), t.graph_ms, t.support_ms, t.segment_ms, t.filter_ms, t.measure_ms);
    }
  }
  std::printf("written       %s (hypotheses.json, objects/) in %.1f s\n", options.out.c_str(),
              outcome.seconds);
}

int runDiscover(const DiscoverCommandOptions& options) {
  printDiscoverSummary(options, discoverScenes(options));
  return kExitSuccess;
}

}  // namespace objscan::app
