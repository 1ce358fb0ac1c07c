#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/discovery/discover.h"
#include "objscan/report/results.h"

namespace objscan::app {

struct EvalCommandOptions {
  std::vector<std::filesystem::path> scenes;  ///< labelled scenes (see readScenes)
  std::filesystem::path out;
  discovery::DiscoveryConfig config;
  std::optional<std::filesystem::path> catalog;  ///< nothing: no catalog
  int splits = 20;
  std::uint64_t seed = 1;
  bool ablation = true;
  report::Settings settings;  ///< the command line's, for OUT/settings.json
};

/// `objscan eval`: the paper's protocol on labelled scenes; writes ap.csv, pr_curves.csv,
/// pr_curves.png, segments.csv, recall.csv and summary.json into OUT and prints the AP table and
/// object recall. Returns the exit code.
int runEval(const EvalCommandOptions& options);

struct TrainCommandOptions {
  std::vector<std::filesystem::path> scenes;
  std::filesystem::path model;  ///< the file to write
  std::string kind = "rbf_svm";
  discovery::DiscoveryConfig config;
  std::optional<std::filesystem::path> catalog;
  double min_iou = 0.7;  ///< a segment is an object at this IoU with a ground-truth object
  std::uint64_t seed = 1;
};

/// `objscan train`: fits a classifier to labelled scenes' segments (grid search, 5-fold
/// cross-validation) and writes the model file that `objscan discover --model` reads.
int runTrain(const TrainCommandOptions& options);

}  // namespace objscan::app
