#include "objscan/discovery/scoring.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "stratify.h"

namespace objscan::discovery {

namespace {

constexpr int kModelFileVersion = 1;

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

}  // namespace

struct ObjectnessModel::Impl {
  ScoreKind kind = ScoreKind::kAverage;
  MeasureNormaliser normaliser;
  MeasureMask mask = kAllMeasures;
  Params params;
  double cv_ap = std::numeric_limits<double>::quiet_NaN();
  double sign = 1.0;  ///< orients the SVM's decision value so that objects score higher
  cv::Ptr<cv::ml::SVM> svm;
  cv::Ptr<cv::ml::KNearest> knn;
  NaiveBayes bayes;

  void fit(const cv::Mat& x, const std::vector<int>& y);
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
      svm = cv::ml::SVM::create();
      svm->setType(cv::ml::SVM::C_SVC);
      svm->setKernel(kind == ScoreKind::kLinearSvm ? cv::ml::SVM::LINEAR : cv::ml::SVM::RBF);
      svm->setC(params.c);
      if (kind == ScoreKind::kRbfSvm) svm->setGamma(params.gamma);
      svm->setTermCriteria(
          cv::TermCriteria(cv::TermCriteria::MAX_ITER + cv::TermCriteria::EPS, 20000, 1e-5));
      svm->train(cv::ml::TrainData::create(x, cv::ml::ROW_SAMPLE, responses.reshape(1, x.rows)));
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
      knn = cv::ml::KNearest::create();
      knn->setIsClassifier(true);
      params.k = std::min(params.k, x.rows);  // findNearest needs k <= the sample count
      knn->setDefaultK(params.k);
      cv::Mat labels;
      responses.reshape(1, x.rows).convertTo(labels, CV_32F);
      knn->train(cv::ml::TrainData::create(x, cv::ml::ROW_SAMPLE, labels));
      break;
    }
  }
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
      cv::Mat raw;
      svm->predict(x, raw, cv::ml::StatModel::RAW_OUTPUT);
      for (int r = 0; r < x.rows; ++r) out[r] = sign * raw.at<float>(r);
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

