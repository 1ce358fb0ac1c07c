#include "objscan/discovery/evaluation.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

#include <tbb/parallel_for.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/image_codec.h"
#include "stratify.h"

namespace objscan::discovery {

namespace {

/// One method's outcome on one split.
struct SplitOutcome {
  double ap = 0.0;
  std::vector<double> precision;
};

SplitOutcome outcome(const std::vector<double>& scores, const std::vector<int>& labels) {
  return {averagePrecision(scores, labels), interpolatedPrecision(scores, labels)};
}

MethodResult summarise(const std::string& name, const std::vector<SplitOutcome>& splits) {
  MethodResult r;
  r.name = name;
  r.precision.assign(kRecallSteps + 1, 0.0);
  for (const SplitOutcome& s : splits) {
    r.ap_mean += s.ap;
    for (int i = 0; i <= kRecallSteps; ++i) r.precision[i] += s.precision[i];
  }
  const auto n = static_cast<double>(splits.size());
  r.ap_mean /= n;
  for (double& p : r.precision) p /= n;
  for (const SplitOutcome& s : splits) r.ap_sd += std::pow(s.ap - r.ap_mean, 2.0);
  r.ap_sd = std::sqrt(r.ap_sd / n);
  return r;
}

std::string csvNumber(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

}  // namespace

void EvalConfig::validate() const {
  if (splits < 1) throw std::invalid_argument("evaluation needs at least one split");
  if (!(train_share > 0.0 && train_share < 1.0)) {
    throw std::invalid_argument("the training share must lie strictly between 0 and 1");
  }
  if (folds < 2) throw std::invalid_argument("cross-validation needs at least 2 folds");
}

std::vector<double> interpolatedPrecision(const std::vector<double>& scores,
                                          const std::vector<int>& labels) {
  std::vector<double> out(kRecallSteps + 1, 0.0);
  const auto positives = static_cast<std::size_t>(std::count(labels.begin(), labels.end(), 1));
  if (positives == 0) return out;
  std::vector<std::size_t> order(scores.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (scores[a] != scores[b]) return scores[a] > scores[b];
    return labels[a] < labels[b];
  });
  // Precision and recall after each rank; then the best precision at any recall >= r.
  std::vector<std::pair<double, double>> points;  // (recall, precision)
  std::size_t hits = 0;
  for (std::size_t rank = 0; rank < order.size(); ++rank) {
    if (labels[order[rank]] == 1) ++hits;
    points.emplace_back(static_cast<double>(hits) / static_cast<double>(positives),
                        static_cast<double>(hits) / static_cast<double>(rank + 1));
  }
  double best = 0.0;
  std::size_t p = points.size();
  for (int i = kRecallSteps; i >= 0; --i) {
    const double r = static_cast<double>(i) / kRecallSteps;
    while (p > 0 && points[p - 1].first >= r - 1e-12) best = std::max(best, points[--p].second);
    out[i] = best;
  }
  return out;
}

EvalResult evaluate(const std::vector<ShapeMeasures>& measures, const std::vector<int>& labels,
                    const EvalConfig& config, const std::function<void()>& on_split) {
  config.validate();
  if (measures.size() != labels.size()) {
    throw std::invalid_argument("evaluate: measures and labels differ in length");
  }
  EvalResult result;
  result.segments = measures.size();
  result.objects = static_cast<std::size_t>(std::count(labels.begin(), labels.end(), 1));
  const std::size_t negatives = result.segments - result.objects;
  const double least = std::min(config.train_share, 1.0 - config.train_share);
  if (std::floor(least * static_cast<double>(std::min(result.objects, negatives))) < config.folds) {
    throw std::invalid_argument(
        "too few labelled segments to evaluate: " + std::to_string(result.objects) +
        " objects and " + std::to_string(negatives) + " non-objects; each half needs at least " +
        std::to_string(config.folds) + " of each");
  }

  // The paper normalises each measure over the whole data set before splitting.
  const MeasureNormaliser normaliser = MeasureNormaliser::fit(measures);
  std::vector<MeasureRow> rows;
  rows.reserve(measures.size());
  for (const ShapeMeasures& m : measures) rows.push_back(normaliser.normalise(m));
  const MeasureMask varying = varyingMeasures(normaliser);

  // The methods, in the order of the result.
  std::vector<std::string> names;
  std::vector<std::size_t> single;
  for (std::size_t k = 0; k < kMeasureCount; ++k) {
    if (!varying[k]) continue;
    single.push_back(k);
    names.emplace_back(kMeasureNames[k]);
  }
  for (ScoreKind kind : kAllScoreKinds) names.emplace_back(toString(kind));
  std::vector<std::size_t> ablated;
  if (config.ablation) {
    for (std::size_t k : single) {
      if (single.size() < 2) break;
      ablated.push_back(k);
      names.push_back(std::string("rbf_svm without ") + kMeasureNames[k]);
    }
  }

  std::vector<std::vector<SplitOutcome>> per_method(
      names.size(), std::vector<SplitOutcome>(static_cast<std::size_t>(config.splits)));
  tbb::parallel_for(0, config.splits, [&](int s) {
    // A stratified random halving: each class shuffled and cut at the training share.
    std::mt19937_64 rng(config.seed + static_cast<std::uint64_t>(s));
    std::vector<std::size_t> train, test;
    for (const std::vector<std::size_t>& idx : shuffledByClass(labels, rng)) {
      const auto cut = static_cast<std::size_t>(std::llround(config.train_share * idx.size()));
      train.insert(train.end(), idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(cut));
      test.insert(test.end(), idx.begin() + static_cast<std::ptrdiff_t>(cut), idx.end());
    }
    std::vector<MeasureRow> train_rows, test_rows;
    std::vector<int> train_labels, test_labels;
    for (std::size_t i : train) {
      train_rows.push_back(rows[i]);
      train_labels.push_back(labels[i] == 1 ? 1 : 0);
    }
    for (std::size_t i : test) {
      test_rows.push_back(rows[i]);
      test_labels.push_back(labels[i] == 1 ? 1 : 0);
    }
    const auto scoreWith = [&](const ObjectnessModel& model) {
      std::vector<double> scores;
      scores.reserve(test_rows.size());
      for (const MeasureRow& z : test_rows) scores.push_back(model.scoreNormalised(z));
      return scores;
    };
    const TrainConfig train_config{config.folds, config.seed + static_cast<std::uint64_t>(s)};
    std::size_t m = 0;
    for (std::size_t k : single) {
      std::vector<double> scores;
      for (const MeasureRow& z : test_rows) scores.push_back(z[k]);
      per_method[m++][s] = outcome(scores, test_labels);
    }
    for (ScoreKind kind : kAllScoreKinds) {
      const ObjectnessModel model =
          ObjectnessModel::train(kind, normaliser, train_rows, train_labels, varying, train_config);
      per_method[m++][s] = outcome(scoreWith(model), test_labels);
    }
    for (std::size_t k : ablated) {
      MeasureMask mask = varying;
      mask[k] = false;
      const ObjectnessModel model = ObjectnessModel::train(
          ScoreKind::kRbfSvm, normaliser, train_rows, train_labels, mask, train_config);
      per_method[m++][s] = outcome(scoreWith(model), test_labels);
    }
    if (on_split) on_split();
  });

  const std::size_t first_ablation = names.size() - ablated.size();
  for (std::size_t m = 0; m < names.size(); ++m) {
    (m < first_ablation ? result.methods : result.ablation)
        .push_back(summarise(names[m], per_method[m]));
  }
  return result;
}

void writeEvalCsv(const EvalResult& result, const std::filesystem::path& curves_csv,
                  const std::filesystem::path& ap_csv) {
  std::ostringstream ap, curves;
  ap << "method,ap_mean,ap_sd\n";
  curves << "method,recall,precision\n";
  for (const auto* list : {&result.methods, &result.ablation}) {
    for (const MethodResult& r : *list) {
      ap << r.name << ',' << csvNumber(r.ap_mean) << ',' << csvNumber(r.ap_sd) << '\n';
      for (int i = 0; i <= kRecallSteps; ++i) {
        curves << r.name << ',' << csvNumber(static_cast<double>(i) / kRecallSteps) << ','
               << csvNumber(r.precision[i]) << '\n';
      }
    }
  }
  writeFileAtomically(ap_csv, ap.str());
  writeFileAtomically(curves_csv, curves.str());
}

void writePrPlot(const EvalResult& result, const std::filesystem::path& png, int width,
                 int height) {
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 70, right = 300, top = 40, bottom = 60;
  const int w = width - left - right, h = height - top - bottom;
  const auto at = [&](double recall, double precision) {
    return cv::Point(left + static_cast<int>(std::lround(recall * w)),
                     top + static_cast<int>(std::lround((1.0 - precision) * h)));
  };
  const cv::Scalar grey(210, 210, 210), black(0, 0, 0);
  for (int i = 0; i <= 10; ++i) {
    const double v = i / 10.0;
    cv::line(img, at(v, 0), at(v, 1), grey, 1);
    cv::line(img, at(0, v), at(1, v), grey, 1);
    std::ostringstream label;
    label << std::fixed << std::setprecision(1) << v;
    cv::putText(img, label.str(), at(v, 0) + cv::Point(-10, 20), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                black, 1, cv::LINE_AA);
    cv::putText(img, label.str(), at(0, v) + cv::Point(-35, 5), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                black, 1, cv::LINE_AA);
  }
  cv::rectangle(img, at(0, 1), at(1, 0), black, 1);
  cv::putText(img, "recall", cv::Point(left + w / 2 - 20, height - 15), cv::FONT_HERSHEY_SIMPLEX,
              0.6, black, 1, cv::LINE_AA);
  cv::putText(img, "precision", cv::Point(5, top - 15), cv::FONT_HERSHEY_SIMPLEX, 0.6, black, 1,
              cv::LINE_AA);

  // The combinations, and the best single measure dashed.
  std::vector<const MethodResult*> drawn;
  const MethodResult* best_single = nullptr;
  for (const MethodResult& r : result.methods) {
    bool combination = false;
    for (ScoreKind kind : kAllScoreKinds) combination |= r.name == toString(kind);
    if (combination) {
      drawn.push_back(&r);
    } else if (!best_single || r.ap_mean > best_single->ap_mean) {
      best_single = &r;
    }
  }
  if (best_single) drawn.push_back(best_single);
  // Distinct colours (BGR) that stay apart for colour-blind readers (Okabe-Ito).
  const cv::Scalar colours[] = {{0, 159, 230}, {178, 114, 0},   {0, 94, 213},
                                {115, 158, 0}, {167, 121, 204}, {66, 228, 240}};
  for (std::size_t d = 0; d < drawn.size(); ++d) {
    const MethodResult& r = *drawn[d];
    const cv::Scalar colour = colours[d % 6];
    const bool dashed = &r == best_single;
    for (int i = 0; i < kRecallSteps; ++i) {
      if (dashed && i % 4 >= 2) continue;
      cv::line(img, at(static_cast<double>(i) / kRecallSteps, r.precision[i]),
               at(static_cast<double>(i + 1) / kRecallSteps, r.precision[i + 1]), colour, 2,
               cv::LINE_AA);
    }
    std::ostringstream legend;
    legend << r.name << "  AP " << std::fixed << std::setprecision(3) << r.ap_mean;
    const cv::Point p(left + w + 20, top + 20 + 26 * static_cast<int>(d));
    cv::line(img, p + cv::Point(0, -4), p + cv::Point(30, -4), colour, 3, cv::LINE_AA);
    cv::putText(img, legend.str(), p + cv::Point(38, 0), cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1,
                cv::LINE_AA);
  }
  writeFileAtomically(png, encodePng(img));
}

RankingEvaluation evaluateRanking(const GroundTruthObjects& truth,
                                  const std::vector<std::vector<std::int32_t>>& ranked,
                                  double min_iou) {
  RankingEvaluation e;
  e.min_iou = min_iou;
  e.objects = truth.objectIds().size();
  std::set<std::int32_t> found;
  std::vector<int> hits;
  std::size_t scored = 0;
  for (std::size_t k = 0; k < ranked.size(); ++k) {
    RankMatch r;
    r.match = truth.bestMatch(ranked[k]);
    r.ignored = truth.ignoredShare(ranked[k]) > kMaxIgnoredShare;
    r.found = !r.ignored && isObject(r.match, min_iou) && found.insert(r.match.object_id).second;
    if (!r.ignored) {
      ++scored;
      hits.push_back(r.found);
    }
    r.precision = scored ? static_cast<double>(found.size()) / static_cast<double>(scored) : 0.0;
    r.recall = e.objects ? static_cast<double>(found.size()) / static_cast<double>(e.objects) : 0.0;
    e.ranks.push_back(r);
  }
  e.found = found.size();
  e.ap = averagePrecisionOfRanking(hits, e.objects);
  return e;
}

}  // namespace objscan::discovery
