#include "objscan/discovery/scoring.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include <nlohmann/json.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "stratify.h"

namespace objscan::discovery {

namespace {

/// Version 2: JSON (version 1 was OpenCV FileStorage YAML, no longer read).
constexpr int kModelFileVersion = 2;

/// The grids searched (features are z-normalised, so the RBF width is in units of a standard
/// deviation; 1/6 is libsvm's 1/features default).
const std::vector<double> kLinearC = {0.01, 0.1, 1, 10, 100};
const std::vector<double> kRbfC = {0.1, 1, 10, 100};
const std::vector<double> kRbfGamma = {0.02, 0.08, 0.3, 1.0};
const std::vector<int> kNeighbours = {1, 3, 5, 9, 15, 25};

struct Params {
  double c = 1.0, gamma = 0.0;
  int k = 0;
};

std::vector<int> usedColumns(const MeasureMask& mask) {
  std::vector<int> cols;
  for (std::size_t i = 0; i < kMeasureCount; ++i) {
    if (mask[i]) cols.push_back(static_cast<int>(i));
  }
  return cols;
}

cv::Mat toSamples(const std::vector<MeasureRow>& rows, const std::vector<std::size_t>& which,
                  const std::vector<int>& cols) {
  cv::Mat m(static_cast<int>(which.size()), static_cast<int>(cols.size()), CV_32F);
  for (std::size_t r = 0; r < which.size(); ++r) {
    for (std::size_t c = 0; c < cols.size(); ++c) {
      m.at<float>(static_cast<int>(r), static_cast<int>(c)) =
          static_cast<float>(rows[which[r]][cols[c]]);
    }
  }
  return m;
}

/// Gaussian naive Bayes, written here because OpenCV's NormalBayesClassifier models a full
/// covariance per class (it is not naive) and exposes no posterior odds to rank by.
struct NaiveBayes {
  std::vector<double> mean[2], var[2];
  double log_prior[2] = {0, 0};

  void fit(const cv::Mat& x, const std::vector<int>& y) {
    const int d = x.cols;
    for (int c = 0; c < 2; ++c) {
      mean[c].assign(d, 0.0);
      var[c].assign(d, 0.0);
      std::size_t n = 0;
      for (int r = 0; r < x.rows; ++r) {
        if (y[r] != c) continue;
        ++n;
        for (int j = 0; j < d; ++j) mean[c][j] += x.at<float>(r, j);
      }
      for (int j = 0; j < d; ++j) mean[c][j] /= static_cast<double>(std::max<std::size_t>(n, 1));
      for (int r = 0; r < x.rows; ++r) {
        if (y[r] != c) continue;
        for (int j = 0; j < d; ++j) var[c][j] += std::pow(x.at<float>(r, j) - mean[c][j], 2.0);
      }
      // A variance floor keeps a constant column from dividing by zero.
      for (int j = 0; j < d; ++j) {
        var[c][j] = var[c][j] / static_cast<double>(std::max<std::size_t>(n, 1)) + 1e-6;
      }
      log_prior[c] = std::log((static_cast<double>(n) + 1.0) / (x.rows + 2.0));
    }
  }

  double logOdds(const float* x, int d) const {
    double s = log_prior[1] - log_prior[0];
    for (int j = 0; j < d; ++j) {
      for (int c = 0; c < 2; ++c) {
        const double ll = -0.5 * (std::log(2.0 * M_PI * var[c][j]) +
                                  std::pow(x[j] - mean[c][j], 2.0) / var[c][j]);
        s += c == 1 ? ll : -ll;
      }
    }
    return s;
  }
};

/// A two-class SVM's decision function, f(x) = sum_i alpha_i K(v_i, x) - rho, with K the dot
/// product (gamma 0) or exp(-gamma |v - x|^2). objscan trains with OpenCV's SVM and keeps these
/// numbers, read from it, in the model file: OpenCV restores an SVM only from its FileStorage
/// YAML, whose reader can hang on a damaged file (docs/fuzzing.md).
struct SvmDecision {
  cv::Mat vectors;  ///< support vectors, one CV_32F row each
  std::vector<double> alpha;
  double rho = 0.0;
  double gamma = 0.0;