void ObjectnessModel::save(const std::filesystem::path& path) const {
  cv::FileStorage fs(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  const Impl& m = *impl_;
  fs << "objscan_model" << kModelFileVersion;
  fs << "kind" << toString(m.kind);
  fs << "measures"
     << "[";
  for (std::size_t k = 0; k < kMeasureCount; ++k) {
    if (m.mask[k]) fs << kMeasureNames[k];
  }
  fs << "]";
  fs << "mean" << std::vector<double>(m.normaliser.mean.begin(), m.normaliser.mean.end());
  fs << "sd" << std::vector<double>(m.normaliser.sd.begin(), m.normaliser.sd.end());
  fs << "C" << m.params.c << "gamma" << m.params.gamma << "k" << m.params.k;
  fs << "cross_validated_ap" << (std::isfinite(m.cv_ap) ? m.cv_ap : -1.0);
  fs << "sign" << m.sign;
  if (m.kind == ScoreKind::kNaiveBayes) {
    fs << "bayes"
       << "{";
    fs << "mean0" << m.bayes.mean[0] << "mean1" << m.bayes.mean[1];
    fs << "var0" << m.bayes.var[0] << "var1" << m.bayes.var[1];
    fs << "log_prior0" << m.bayes.log_prior[0] << "log_prior1" << m.bayes.log_prior[1];
    fs << "}";
  } else if (m.svm) {
    fs << "opencv_svm"
       << "{";
    m.svm->write(fs);
    fs << "}";
  } else if (m.knn) {
    fs << "opencv_knearest"
       << "{";
    m.knn->write(fs);
    fs << "}";
  }
  writeFileAtomically(path, fs.releaseAndGetString());
}

ObjectnessModel ObjectnessModel::load(const std::filesystem::path& path) {
  const std::string text = readWholeFile(path);
  const auto bad = [&](const std::string& problem) { return InputError(path, problem); };
  if (text.empty()) throw bad("empty file, not an objscan model");
  // OpenCV 4.6's FileStorage reader never returns on some malformed YAML (found by fuzz_model:
  // "%YAML:1.\n----s\n-  -\n " loops forever). A model file is what save() writes: YAML 1.0
  // with its document marker alone on the second line, text without control bytes. Anything else
  // is refused before OpenCV sees it.
  constexpr std::string_view kStart = "%YAML:1.0\n---\n";
  if (text.compare(0, kStart.size(), kStart) != 0) {
    throw bad("not an objscan model file (it starts \"%YAML:1.0\" and \"---\", as `objscan train` "
              "writes it)");
  }
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if ((u < 0x20 && c != '\n' && c != '\r' && c != '\t') || u == 0x7f) {
      throw bad("not an objscan model file (it holds control bytes: not text)");
    }
  }
  auto impl = std::make_shared<Impl>();
  try {
    cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
    if (!fs.isOpened() || fs["objscan_model"].empty()) {
      throw bad("not an objscan model file (written by `objscan train`)");
    }
    const int version = static_cast<int>(fs["objscan_model"]);
    if (version > kModelFileVersion) {
      throw bad("model file version " + std::to_string(version) +
                " is newer than this objscan's (" + std::to_string(kModelFileVersion) + ")");
    }
    impl->kind = scoreKindFromString(static_cast<std::string>(fs["kind"]));
    impl->mask = {};
    for (const auto& node : fs["measures"]) {
      const std::string name = static_cast<std::string>(node);
      const auto it = std::find(kMeasureNames.begin(), kMeasureNames.end(), name);
      if (it == kMeasureNames.end()) throw bad("unknown measure '" + name + "'");
      impl->mask[static_cast<std::size_t>(it - kMeasureNames.begin())] = true;
    }
    if (std::find(impl->mask.begin(), impl->mask.end(), true) == impl->mask.end()) {
      throw bad("the model uses no measure");
    }
    std::vector<double> mean, sd;
    fs["mean"] >> mean;
    fs["sd"] >> sd;
    if (mean.size() != kMeasureCount || sd.size() != kMeasureCount) {
      throw bad("the normaliser needs " + std::to_string(kMeasureCount) + " means and deviations");
    }
    std::copy(mean.begin(), mean.end(), impl->normaliser.mean.begin());
    std::copy(sd.begin(), sd.end(), impl->normaliser.sd.begin());
    fs["C"] >> impl->params.c;
    fs["gamma"] >> impl->params.gamma;
    fs["k"] >> impl->params.k;
    fs["sign"] >> impl->sign;
    double cv_ap = -1.0;
    fs["cross_validated_ap"] >> cv_ap;
    if (cv_ap >= 0.0) impl->cv_ap = cv_ap;
    const std::size_t used =
        static_cast<std::size_t>(std::count(impl->mask.begin(), impl->mask.end(), true));
    switch (impl->kind) {
      case ScoreKind::kAverage:
        break;
      case ScoreKind::kNaiveBayes: {
        const cv::FileNode b = fs["bayes"];
        if (b.empty()) throw bad("a naive_bayes model without its parameters");
        b["mean0"] >> impl->bayes.mean[0];
        b["mean1"] >> impl->bayes.mean[1];
        b["var0"] >> impl->bayes.var[0];
        b["var1"] >> impl->bayes.var[1];
        b["log_prior0"] >> impl->bayes.log_prior[0];
        b["log_prior1"] >> impl->bayes.log_prior[1];
        for (int c = 0; c < 2; ++c) {
          if (impl->bayes.mean[c].size() != used || impl->bayes.var[c].size() != used) {
            throw bad("naive_bayes parameters do not match its measures");
          }
        }
        break;
      }
      case ScoreKind::kLinearSvm:
      case ScoreKind::kRbfSvm:
        if (fs["opencv_svm"].empty()) throw bad("an SVM model without its support vectors");
        impl->svm = cv::ml::SVM::create();
        impl->svm->read(fs["opencv_svm"]);
        if (!impl->svm->isTrained() || impl->svm->getVarCount() != static_cast<int>(used)) {
          throw bad("the SVM does not match its measures");
        }
        break;
      case ScoreKind::kNearestNeighbour:
        if (fs["opencv_knearest"].empty()) throw bad("a nearest_neighbour model without samples");
        impl->knn = cv::ml::KNearest::create();
        impl->knn->read(fs["opencv_knearest"]);
        if (!impl->knn->isTrained() || impl->knn->getVarCount() != static_cast<int>(used)) {
          throw bad("the nearest-neighbour samples do not match its measures");
        }
        break;
    }
  } catch (const cv::Exception& e) {
    throw bad(std::string("not a readable model file (") + e.err + ")");
  } catch (const std::invalid_argument& e) {
    throw bad(e.what());
  }
  return ObjectnessModel(std::move(impl));
}

}  // namespace objscan::discovery
