#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "objscan/discovery/labels.h"
#include "objscan/discovery/scoring.h"

/// The paper's evaluation protocol (section V): measures z-normalised over the whole data set,
/// half the segments to train and half to test, repeated over random splits, each classifier's
/// parameters chosen by 5-fold cross-validated grid search; average precision and
/// precision-recall curves for every single measure, for averaging, for each classifier, and for
/// the RBF SVM with each measure removed (the ablation).
namespace objscan::discovery {

struct EvalConfig {
  int splits = 20;           ///< the paper's 20 random halvings
  double train_share = 0.5;  ///< the paper's half for training
  int folds = 5;             ///< cross-validation folds of the grid search
  std::uint64_t seed = 1;    ///< split s uses seed + s: same data and seed, same numbers
  bool ablation = true;      ///< also the RBF SVM without each measure in turn
  void validate() const;
};

inline constexpr int kRecallSteps = 100;

struct MethodResult {
  std::string name;  ///< a measure's name, a ScoreKind's name, or "rbf_svm without <measure>"
  double ap_mean = 0.0;
  double ap_sd = 0.0;  ///< over the splits
  /// Interpolated precision (the best precision at recall >= r) at r = i / kRecallSteps,
  /// i = 0..kRecallSteps, averaged over the splits.
  std::vector<double> precision;
};

struct EvalResult {
  std::size_t segments = 0, objects = 0;
  /// Single measures (those that vary), then average, naive_bayes, linear_svm, rbf_svm,
  /// nearest_neighbour.
  std::vector<MethodResult> methods;
  std::vector<MethodResult> ablation;  ///< the RBF SVM without each varying measure
};

/// Interpolated precision at kRecallSteps + 1 recall levels; all zero with no positive.
std::vector<double> interpolatedPrecision(const std::vector<double>& scores,
                                          const std::vector<int>& labels);

/// Runs the protocol on labelled segments (labels 1 = object, 0 = not). `on_split` (optional) is
/// called once per finished split, from any thread. Throws std::invalid_argument when a test or
/// training half could hold fewer than config.folds objects or non-objects.
EvalResult evaluate(const std::vector<ShapeMeasures>& measures, const std::vector<int>& labels,
                    const EvalConfig& config, const std::function<void()>& on_split = {});

/// Writes the curves as CSV (method, recall, precision) and the AP table as CSV (method, ap_mean,
/// ap_sd), both atomically. Throws OutputError.
void writeEvalCsv(const EvalResult& result, const std::filesystem::path& curves_csv,
                  const std::filesystem::path& ap_csv);

/// Draws the precision-recall curves of the combinations (and the best single measure) with a
/// legend of their APs, as a PNG of width x height pixels (OpenCV), written atomically.
void writePrPlot(const EvalResult& result, const std::filesystem::path& png, int width = 900,
                 int height = 700);

/// A hypothesis more than half of whose vertices are ignored by the labels is not scored.
inline constexpr double kMaxIgnoredShare = 0.5;

/// One rank of a ranked list matched against the ground truth.
struct RankMatch {
  ObjectMatch match;       ///< the object it overlaps most
  bool found = false;      ///< it finds that object: IoU >= min_iou and no better rank found it
  /// Not scored: more than kMaxIgnoredShare of it lies where the labels say nothing
  /// (GroundTruthObjects' ignore flags); it counts neither for nor against the ranking.
  bool ignored = false;
  double precision = 0.0;  ///< objects found up to this rank / ranks scored up to it
  double recall = 0.0;     ///< objects found up to this rank / objects
};

/// How one scan's ranked hypotheses find the objects of its scene (objscan scan's evaluation).
struct RankingEvaluation {
  std::size_t objects = 0;  ///< ground-truth objects with at least one vertex
  std::size_t found = 0;
  double min_iou = 0.7;
  double ap = 0.0;  ///< averagePrecisionOfRanking over the objects
  std::vector<RankMatch> ranks;
};

/// Matches ranked vertex sets (best first, indices into the scene mesh) with the objects: a rank
/// finds an object when their vertex IoU reaches `min_iou` and no better rank found it already.
/// Ranks in ignored regions are skipped (RankMatch::ignored).
RankingEvaluation evaluateRanking(const GroundTruthObjects& truth,
                                  const std::vector<std::vector<std::int32_t>>& ranked,
                                  double min_iou = 0.7);

}  // namespace objscan::discovery