  static SvmDecision of(const cv::ml::SVM& svm) {
    SvmDecision d;
    cv::Mat alpha, index;
    d.rho = svm.getDecisionFunction(0, alpha, index);
    const cv::Mat all = svm.getSupportVectors();
    d.vectors.create(index.rows * index.cols, all.cols, CV_32F);
    for (int i = 0; i < d.vectors.rows; ++i) {
      all.row(index.at<int>(i)).copyTo(d.vectors.row(i));
      d.alpha.push_back(alpha.at<double>(i));
    }
    d.gamma = svm.getKernelType() == cv::ml::SVM::RBF ? svm.getGamma() : 0.0;
    return d;
  }

  /// The decision value; `magnitude` (optional) gets |rho| + sum_i |alpha_i K_i|, the scale of
  /// the rounding error of a sum computed in float.
  double value(const float* x, double* magnitude = nullptr) const {
    double sum = -rho, size = std::abs(rho);
    for (int i = 0; i < vectors.rows; ++i) {
      const float* v = vectors.ptr<float>(i);
      double k = 0.0;
      for (int j = 0; j < vectors.cols; ++j) {
        k += gamma > 0.0 ? (v[j] - x[j]) * static_cast<double>(v[j] - x[j])
                         : static_cast<double>(v[j]) * x[j];
      }
      const double term =
          alpha[static_cast<std::size_t>(i)] * (gamma > 0.0 ? std::exp(-gamma * k) : k);
      sum += term;
      size += std::abs(term);
    }
    if (magnitude != nullptr) *magnitude = size;
    return sum;
  }
};

}  // namespace

struct ObjectnessModel::Impl {
  ScoreKind kind = ScoreKind::kAverage;
  MeasureNormaliser normaliser;
  MeasureMask mask = kAllMeasures;
  Params params;
  double cv_ap = std::numeric_limits<double>::quiet_NaN();
  double sign = 1.0;  ///< orients the SVM's decision value so that objects score higher
  SvmDecision svm;
  cv::Mat knn_samples;          ///< the training rows (CV_32F), what a model file keeps
  std::vector<int> knn_labels;  ///< 1 object, 0 not, one per row
  cv::Ptr<cv::ml::KNearest> knn;
  NaiveBayes bayes;

