#include "discover_command.h"

#include <algorithm>
#include <cstdio>

#include "exit_codes.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/progress.h"
#include "objscan/pipeline/frame_scene.h"
#include "objscan/report/results_io.h"

namespace objscan::app {

discovery::SceneDiscoveryOptions sceneDiscoveryOptions(const DiscoverCommandOptions& options) {
  options.config.validate();
  discovery::SceneDiscoveryOptions out;
  out.config = options.config;
  if (!options.model.empty()) out.model = discovery::ObjectnessModel::load(options.model);
  if (!options.no_catalog) out.catalog = options.catalog.value_or(discovery::defaultCatalogPath());
  return out;
}

report::Hypotheses writeDiscoveryResults(const DiscoverCommandOptions& options,
                                         const discovery::SceneDiscovery& run) {
  const MeshFormat format = meshFormatFromName(options.object_format);
  report::Hypotheses hypotheses =
      report::hypothesesFrom(run, options.model.string(), options.out, format);
  report::writeDiscovery(options.out, hypotheses, run, format);
  return hypotheses;
}

void printDiscoverSummary(const DiscoverCommandOptions& options,
                          const discovery::SceneDiscovery& run) {
  std::size_t candidates = 0, cached = 0;
  for (const discovery::DiscoveredScene& s : run.scenes) {
    candidates += s.candidates.segments.size();
    cached += s.from_catalog ? 1 : 0;
  }
  std::printf("scenes        %zu (%zu from the catalog)\n", run.scenes.size(), cached);
  const std::size_t objects = static_cast<std::size_t>(
      std::count_if(run.ranked.begin(), run.ranked.end(), [](const discovery::RankedHypothesis& r) {
        return r.hypothesis.object_rank > 0;
      }));
  if (options.config.objects.enabled) {
    std::printf("candidates    %zu after the filters; %zu hypotheses: %zu objects (no two "
                "overlap), then %zu alternatives\n",
                candidates, run.ranked.size(), objects, run.ranked.size() - objects);
  } else {
    std::printf("candidates    %zu after the filters; %zu hypotheses after suppression\n",
                candidates, run.ranked.size());
  }
  std::printf("scored by     %s%s\n", discovery::toString(run.scorer),
              options.model.empty() ? " of the z-normalised measures"
                                    : (" (" + options.model.string() + ")").c_str());
  printCatalogUse(run);
  if (run.ranked.empty()) std::printf("no object candidates\n");
  const bool many = run.scenes.size() > 1;
  for (std::size_t i = 0; i < std::min<std::size_t>(run.ranked.size(), 10); ++i) {
    const discovery::Hypothesis& h = run.ranked[i].hypothesis;
    const char* footing = h.object_rank == 0                                  ? ""
                          : h.context.footing == discovery::Footing::kSupport  ? "  on a support"
                          : h.context.footing == discovery::Footing::kOnSurface ? "  on a surface"
                          : h.context.footing == discovery::Footing::kPatch ? "  a support's patch"
                          : h.context.footing == discovery::Footing::kUnder ? "  under a support"
                                                                               : "  floating";
    // An object is ranked by its object score, an alternative by its score.
    const bool object = h.object_rank > 0;
    std::printf("  #%-3zu %s %+.3f  %5zu vertices  %.0f x %.0f x %.0f mm%s%s%s\n", i + 1,
                object ? "object score" : "score", object ? h.object_score : h.score,
                h.segment.vertices.size(), 1e3 * h.segment.extents[0],
                1e3 * h.segment.extents[1], 1e3 * h.segment.extents[2], footing,
                many ? "  " : "", many ? run.scenes[run.ranked[i].scene].name.c_str() : "");
  }
  if (options.timings) {
    for (const discovery::DiscoveredScene& s : run.scenes) {
      if (s.from_catalog) {
        std::printf("time          %s: from the catalog\n", s.name.c_str());
        continue;
      }
      const discovery::DiscoveryTimings& t = s.candidates.timings;
      std::printf(
          "time          %s: graph %.0f ms, supports %.0f ms, segmentation %.0f ms, "
          "filters %.0f ms, measures %.0f ms\n",
          s.name.c_str(), t.graph_ms, t.support_ms, t.segment_ms, t.filter_ms, t.measure_ms);
    }
  }
  std::printf("written       %s (hypotheses.json, objects/) in %.1f s\n", options.out.c_str(),
              run.seconds);
}

void printCatalogUse(const discovery::SceneDiscovery& run) {
  if (!run.catalog) return;
  std::printf("catalog       %s: %zu scenes, %zu segments\n", run.catalog->c_str(),
              run.catalog_scenes, run.catalog_segments);
  if (run.catalog_scenes > run.scenes.size()) {
    // The paper's normalisation over every scene seen: a surprise when it is not said.
    std::printf(
        "              scores are normalised over all %zu scenes, so the same scene can rank "
        "differently as scenes are added (--no-catalog ranks these scenes alone)\n",
        run.catalog_scenes);
  }
}

int runDiscover(const DiscoverCommandOptions& options) {
  const discovery::SceneDiscoveryOptions library = sceneDiscoveryOptions(options);
  std::vector<discovery::SceneInput> scenes;
  {
    ProgressBar progress("reading scenes", options.meshes.size());
    for (const std::filesystem::path& mesh : options.meshes) {
      discovery::SceneReading reading = options.reading;
      reading.hash = library.catalog.has_value();
      scenes.push_back(pipeline::readScene(mesh, reading, options.frame));
      progress.advance();
    }
  }
  // Once every scene has been read (and found to fit in memory): a scene that cannot be leaves no
  // output folder behind.
  discovery::requireMemoryFor(scenes);
  const OutputFolderLock lock = prepareOutputFolder(options.out);
  const discovery::SceneDiscovery run = discovery::discoverScenes(std::move(scenes), library);
  writeDiscoveryResults(options, run);
  report::Settings settings = options.settings;
  settings.catalog = report::catalogUseOf(run);
  report::writeSettings(options.out / report::kSettingsFile, settings);
  printDiscoverSummary(options, run);
  return kExitSuccess;
}

}  // namespace objscan::app
