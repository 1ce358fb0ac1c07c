// The evaluation protocol: curves, the split-and-train loop, and its files.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/discovery/evaluation.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

TEST(InterpolatedPrecision, BestPrecisionAtOrAboveEachRecall) {
  // Ranks: object, clutter, object, clutter. Recall 0.5 at precision 1, recall 1 at 2/3.
  const std::vector<double> p = interpolatedPrecision({4, 3, 2, 1}, {1, 0, 1, 0});
  ASSERT_EQ(p.size(), static_cast<std::size_t>(kRecallSteps + 1));
  EXPECT_DOUBLE_EQ(p[0], 1.0);
  EXPECT_DOUBLE_EQ(p[kRecallSteps / 2], 1.0);
  EXPECT_DOUBLE_EQ(p[kRecallSteps / 2 + 1], 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(p[kRecallSteps], 2.0 / 3.0);
}

/// Segments whose compactness tells objects (a third of them) from clutter with some overlap,
/// whose smoothness is pure noise, and whose other measures are constant.
void segments(std::uint32_t seed, int n, std::vector<ShapeMeasures>& m, std::vector<int>& y) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < n; ++i) {
    const int label = i % 3 == 0 ? 1 : 0;
    ShapeMeasures s;
    s.compactness = 0.3 + 0.1 * label + 0.03 * g(rng);
    s.smoothness = 0.5 + 0.1 * g(rng);
    m.push_back(s);
    y.push_back(label);
  }
}

TEST(Evaluate, InformativeMeasureScoresHighNoiseScoresTheBaseRate) {
  std::vector<ShapeMeasures> m;
  std::vector<int> y;
  segments(1, 240, m, y);
  EvalConfig config;
  config.splits = 4;
  int splits_done = 0;
  const EvalResult r = evaluate(m, y, config, [&] { ++splits_done; });
  EXPECT_EQ(splits_done, 4);
  EXPECT_EQ(r.segments, 240u);
  EXPECT_EQ(r.objects, 80u);
  // Only the two varying measures are single methods, then the five combinations.
  std::vector<std::string> names;
  for (const MethodResult& x : r.methods) names.push_back(x.name);
  EXPECT_EQ(names, (std::vector<std::string>{"compactness", "smoothness", "average", "naive_bayes",
                                             "linear_svm", "rbf_svm", "nearest_neighbour"}));
  const auto ap = [&](const std::string& name) {
    for (const auto* list : {&r.methods, &r.ablation}) {
      for (const MethodResult& x : *list) {
        if (x.name == name) return x.ap_mean;
      }
    }
    ADD_FAILURE() << name;
    return 0.0;
  };
  // Classes 3.3 sd apart on compactness: AP near 1 (0.9 allows the noise).
  EXPECT_GE(ap("compactness"), 0.9);
  EXPECT_GE(ap("rbf_svm"), 0.9);
  EXPECT_GE(ap("linear_svm"), 0.9);
  // Smoothness is noise: about the base rate 1/3 (0.2 allows for 120 test segments).
  EXPECT_NEAR(ap("smoothness"), 1.0 / 3.0, 0.2);
  // Averaging with a noise measure still ranks better than the noise alone.
  EXPECT_GT(ap("average"), ap("smoothness") + 0.2);
  // Ablation: without compactness the RBF SVM is left with noise.
  ASSERT_EQ(r.ablation.size(), 2u);
  EXPECT_NEAR(ap("rbf_svm without compactness"), 1.0 / 3.0, 0.2);
  EXPECT_GE(ap("rbf_svm without smoothness"), 0.9);
}

TEST(Evaluate, SameSeedSameNumbers) {
  std::vector<ShapeMeasures> m;
  std::vector<int> y;
  segments(2, 150, m, y);
  EvalConfig config;
  config.splits = 2;
  config.ablation = false;
  const EvalResult a = evaluate(m, y, config), b = evaluate(m, y, config);
  ASSERT_EQ(a.methods.size(), b.methods.size());
  for (std::size_t i = 0; i < a.methods.size(); ++i) {
    EXPECT_EQ(a.methods[i].ap_mean, b.methods[i].ap_mean) << a.methods[i].name;
  }
}

TEST(Evaluate, TooFewLabelledSegmentsIsAClearError) {
  std::vector<ShapeMeasures> m;
  std::vector<int> y;
  segments(3, 24, m, y);  // 8 objects: 4 per half, fewer than 5 folds
  EXPECT_THROW(evaluate(m, y, EvalConfig{}), std::invalid_argument);
  EvalConfig bad;
  bad.train_share = 1.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(Evaluate, WritesCurvesTableAndPlot) {
  std::vector<ShapeMeasures> m;
  std::vector<int> y;
  segments(4, 150, m, y);
  EvalConfig config;
  config.splits = 2;
  const EvalResult r = evaluate(m, y, config);
  testing::TempDir dir;
  writeEvalCsv(r, dir / "pr_curves.csv", dir / "ap.csv");
  writePrPlot(r, dir / "pr_curves.png");
  const std::string ap = readWholeFile(dir / "ap.csv");
  EXPECT_EQ(ap.rfind("method,ap_mean,ap_sd\ncompactness,", 0), 0u) << ap;
  EXPECT_NE(ap.find("\nrbf_svm without smoothness,"), std::string::npos);
  const std::string curves = readWholeFile(dir / "pr_curves.csv");
  // Header plus 101 points for each of 7 methods and 2 ablations.
  EXPECT_EQ(std::count(curves.begin(), curves.end(), '\n'), 1 + 101 * 9);
  const cv::Mat png = cv::imread((dir / "pr_curves.png").string());
  EXPECT_EQ(png.cols, 900);
  EXPECT_EQ(png.rows, 700);
}

TEST(EvaluateRanking, RanksInIgnoredRegionsCountNeitherForNorAgainst) {
  // Objects 1 (vertices 0-3) and 2 (4-7); 8-11 background; 12-15 ignored (a plant).
  std::vector<std::int32_t> labels(16, 0);
  for (int v = 0; v < 8; ++v) labels[static_cast<std::size_t>(v)] = v < 4 ? 1 : 2;
  std::vector<std::uint8_t> ignore(16, 0);
  for (int v = 12; v < 16; ++v) ignore[static_cast<std::size_t>(v)] = 1;
  const GroundTruthObjects truth(labels, ignore);
  // The plant, object 1, the background, object 2.
  const RankingEvaluation e =
      evaluateRanking(truth, {{12, 13, 14}, {0, 1, 2, 3}, {8, 9, 10}, {4, 5, 6, 7}}, 0.5);
  ASSERT_EQ(e.ranks.size(), 4u);
  EXPECT_TRUE(e.ranks[0].ignored);
  EXPECT_FALSE(e.ranks[0].found);
  EXPECT_FALSE(e.ranks[1].ignored);
  EXPECT_TRUE(e.ranks[1].found);
  EXPECT_DOUBLE_EQ(e.ranks[1].precision, 1.0);  // the plant is not a rank
  EXPECT_DOUBLE_EQ(e.ranks[3].precision, 2.0 / 3.0);
  EXPECT_EQ(e.found, 2u);
  // AP: (1/1 + 2/3) / 2, as if the plant were not listed.
  EXPECT_NEAR(e.ap, (1.0 + 2.0 / 3.0) / 2.0, 1e-12);
  const RankingEvaluation without =
      evaluateRanking(truth, {{0, 1, 2, 3}, {8, 9, 10}, {4, 5, 6, 7}}, 0.5);
  EXPECT_DOUBLE_EQ(without.ap, e.ap);
}

}  // namespace
}  // namespace objscan::discovery