  void fit(const cv::Mat& x, const std::vector<int>& y);
  /// Builds OpenCV's neighbour search over knn_samples (all it does is keep them).
  void trainNeighbours();
  std::vector<double> scores(const cv::Mat& x) const;
};

void ObjectnessModel::Impl::fit(const cv::Mat& x, const std::vector<int>& y) {
  const cv::Mat responses(y, true);
  switch (kind) {
    case ScoreKind::kAverage:
      break;
    case ScoreKind::kNaiveBayes:
      bayes.fit(x, y);
      break;
    case ScoreKind::kLinearSvm:
    case ScoreKind::kRbfSvm: {
      const cv::Ptr<cv::ml::SVM> trained = cv::ml::SVM::create();
      trained->setType(cv::ml::SVM::C_SVC);
      trained->setKernel(kind == ScoreKind::kLinearSvm ? cv::ml::SVM::LINEAR : cv::ml::SVM::RBF);
      trained->setC(params.c);
      if (kind == ScoreKind::kRbfSvm) trained->setGamma(params.gamma);
      trained->setTermCriteria(
          cv::TermCriteria(cv::TermCriteria::MAX_ITER + cv::TermCriteria::EPS, 20000, 1e-5));
      trained->train(
          cv::ml::TrainData::create(x, cv::ml::ROW_SAMPLE, responses.reshape(1, x.rows)));
      svm = SvmDecision::of(*trained);
      // The decision function objscan evaluates must be OpenCV's, up to its float arithmetic.
      cv::Mat opencv_raw;
      trained->predict(x, opencv_raw, cv::ml::StatModel::RAW_OUTPUT);
      for (int r = 0; r < x.rows; ++r) {
        double magnitude = 0.0;
        const double ours = svm.value(x.ptr<float>(r), &magnitude);
        const double theirs = opencv_raw.at<float>(r);
        if (std::abs(ours - theirs) > 1e-4 * (1.0 + magnitude)) {
          throw std::logic_error("the SVM's decision function read from OpenCV gives " +
                                 std::to_string(ours) + " where OpenCV gives " +
                                 std::to_string(theirs));
        }
      }
      // OpenCV's raw output is a signed distance whose sign depends on the internal class order:
      // orient it so that the training objects lie on the positive side.
      sign = 1.0;
      const std::vector<double> raw = scores(x);
      double pos = 0, neg = 0;
      for (std::size_t i = 0; i < raw.size(); ++i) (y[i] == 1 ? pos : neg) += raw[i];
      const auto n_pos = static_cast<double>(std::count(y.begin(), y.end(), 1));
      if (pos / std::max(n_pos, 1.0) < neg / std::max(y.size() - n_pos, 1.0)) sign = -1.0;
      break;
    }
    case ScoreKind::kNearestNeighbour: {
      params.k = std::min(params.k, x.rows);  // findNearest needs k <= the sample count
      knn_samples = x.clone();
      knn_labels = y;
      trainNeighbours();
      break;
    }
  }
}

void ObjectnessModel::Impl::trainNeighbours() {
  knn = cv::ml::KNearest::create();
  knn->setIsClassifier(true);
  knn->setDefaultK(params.k);
  cv::Mat labels;
  cv::Mat(knn_labels, true).reshape(1, knn_samples.rows).convertTo(labels, CV_32F);
  knn->train(cv::ml::TrainData::create(knn_samples, cv::ml::ROW_SAMPLE, labels));
}

std::vector<double> ObjectnessModel::Impl::scores(const cv::Mat& x) const {
  std::vector<double> out(static_cast<std::size_t>(x.rows), 0.0);
  switch (kind) {
    case ScoreKind::kAverage:
      for (int r = 0; r < x.rows; ++r) {
        double s = 0.0;
        for (int j = 0; j < x.cols; ++j) s += x.at<float>(r, j);
        out[r] = x.cols > 0 ? s / x.cols : 0.0;
      }
      break;
    case ScoreKind::kNaiveBayes:
      for (int r = 0; r < x.rows; ++r) out[r] = bayes.logOdds(x.ptr<float>(r), x.cols);
      break;
    case ScoreKind::kLinearSvm:
    case ScoreKind::kRbfSvm: {
      for (int r = 0; r < x.rows; ++r) out[r] = sign * svm.value(x.ptr<float>(r));
      break;
    }
    case ScoreKind::kNearestNeighbour: {
      cv::Mat results, neighbours, distances;
      knn->findNearest(x, params.k, results, neighbours, distances);
      for (int r = 0; r < x.rows; ++r) {
        double s = 0.0;
        for (int j = 0; j < neighbours.cols; ++j) s += neighbours.at<float>(r, j);
        // The share of objects among the neighbours; the nearest distance breaks ties, so that
        // of two segments with the same share the one closer to its neighbours ranks first.
        out[r] = s / neighbours.cols - 1e-6 * distances.at<float>(r, 0);
      }
      break;
    }
  }
  return out;
}

const char* toString(ScoreKind kind) {
  switch (kind) {
    case ScoreKind::kAverage:
      return "average";
    case ScoreKind::kNaiveBayes:
      return "naive_bayes";
    case ScoreKind::kLinearSvm:
      return "linear_svm";
    case ScoreKind::kRbfSvm:
      return "rbf_svm";
    case ScoreKind::kNearestNeighbour:
      return "nearest_neighbour";
  }
  return "?";
}

ScoreKind scoreKindFromString(const std::string& name) {
  for (ScoreKind kind : kAllScoreKinds) {
    if (name == toString(kind)) return kind;
  }
  throw std::invalid_argument("unknown score kind '" + name +
                              "': use average, naive_bayes, linear_svm, rbf_svm or "
                              "nearest_neighbour");
}

void TrainConfig::validate() const {
  if (folds < 2) throw std::invalid_argument("cross-validation needs at least 2 folds");
}

MeasureNormaliser MeasureNormaliser::fit(const std::vector<ShapeMeasures>& rows) {
  MeasureNormaliser n;
  for (std::size_t k = 0; k < kMeasureCount; ++k) {
    double sum = 0.0, square = 0.0;
    std::size_t count = 0;
    for (const ShapeMeasures& m : rows) {
      const double v = orientedMeasures(m)[k];
      if (!std::isfinite(v)) continue;
      sum += v;
      square += v * v;
      ++count;
    }
    if (count == 0) continue;
    n.mean[k] = sum / static_cast<double>(count);
    const double variance = square / static_cast<double>(count) - n.mean[k] * n.mean[k];
    // A spread below rounding noise of the mean is no spread.
    n.sd[k] = variance > 1e-12 * (1.0 + n.mean[k] * n.mean[k]) ? std::sqrt(variance) : 0.0;
  }
  return n;
}

MeasureMask varyingMeasures(const MeasureNormaliser& normaliser) {
  MeasureMask mask{};
  for (std::size_t k = 0; k < kMeasureCount; ++k) mask[k] = normaliser.sd[k] > 0.0;
  return mask;
}

MeasureRow MeasureNormaliser::normalise(const ShapeMeasures& m) const {
  MeasureRow z = orientedMeasures(m);
  for (std::size_t k = 0; k < kMeasureCount; ++k) {
    z[k] = std::isfinite(z[k]) && sd[k] > 0.0 ? (z[k] - mean[k]) / sd[k] : 0.0;
  }
  return z;
}

HeldOutScenes leaveOneSceneOut(ScoreKind kind, const MeasureNormaliser& normaliser,
                               const std::vector<MeasureRow>& normalised_rows,
                               const std::vector<int>& labels,
                               const std::vector<std::size_t>& scene_of, const MeasureMask& mask,
                               const TrainConfig& config, std::size_t max_scenes) {
  if (normalised_rows.size() != labels.size() || scene_of.size() != labels.size()) {
    throw std::invalid_argument("leaveOneSceneOut: rows, labels and scenes differ in length");
  }
  std::vector<std::size_t> scenes(scene_of.begin(), scene_of.end());
  std::sort(scenes.begin(), scenes.end());
  scenes.erase(std::unique(scenes.begin(), scenes.end()), scenes.end());
  HeldOutScenes out;
  if (scenes.size() < 2 || max_scenes == 0) return out;
  // Evenly spread over the scenes, so that a long list costs at most max_scenes trainings.
  std::vector<std::size_t> chosen;
  const std::size_t n = std::min(max_scenes, scenes.size());
  for (std::size_t k = 0; k < n; ++k) chosen.push_back(scenes[k * scenes.size() / n]);
  std::vector<double> scores;
  std::vector<int> truth;
  for (const std::size_t held : chosen) {
    std::vector<MeasureRow> train_rows;
    std::vector<int> train_labels;
    std::size_t objects = 0;
    for (std::size_t i = 0; i < labels.size(); ++i) {
      if (scene_of[i] == held) continue;
      train_rows.push_back(normalised_rows[i]);
      train_labels.push_back(labels[i]);
      objects += labels[i] == 1 ? 1 : 0;
    }
    const auto folds = static_cast<std::size_t>(config.folds);
    if (objects < folds || train_labels.size() - objects < folds) {
      ++out.skipped;
      continue;
    }
    const ObjectnessModel model =
        ObjectnessModel::train(kind, normaliser, train_rows, train_labels, mask, config);
    ++out.scenes;
    for (std::size_t i = 0; i < labels.size(); ++i) {
      if (scene_of[i] != held) continue;
      const double score = model.scoreNormalised(normalised_rows[i]);
      scores.push_back(score);
      truth.push_back(labels[i]);
      out.min_score = scores.size() == 1 ? score : std::min(out.min_score, score);
      out.max_score = scores.size() == 1 ? score : std::max(out.max_score, score);
    }
  }
  out.rows = scores.size();
  if (!scores.empty()) out.ap = averagePrecision(scores, truth);
  return out;
}

double averagePrecision(const std::vector<double>& scores, const std::vector<int>& labels) {
  if (scores.size() != labels.size()) {
    throw std::invalid_argument("averagePrecision: scores and labels differ in length");
  }
  std::vector<std::size_t> order(scores.size());
  std::iota(order.begin(), order.end(), 0);
  // Ties: negatives first, so that a tie never flatters a ranking.
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (scores[a] != scores[b]) return scores[a] > scores[b];
    return labels[a] < labels[b];
  });
  std::vector<int> hits(order.size());
  for (std::size_t rank = 0; rank < order.size(); ++rank) hits[rank] = labels[order[rank]] == 1;
  const auto positives = static_cast<std::size_t>(std::count(hits.begin(), hits.end(), 1));
  return positives > 0 ? averagePrecisionOfRanking(hits, positives)
                       : std::numeric_limits<double>::quiet_NaN();
}

