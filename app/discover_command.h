#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include "discovery_scenes.h"
#include "objscan/discovery/discover.h"
#include "objscan/discovery/scoring.h"

namespace objscan::app {

struct DiscoverCommandOptions {
  std::vector<std::filesystem::path> meshes;
  std::filesystem::path out;
  discovery::DiscoveryConfig config;
  std::optional<std::filesystem::path> catalog;  ///< nothing: the default catalog
  bool no_catalog = false;
  std::filesystem::path model;  ///< empty: the unsupervised average
  bool timings = false;
};

/// A hypothesis of a run: which scene it is in, and the ranked hypothesis itself.
struct RankedHypothesis {
  std::size_t scene = 0;
  discovery::Hypothesis hypothesis;
};

/// What a discovery run found and wrote.
struct DiscoverOutcome {
  SceneSet set;
  std::vector<RankedHypothesis> ranked;  ///< best first, over all scenes
  discovery::ScoreKind scorer = discovery::ScoreKind::kAverage;
  std::optional<std::filesystem::path> catalog;  ///< the catalog used, if any
  double seconds = 0.0;
};

/// Ranks the hypotheses of options.meshes and writes OUT/hypotheses.json and
/// OUT/objects/rank_NNN.ply (the objects folder is swapped in whole, so it never mixes runs).
DiscoverOutcome discoverScenes(const DiscoverCommandOptions& options);

/// Prints discover's summary (and with options.timings each stage's time) to stdout.
void printDiscoverSummary(const DiscoverCommandOptions& options, const DiscoverOutcome& outcome);

/// `objscan discover`: ranks the object hypotheses of one or more scene meshes into
/// OUT/hypotheses.json and OUT/objects/rank_NNN.ply, and prints a summary (and with --timings
/// each stage's time). Returns the exit code.
int runDiscover(const DiscoverCommandOptions& options);

}  // namespace objscan::app
