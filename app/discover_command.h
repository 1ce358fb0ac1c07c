#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include "objscan/discovery/discover.h"

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

/// `objscan discover`: ranks the object hypotheses of one or more scene meshes into
/// OUT/hypotheses.json and OUT/objects/rank_NNN.ply, and prints a summary (and with --timings
/// each stage's time). Returns the exit code.
int runDiscover(const DiscoverCommandOptions& options);

}  // namespace objscan::app