double averagePrecisionOfRanking(const std::vector<int>& hits, std::size_t positives) {
  double sum = 0.0;
  std::size_t found = 0;
  for (std::size_t rank = 0; rank < hits.size(); ++rank) {
    if (hits[rank] != 1) continue;
    ++found;
    sum += static_cast<double>(found) / static_cast<double>(rank + 1);
  }
  return positives > 0 ? sum / static_cast<double>(positives) : 0.0;
}

ObjectnessModel ObjectnessModel::average(const MeasureNormaliser& normaliser,
                                         const MeasureMask& mask) {
  auto impl = std::make_shared<Impl>();
  impl->normaliser = normaliser;
  impl->mask = mask;
  return ObjectnessModel(std::move(impl));
}

ObjectnessModel ObjectnessModel::train(ScoreKind kind, const MeasureNormaliser& normaliser,
                                       const std::vector<MeasureRow>& normalised_rows,
                                       const std::vector<int>& labels, const MeasureMask& mask,
                                       const TrainConfig& config) {
  config.validate();
  if (normalised_rows.size() != labels.size()) {
    throw std::invalid_argument("training rows and labels differ in length");
  }
  if (kind == ScoreKind::kAverage) return average(normaliser, mask);
  const auto positives = static_cast<int>(std::count(labels.begin(), labels.end(), 1));
  const int negatives = static_cast<int>(labels.size()) - positives;
  if (positives < config.folds || negatives < config.folds) {
    throw std::invalid_argument("training needs at least " + std::to_string(config.folds) +
                                " objects and " + std::to_string(config.folds) +
                                " non-objects; got " + std::to_string(positives) + " and " +
                                std::to_string(negatives));
  }
  const std::vector<int> cols = usedColumns(mask);
  if (cols.empty()) throw std::invalid_argument("no measure is selected");

  // Stratified folds: each class shuffled with the seed and dealt out in turn.
  std::vector<int> fold(labels.size());
  std::mt19937_64 rng(config.seed);
  for (const std::vector<std::size_t>& idx : shuffledByClass(labels, rng)) {
    for (std::size_t i = 0; i < idx.size(); ++i) fold[idx[i]] = static_cast<int>(i) % config.folds;
  }

  std::vector<Params> grid;
  switch (kind) {
    case ScoreKind::kLinearSvm:
      for (double c : kLinearC) grid.push_back({c, 0.0, 0});
      break;
    case ScoreKind::kRbfSvm:
      for (double c : kRbfC) {
        for (double g : kRbfGamma) grid.push_back({c, g, 0});
      }
      break;
    case ScoreKind::kNearestNeighbour:
      for (int k : kNeighbours) grid.push_back({0.0, 0.0, k});
      break;
    default:
      grid.push_back({});
      break;
  }

  const auto fitOn = [&](const Params& p, const std::vector<std::size_t>& which) {
    auto impl = std::make_shared<Impl>();
    impl->kind = kind;
    impl->normaliser = normaliser;
    impl->mask = mask;
    impl->params = p;
    std::vector<int> y;
    for (std::size_t i : which) y.push_back(labels[i] == 1 ? 1 : 0);
    impl->fit(toSamples(normalised_rows, which, cols), y);
    return impl;
  };

  double best_ap = -1.0;
  Params best = grid.front();
  if (grid.size() > 1) {
    for (const Params& p : grid) {
      double ap_sum = 0.0;
      for (int f = 0; f < config.folds; ++f) {
        std::vector<std::size_t> train_idx, test_idx;
        for (std::size_t i = 0; i < labels.size(); ++i) {
          (fold[i] == f ? test_idx : train_idx).push_back(i);
        }
        const auto impl = fitOn(p, train_idx);
        const std::vector<double> s = impl->scores(toSamples(normalised_rows, test_idx, cols));
        std::vector<int> y;
        for (std::size_t i : test_idx) y.push_back(labels[i] == 1 ? 1 : 0);
        ap_sum += averagePrecision(s, y);
      }
      const double ap = ap_sum / config.folds;
      if (ap > best_ap) {
        best_ap = ap;
        best = p;
      }
    }
  }
  std::vector<std::size_t> all(labels.size());
  std::iota(all.begin(), all.end(), 0);
  auto impl = fitOn(best, all);
  impl->cv_ap = grid.size() > 1 ? best_ap : std::numeric_limits<double>::quiet_NaN();
  return ObjectnessModel(std::move(impl));
}

