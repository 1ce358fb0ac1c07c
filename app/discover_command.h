#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <vector>

#include "objscan/discovery/scenes.h"
#include "objscan/report/results.h"

namespace objscan::app {

struct DiscoverCommandOptions {
  /// Scenes as the command line names them: meshes, folders holding one, PCD clouds; with
  /// `frame`, <source>s (openFrameSource) of which that one frame is the scene.
  std::vector<std::filesystem::path> meshes;
  std::optional<std::size_t> frame;  ///< --frame N
  std::filesystem::path out;
  discovery::DiscoveryConfig config;
  discovery::SceneReading reading;  ///< how PCD scenes and frames are read (--intrinsics)
  std::optional<std::filesystem::path> catalog;  ///< nothing: the default catalog
  bool no_catalog = false;
  std::filesystem::path model;  ///< empty: the unsupervised average
  bool timings = false;
  std::string object_format = "ply";  ///< --object-format: objects/rank_NNN.<format>
  report::Settings settings;          ///< the command line's, for OUT/settings.json
};

/// The library's options for these: the config checked, the model loaded, the catalog resolved
/// (InputError / std::invalid_argument for a bad one, before any work).
discovery::SceneDiscoveryOptions sceneDiscoveryOptions(const DiscoverCommandOptions& options);

/// Writes OUT/hypotheses.json and OUT/objects/rank_NNN.<format> (with rank_NNN.json, its box and
/// pose) of a discovery run (the objects folder
/// swapped in whole, so it never mixes runs) and returns what was written.
report::Hypotheses writeDiscoveryResults(const DiscoverCommandOptions& options,
                                         const discovery::SceneDiscovery& run);

/// The catalog line of discover's and scan's summaries, with a note when the catalog holds other
/// scenes, whose measures the scores are normalised over.
void printCatalogUse(const discovery::SceneDiscovery& run);

/// Prints discover's summary (and with options.timings each stage's time) to stdout.
void printDiscoverSummary(const DiscoverCommandOptions& options,
                          const discovery::SceneDiscovery& run);

/// `objscan discover`: ranks the object hypotheses of one or more scene meshes into
/// OUT/hypotheses.json and OUT/objects/rank_NNN.ply, and prints a summary (and with --timings
/// each stage's time). Returns the exit code.
int runDiscover(const DiscoverCommandOptions& options);

}  // namespace objscan::app
