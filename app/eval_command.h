#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/discovery/scenes.h"
#include "objscan/report/results.h"

namespace objscan::app {

struct EvalCommandOptions {
  std::vector<std::filesystem::path> scenes;  ///< labelled scenes (see readScenes)
  std::filesystem::path out;
  discovery::DiscoveryConfig config;
  discovery::SceneReading reading;               ///< how PCD scenes are read (--intrinsics)
  std::optional<std::filesystem::path> catalog;  ///< nothing: no catalog
  /// A classifier from objscan train for discover's ranking (the per-scene figures and object
  /// recall); empty: the average of the normalised measures. The classifier protocol is apart.
  std::filesystem::path model;
  int splits = 20;
  std::uint64_t seed = 1;
  bool ablation = true;
  /// Skip the classifier protocol (AP over random halvings): recall and per-scene figures only.
  bool classifiers = true;
  /// Scene categories for the per-category figures: NAME=REGEX, a POSIX extended regular expression
  /// matched against a scene's file name; the first that matches. Unmatched scenes: "other".
  std::vector<std::string> categories;
  report::Settings settings;  ///< the command line's, for OUT/settings.json
};

/// `objscan eval`: the paper's protocol on labelled scenes; writes ap.csv, pr_curves.csv,
/// pr_curves.png, segments.csv, recall.csv, scenes.csv, hypotheses.csv and summary.json into OUT
/// and prints the AP table, object recall and the per-scene means (by category too). Returns the
/// exit code.
int runEval(const EvalCommandOptions& options);

struct TrainCommandOptions {
  /// Labelled scenes (ground truth); none: the catalog's labels people gave in objscan view.
  std::vector<std::filesystem::path> scenes;
  std::filesystem::path model;  ///< the file to write
  std::string kind = "rbf_svm";
  discovery::DiscoveryConfig config;
  discovery::SceneReading reading;  ///< how PCD scenes are read (--intrinsics)
  std::optional<std::filesystem::path> catalog;
  double min_iou = 0.7;  ///< a segment is an object at this IoU with a ground-truth object
  std::uint64_t seed = 1;
};

/// `objscan train`: fits a classifier to labelled scenes' segments (grid search, 5-fold
/// cross-validation) and writes the model file that `objscan discover --model` reads. Without
/// scenes, to the segments people labelled in the catalog (discovery::catalogTrainingSet); too
/// few of them is std::invalid_argument, saying how many there are (exit code 2).
int runTrain(const TrainCommandOptions& options);

}  // namespace objscan::app