double ObjectnessModel::scoreNormalised(const MeasureRow& z) const {
  const std::vector<int> cols = usedColumns(impl_->mask);
  if (impl_->kind == ScoreKind::kAverage) {  // in double: the common case needs no matrix
    double sum = 0.0;
    for (int c : cols) sum += z[c];
    return cols.empty() ? 0.0 : sum / static_cast<double>(cols.size());
  }
  cv::Mat x(1, static_cast<int>(cols.size()), CV_32F);
  for (std::size_t c = 0; c < cols.size(); ++c) x.at<float>(0, static_cast<int>(c)) = z[cols[c]];
  return impl_->scores(x).front();
}

ScoreKind ObjectnessModel::kind() const { return impl_->kind; }
const MeasureNormaliser& ObjectnessModel::normaliser() const { return impl_->normaliser; }
const MeasureMask& ObjectnessModel::mask() const { return impl_->mask; }
double ObjectnessModel::crossValidatedAp() const { return impl_->cv_ap; }

std::string ObjectnessModel::parameters() const {
  std::ostringstream s;
  switch (impl_->kind) {
    case ScoreKind::kLinearSvm:
      s << "C=" << impl_->params.c;
      break;
    case ScoreKind::kRbfSvm:
      s << "C=" << impl_->params.c << " gamma=" << impl_->params.gamma;
      break;
    case ScoreKind::kNearestNeighbour:
      s << "k=" << impl_->params.k;
      break;
    default:
      break;
  }
  return s.str();
}

