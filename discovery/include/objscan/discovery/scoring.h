#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "objscan/discovery/shape_measures.h"

/// Objectness scores from the six measures (section IV-C): the unsupervised average of the
/// z-normalised measures, or a classifier trained on labelled segments.
namespace objscan::discovery {

using MeasureRow = std::array<double, kMeasureCount>;
/// Which measures take part (all of them, or all but one for the ablation).
using MeasureMask = std::array<bool, kMeasureCount>;
inline constexpr MeasureMask kAllMeasures = {true, true, true, true, true, true};

/// Per-measure mean and standard deviation of the oriented measures (orientedMeasures()), so
/// that each becomes zero mean and unit variance, higher meaning more object-like.
struct MeasureNormaliser {
  MeasureRow mean{};
  MeasureRow sd{};  ///< 0 for a measure that does not vary (or is never known): it then counts 0

  /// Fits over `rows`; a NaN value (recurrence with no other scene) is left out of its column.
  static MeasureNormaliser fit(const std::vector<ShapeMeasures>& rows);
  /// The z-normalised oriented row. A NaN measure, or one whose sd is 0, becomes 0: the mean,
  /// saying nothing either way.
  MeasureRow normalise(const ShapeMeasures& m) const;
};

/// The measures whose spread is not 0: those that tell segments apart.
MeasureMask varyingMeasures(const MeasureNormaliser& normaliser);

enum class ScoreKind {
  kAverage,           ///< mean of the normalised measures; unsupervised, the default
  kNaiveBayes,        ///< Gaussian naive Bayes: log posterior odds
  kLinearSvm,         ///< OpenCV ml SVM, linear kernel: decision value
  kRbfSvm,            ///< OpenCV ml SVM, RBF kernel: decision value
  kNearestNeighbour,  ///< OpenCV ml KNearest: share of object labels among the k nearest
};
inline constexpr std::array<ScoreKind, 5> kAllScoreKinds = {
    ScoreKind::kAverage, ScoreKind::kNaiveBayes, ScoreKind::kLinearSvm, ScoreKind::kRbfSvm,
    ScoreKind::kNearestNeighbour};
/// "average", "naive_bayes", "linear_svm", "rbf_svm", "nearest_neighbour".
const char* toString(ScoreKind kind);
/// Throws std::invalid_argument listing the names for any other.
ScoreKind scoreKindFromString(const std::string& name);

struct TrainConfig {
  int folds = 5;           ///< the paper's 5-fold cross-validation for the grid search
  std::uint64_t seed = 1;  ///< folds are drawn with it: same data and seed, same model
  void validate() const;
};

/// A way to score segments: a normaliser, the measures that take part, and for a supervised kind
/// the trained model. Immutable once made; copies share the model; scoring is thread-safe.
class ObjectnessModel {
 public:
  /// The unsupervised average (no training).
  static ObjectnessModel average(const MeasureNormaliser& normaliser,
                                 const MeasureMask& mask = kAllMeasures);

  /// Fits `kind` to rows already normalised by `normaliser` (labels 1 = object, 0 = not),
  /// choosing its parameters by grid search scored with the mean average precision over
  /// config.folds stratified folds. Throws std::invalid_argument when the rows and labels differ
  /// in length, or either class has fewer than config.folds rows.
  static ObjectnessModel train(ScoreKind kind, const MeasureNormaliser& normaliser,
                               const std::vector<MeasureRow>& normalised_rows,
                               const std::vector<int>& labels,
                               const MeasureMask& mask = kAllMeasures,
                               const TrainConfig& config = {});

  /// Higher is more object-like. Scores of one model are comparable with each other only.
  double score(const ShapeMeasures& m) const { return scoreNormalised(normaliser().normalise(m)); }
  double scoreNormalised(const MeasureRow& z) const;

  ScoreKind kind() const;
  const MeasureNormaliser& normaliser() const;
  const MeasureMask& mask() const;
  /// The chosen parameters, e.g. "C=10 gamma=0.2"; "" for the average.
  std::string parameters() const;
  /// The grid search's best mean cross-validated AP; NaN for the average.
  double crossValidatedAp() const;

  /// Writes a JSON file (atomically; docs/file_formats.md). Throws OutputError.
  void save(const std::filesystem::path& path) const;
  /// Throws InputError naming the file when it is missing, not JSON, not an objscan model (or one
  /// in the YAML form objscan wrote before model file version 2), from a newer objscan, or holds
  /// parameters that do not fit its kind and measures.
  static ObjectnessModel load(const std::filesystem::path& path);

  struct Impl;

 private:
  explicit ObjectnessModel(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}
  std::shared_ptr<const Impl> impl_;
};

/// What a trained kind does on scenes it has not seen (leaveOneSceneOut).
struct HeldOutScenes {
  std::size_t scenes = 0;   ///< scenes held out in turn and scored
  std::size_t skipped = 0;  ///< scenes not held out: the others had too few of a class to train
  std::size_t rows = 0;     ///< segments scored by a model trained without their scene
  /// averagePrecision of those scores, all held-out scenes ranked together; NaN without rows or
  /// without an object among them.
  double ap = std::numeric_limits<double>::quiet_NaN();
  double min_score = std::numeric_limits<double>::quiet_NaN();  ///< the held-out scores' spread
  double max_score = std::numeric_limits<double>::quiet_NaN();
};

/// Leave-one-scene-out: for each of at most `max_scenes` scenes (spread evenly over them, in
/// order), trains `kind` as ObjectnessModel::train does (its grid search included) on the rows
/// of the other scenes and scores the scene's own rows. `scene_of` gives each row's scene
/// (any ids). A scene whose removal leaves fewer than config.folds of a class is skipped. The
/// cross-validated AP of train() draws its folds from the same scenes it trains on; this says
/// what the model does on a scene it has never seen, as it is used.
HeldOutScenes leaveOneSceneOut(ScoreKind kind, const MeasureNormaliser& normaliser,
                               const std::vector<MeasureRow>& normalised_rows,
                               const std::vector<int>& labels,
                               const std::vector<std::size_t>& scene_of,
                               const MeasureMask& mask = kAllMeasures,
                               const TrainConfig& config = {}, std::size_t max_scenes = 10);

/// Average precision of `scores` against `labels` (1 = positive): the mean, over the positives,
/// of the precision at each one's rank. Ties are broken against the positives, so a tie never
/// flatters a ranking. NaN when there is no positive.
double averagePrecision(const std::vector<double>& scores, const std::vector<int>& labels);

/// Average precision of a ranked list, the one definition behind every AP objscan reports: the
/// mean, over `positives` objects, of the precision (hits so far / rank) at the rank of each hit,
/// where hits[k] is 1 when rank k + 1 found an object; objects never found count 0. 0 when
/// `positives` is 0.
double averagePrecisionOfRanking(const std::vector<int>& hits, std::size_t positives);

}  // namespace objscan::discovery