namespace {

/// A JSON integer that fits an int (nlohmann's get<int>() converts a float or a larger integer
/// with undefined behaviour: fuzz_model found "objscan_model": 2e+92).
int wholeNumber(const nlohmann::json& j, const char* what) {
  if (!j.is_number_integer())
    throw std::invalid_argument(std::string(what) + " must be a whole number");
  const bool too_big =
      j.is_number_unsigned() && j.get<std::uint64_t>() > std::numeric_limits<int>::max();
  const auto v = too_big ? std::int64_t{0} : j.get<std::int64_t>();
  if (too_big || v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
    throw std::invalid_argument(std::string(what) + " is out of range");
  }
  return static_cast<int>(v);
}

/// Every number of a model lies within +-1e30 (a trained model's lie within a few thousand): then
/// no score a model computes can overflow to an infinity or a NaN, which ranking cannot order.
constexpr double kLargestModelNumber = 1e30;

double finiteNumber(const nlohmann::json& j, const char* what) {
  if (!j.is_number()) throw std::invalid_argument(std::string(what) + " must be a number");
  const double v = j.get<double>();
  if (!(std::abs(v) <= kLargestModelNumber)) {
    throw std::invalid_argument(std::string(what) + " is not finite or out of range");
  }
  return v;
}

/// A list of `n` numbers, one per `per`, each as finiteNumber() takes it.
std::vector<double> finiteNumbers(const nlohmann::json& j, std::size_t n, const char* what,
                                  const char* per = "measure") {
  if (!j.is_array()) throw std::invalid_argument(std::string(what) + " must be a list of numbers");
  if (j.size() != n) {
    throw std::invalid_argument(std::string(what) + " must hold " + std::to_string(n) +
                                " numbers, one per " + per);
  }
  std::vector<double> v;
  v.reserve(n);
  for (const auto& x : j) v.push_back(finiteNumber(x, what));
  return v;
}

nlohmann::json matrixToJson(const cv::Mat& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < m.rows; ++r) {
    std::vector<double> row(static_cast<std::size_t>(m.cols));
    for (int c = 0; c < m.cols; ++c) row[static_cast<std::size_t>(c)] = m.at<float>(r, c);
    rows.push_back(row);
  }
  return rows;
}

/// Reads an array of rows of `cols` finite numbers (throws std::invalid_argument naming `what`).
cv::Mat matrixFromJson(const nlohmann::json& j, int cols, const char* what) {
  if (!j.is_array() || j.empty()) {
    throw std::invalid_argument(std::string(what) + " must be a non-empty list of rows");
  }
  cv::Mat m(static_cast<int>(j.size()), cols, CV_32F);
  for (std::size_t r = 0; r < j.size(); ++r) {
    const auto row = finiteNumbers(j[r], static_cast<std::size_t>(cols), what);
    for (int c = 0; c < cols; ++c) {
      m.at<float>(static_cast<int>(r), c) = static_cast<float>(row[static_cast<std::size_t>(c)]);
    }
  }
  return m;
}

}  // namespace

void ObjectnessModel::save(const std::filesystem::path& path) const {
  const Impl& m = *impl_;
  nlohmann::json j;
  j["objscan_model"] = kModelFileVersion;
  j["kind"] = toString(m.kind);
  nlohmann::json measures = nlohmann::json::array();
  for (std::size_t k = 0; k < kMeasureCount; ++k) {
    if (m.mask[k]) measures.push_back(kMeasureNames[k]);
  }
  j["measures"] = measures;
  j["mean"] = std::vector<double>(m.normaliser.mean.begin(), m.normaliser.mean.end());
  j["sd"] = std::vector<double>(m.normaliser.sd.begin(), m.normaliser.sd.end());
  j["C"] = m.params.c;
  j["gamma"] = m.params.gamma;
  j["k"] = m.params.k;
  j["cross_validated_ap"] = std::isfinite(m.cv_ap) ? m.cv_ap : -1.0;
  j["sign"] = m.sign;
  if (m.kind == ScoreKind::kNaiveBayes) {
    j["bayes"] = {{"mean0", m.bayes.mean[0]},
                  {"mean1", m.bayes.mean[1]},
                  {"var0", m.bayes.var[0]},
                  {"var1", m.bayes.var[1]},
                  {"log_prior0", m.bayes.log_prior[0]},
                  {"log_prior1", m.bayes.log_prior[1]}};
  } else if (m.kind == ScoreKind::kLinearSvm || m.kind == ScoreKind::kRbfSvm) {
    j["svm"] = {{"gamma", m.svm.gamma},
                {"rho", m.svm.rho},
                {"alpha", m.svm.alpha},
                {"support_vectors", matrixToJson(m.svm.vectors)}};
  } else if (m.kind == ScoreKind::kNearestNeighbour) {
    j["knn"] = {{"samples", matrixToJson(m.knn_samples)}, {"labels", m.knn_labels}};
  }
  writeFileAtomically(path, j.dump(1) + "\n");
}

ObjectnessModel ObjectnessModel::load(const std::filesystem::path& path) {
  const std::string text = readWholeFile(path);
  const auto bad = [&](const std::string& problem) { return InputError(path, problem); };
  if (text.empty()) throw bad("empty file, not an objscan model");
  // Until 2026-11 models were OpenCV FileStorage YAML. OpenCV 4.6's YAML reader never returns on
  // some damaged files (fuzz_model found several), so objscan no longer reads YAML at all.
  if (text.rfind("%YAML", 0) == 0) {
    throw bad(
        "an objscan model in the old YAML form, which objscan no longer reads (OpenCV's "
        "YAML reader can hang on a damaged file): train it again with `objscan train`");
  }
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception&) {
    throw bad("not an objscan model file (not JSON)");
  }
  if (!j.is_object() || !j.contains("objscan_model")) {
    throw bad("not an objscan model file (written by `objscan train`)");
  }
  auto impl = std::make_shared<Impl>();
  try {
    const int version = wholeNumber(j.at("objscan_model"), "objscan_model (the version)");
    if (version > kModelFileVersion) {
      throw bad("model file version " + std::to_string(version) +
                " is newer than this objscan's (" + std::to_string(kModelFileVersion) + ")");
    }
    if (version < kModelFileVersion)
      throw bad("model file version " + std::to_string(version) + " is not one this objscan reads");
    impl->kind = scoreKindFromString(j.at("kind").get<std::string>());
    impl->mask = {};
    for (const auto& node : j.at("measures")) {
      const auto name = node.get<std::string>();
      const auto it = std::find(kMeasureNames.begin(), kMeasureNames.end(), name);
      if (it == kMeasureNames.end()) throw bad("unknown measure '" + name + "'");
      impl->mask[static_cast<std::size_t>(it - kMeasureNames.begin())] = true;
    }
    if (std::find(impl->mask.begin(), impl->mask.end(), true) == impl->mask.end()) {
      throw bad("the model uses no measure");
    }
    const auto mean = finiteNumbers(j.at("mean"), kMeasureCount, "the normaliser's mean");
    const auto sd = finiteNumbers(j.at("sd"), kMeasureCount, "the normaliser's deviation");
    for (std::size_t k = 0; k < kMeasureCount; ++k) {
      // Each measure is divided by its deviation: a negative one would turn the measure around,
      // a tiny one blow it up to infinity. 0 is what train writes for a measure that did not
      // vary (or was never known): it then counts as the mean.
      if (sd[k] < 0.0 || (sd[k] > 0.0 && sd[k] < 1.0 / kLargestModelNumber)) {
        char value[32];
        std::snprintf(value, sizeof value, "%g", sd[k]);
        throw bad(std::string("\"sd\": the deviation of ") + kMeasureNames[k] + " is " + value +
                  "; it is 0 (the measure does not vary) or at least 1e-30");
      }
    }
    std::copy(mean.begin(), mean.end(), impl->normaliser.mean.begin());
    std::copy(sd.begin(), sd.end(), impl->normaliser.sd.begin());
    impl->params.c = finiteNumber(j.at("C"), "C");
    impl->params.gamma = finiteNumber(j.at("gamma"), "gamma");
    impl->params.k = wholeNumber(j.at("k"), "k");
    impl->sign = finiteNumber(j.at("sign"), "sign");
    if (impl->sign != 1.0 && impl->sign != -1.0) {
      char value[32];
      std::snprintf(value, sizeof value, "%g", impl->sign);
      throw bad(std::string("\"sign\" is ") + value +
                "; it is 1 or -1 (which way the score points)");
    }
    const double cv_ap = j.value("cross_validated_ap", -1.0);
    if (cv_ap >= 0.0 && cv_ap <= 1.0) impl->cv_ap = cv_ap;
    const std::size_t used =
        static_cast<std::size_t>(std::count(impl->mask.begin(), impl->mask.end(), true));
    switch (impl->kind) {
      case ScoreKind::kAverage:
        break;
      case ScoreKind::kNaiveBayes: {
        const auto& b = j.at("bayes");
        NaiveBayes& nb = impl->bayes;
        nb.mean[0] = finiteNumbers(b.at("mean0"), used, "naive_bayes mean0");
        nb.mean[1] = finiteNumbers(b.at("mean1"), used, "naive_bayes mean1");
        nb.var[0] = finiteNumbers(b.at("var0"), used, "naive_bayes var0");
        nb.var[1] = finiteNumbers(b.at("var1"), used, "naive_bayes var1");
        for (int c = 0; c < 2; ++c) {
          for (const double v : nb.var[c]) {
            if (!(v >= 1.0 / kLargestModelNumber)) {
              throw bad("naive_bayes variances must be positive (1e-30 at least)");
            }
          }
        }
        nb.log_prior[0] = finiteNumber(b.at("log_prior0"), "naive_bayes log_prior0");
        nb.log_prior[1] = finiteNumber(b.at("log_prior1"), "naive_bayes log_prior1");
        break;
      }
      case ScoreKind::kLinearSvm:
      case ScoreKind::kRbfSvm: {
        if (!j.contains("svm")) throw bad("an SVM model without its support vectors");
        const auto& s = j.at("svm");
        SvmDecision& d = impl->svm;
        d.vectors = matrixFromJson(s.at("support_vectors"), static_cast<int>(used),
                                   "the SVM's support_vectors");
        d.alpha = finiteNumbers(s.at("alpha"), static_cast<std::size_t>(d.vectors.rows),
                                "the SVM's alpha", "support vector");
        d.rho = finiteNumber(s.at("rho"), "the SVM's rho");
        d.gamma = impl->kind == ScoreKind::kRbfSvm ? finiteNumber(s.at("gamma"), "gamma") : 0.0;
        if (d.gamma < 0.0) throw bad("the SVM's gamma is negative");
        break;
      }
      case ScoreKind::kNearestNeighbour: {
        if (!j.contains("knn")) throw bad("a nearest_neighbour model without samples");
        const auto& n = j.at("knn");
        impl->knn_samples = matrixFromJson(n.at("samples"), static_cast<int>(used),
                                           "the nearest_neighbour samples");
        const auto& labels = n.at("labels");
        if (!labels.is_array() ||
            labels.size() != static_cast<std::size_t>(impl->knn_samples.rows)) {
          throw bad("the nearest_neighbour labels must be one per sample");
        }
        for (const auto& label : labels) {
          impl->knn_labels.push_back(wholeNumber(label, "a nearest_neighbour label"));
          if (impl->knn_labels.back() != 0 && impl->knn_labels.back() != 1) {
            throw bad("nearest_neighbour labels are 0 or 1");
          }
        }
        if (impl->params.k < 1 || impl->params.k > impl->knn_samples.rows) {
          throw bad("k must be between 1 and the number of samples");
        }
        impl->trainNeighbours();
        break;
      }
    }
  } catch (const nlohmann::json::exception& e) {
    // A key missing or of the wrong type: name it (e.what() ends with the key's own words).
    throw bad(std::string("not a readable model file (") + e.what() + ")");
  } catch (const cv::Exception& e) {
    throw bad(std::string("not a readable model file (") + e.err + ")");
  } catch (const std::invalid_argument& e) {
    throw bad(e.what());
  }
  return ObjectnessModel(std::move(impl));
}

}  // namespace objscan::discovery
