// Objectness scores: normalisation, average precision, the classifiers and their model files.

#include <gtest/gtest.h>

#include <functional>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "objscan/core/error.h"
#include "objscan/discovery/scoring.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

TEST(AveragePrecision, HandComputedRankings) {
  // Ranks 1..4 hold object, clutter, object, clutter: AP = (1/1 + 2/3) / 2.
  EXPECT_NEAR(averagePrecision({0.9, 0.8, 0.7, 0.6}, {1, 0, 1, 0}), (1.0 + 2.0 / 3.0) / 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(averagePrecision({3, 2, 1}, {1, 1, 0}), 1.0);
  // A tie is broken against the positives: ranks 3 and 4 of 4.
  EXPECT_NEAR(averagePrecision({1, 1, 1, 1}, {1, 0, 1, 0}), (1.0 / 3.0 + 2.0 / 4.0) / 2.0, 1e-12);
  EXPECT_TRUE(std::isnan(averagePrecision({1, 2}, {0, 0})));
  EXPECT_THROW(averagePrecision({1}, {1, 0}), std::invalid_argument);
}

TEST(MeasureNormaliser, ZeroMeanUnitVarianceOrientedAndNanAsTheMean) {
  std::vector<ShapeMeasures> rows(4);
  const double compact[] = {1, 2, 3, 4}, sym[] = {0.1, 0.1, 0.3, 0.3};
  for (int i = 0; i < 4; ++i) {
    rows[i].compactness = compact[i];
    rows[i].symmetry = sym[i];
    rows[i].local_convexity = 0.5;  // constant: says nothing
    rows[i].recurrence = i < 2 ? 1.0 : NAN;
  }
  const MeasureNormaliser n = MeasureNormaliser::fit(rows);
  EXPECT_DOUBLE_EQ(n.mean[0], 2.5);
  EXPECT_NEAR(n.sd[0], std::sqrt(1.25), 1e-12);
  EXPECT_NEAR(n.mean[1], -0.2, 1e-12);  // symmetry is a distance: negated
  EXPECT_EQ(n.sd[3], 0.0);
  EXPECT_EQ(n.sd[5], 0.0);  // recurrence known twice, both 1: no spread
  const MeasureRow z = n.normalise(rows[0]);
  EXPECT_NEAR(z[0], (1 - 2.5) / std::sqrt(1.25), 1e-12);
  EXPECT_NEAR(z[1], 1.0, 1e-12);  // the more symmetric half scores +1 sd
  EXPECT_EQ(z[3], 0.0);
  EXPECT_EQ(n.normalise(rows[3])[5], 0.0);
}

/// Labelled rows in six z-normalised dimensions: objects where x0^2 + x1^2 < 1 (a disc, which
/// no hyperplane separates from the ring of clutter around it), the other dimensions noise.
void discData(std::uint32_t seed, int n, std::vector<MeasureRow>& rows, std::vector<int>& labels) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  rows.clear();
  labels.clear();
  for (int i = 0; i < n; ++i) {
    MeasureRow r;
    for (double& v : r) v = 1.2 * g(rng);
    rows.push_back(r);
    labels.push_back(r[0] * r[0] + r[1] * r[1] < 1.0 ? 1 : 0);
  }
}

/// Rows where objects sit at +1 in every dimension and clutter at -1, with unit noise.
void blobData(std::uint32_t seed, int n, std::vector<MeasureRow>& rows, std::vector<int>& labels) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  rows.clear();
  labels.clear();
  for (int i = 0; i < n; ++i) {
    const int y = i % 3 == 0 ? 1 : 0;
    MeasureRow r;
    for (double& v : r) v = (y ? 1.0 : -1.0) + g(rng);
    rows.push_back(r);
    labels.push_back(y);
  }
}

double heldOutAp(const ObjectnessModel& model, const std::vector<MeasureRow>& rows,
                 const std::vector<int>& labels) {
  std::vector<double> s;
  for (const MeasureRow& r : rows) s.push_back(model.scoreNormalised(r));
  return averagePrecision(s, labels);
}

TEST(ObjectnessModel, EveryKindRanksSeparableBlobsAndTheAverageNeedsNoTraining) {
  std::vector<MeasureRow> train, test;
  std::vector<int> ytrain, ytest;
  blobData(1, 300, train, ytrain);
  blobData(2, 300, test, ytest);
  // The Bayes-optimal ranking of two unit Gaussians 2 apart in 6-D has AP about 0.99; 0.95 allows
  // for the sample.
  for (ScoreKind kind : kAllScoreKinds) {
    const ObjectnessModel m = ObjectnessModel::train(kind, MeasureNormaliser{}, train, ytrain);
    EXPECT_EQ(m.kind(), kind);
    EXPECT_GE(heldOutAp(m, test, ytest), 0.95) << toString(kind);
  }
}

TEST(ObjectnessModel, OnlyTheRbfKernelAndNeighboursSeparateADiscFromItsRing) {
  std::vector<MeasureRow> train, test;
  std::vector<int> ytrain, ytest;
  discData(3, 500, train, ytrain);
  discData(4, 500, test, ytest);
  const auto ap = [&](ScoreKind kind) {
    return heldOutAp(ObjectnessModel::train(kind, MeasureNormaliser{}, train, ytrain), test, ytest);
  };
  const double base = 0.3;  // about P(x0^2 + x1^2 < 1) for sd 1.2: 1 - exp(-1 / 2.88) = 0.29
  EXPECT_GE(ap(ScoreKind::kRbfSvm), 0.85);
  EXPECT_GE(ap(ScoreKind::kNearestNeighbour), 0.75);
  EXPECT_LE(ap(ScoreKind::kLinearSvm), base + 0.15);
  EXPECT_LE(ap(ScoreKind::kAverage), base + 0.15);
}

TEST(ObjectnessModel, TheMaskLeavesMeasuresOut) {
  std::vector<MeasureRow> rows;
  std::vector<int> labels;
  discData(5, 400, rows, labels);
  // Without x0 and x1 the disc cannot be found: the RBF SVM falls to about the base rate 0.3.
  MeasureMask mask = kAllMeasures;
  mask[0] = mask[1] = false;
  const ObjectnessModel m =
      ObjectnessModel::train(ScoreKind::kRbfSvm, MeasureNormaliser{}, rows, labels, mask);
  std::vector<MeasureRow> test;
  std::vector<int> ytest;
  discData(6, 400, test, ytest);
  EXPECT_LE(heldOutAp(m, test, ytest), 0.45);
  // The average over compactness alone is compactness.
  MeasureMask only_first{};
  only_first[0] = true;
  EXPECT_DOUBLE_EQ(ObjectnessModel::average({}, only_first).scoreNormalised(test[0]), test[0][0]);
}

TEST(ObjectnessModel, SavedAndLoadedModelsScoreTheSame) {
  testing::TempDir dir;
  std::vector<MeasureRow> rows;
  std::vector<int> labels;
  discData(7, 200, rows, labels);
  MeasureNormaliser n;
  n.mean = {1, 2, 3, 4, 5, 6};
  n.sd = {1, 0.5, 2, 1, 1, 0};
  for (ScoreKind kind : kAllScoreKinds) {
    const ObjectnessModel m = ObjectnessModel::train(kind, n, rows, labels);
    const auto path = dir / (std::string(toString(kind)) + ".json");
    m.save(path);
    const ObjectnessModel back = ObjectnessModel::load(path);
    EXPECT_EQ(back.kind(), kind);
    EXPECT_EQ(back.parameters(), m.parameters());
    EXPECT_EQ(back.normaliser().mean, n.mean);
    EXPECT_EQ(back.normaliser().sd, n.sd);
    ShapeMeasures s;
    s.compactness = 0.3;
    s.symmetry = 0.1;
    s.smoothness = 0.7;
    s.recurrence = 2.0;
    EXPECT_NEAR(back.score(s), m.score(s), 1e-6) << toString(kind);
    for (int i = 0; i < 20; ++i) {
      EXPECT_NEAR(back.scoreNormalised(rows[i]), m.scoreNormalised(rows[i]), 1e-6);
    }
  }
}

TEST(ObjectnessModel, WrongFilesAreInputErrorsNamingTheFile) {
  testing::TempDir dir;
  testing::writeBytes(dir / "mesh.ply", "ply\nformat ascii 1.0\nend_header\n");
  testing::writeBytes(dir / "other.json", R"({"something": 3})");
  testing::writeBytes(dir / "newer.json", R"({"objscan_model": 99, "kind": "average"})");
  testing::writeBytes(dir / "empty.json", "");
  testing::writeBytes(dir / "bad_kind.json", R"({"objscan_model": 2, "kind": "random_forest"})");
  testing::writeBytes(dir / "truncated.json", R"({"objscan_model": 2, "kind": "ave)");
  // A model of objscan before version 2 (OpenCV FileStorage YAML): no longer read, because
  // OpenCV 4.6's YAML reader never returns on some damaged files (fuzz_model found them).
  testing::writeBytes(dir / "old.yml", "%YAML:1.0\n---\nobjscan_model: 1\nkind: average\n");
  testing::writeBytes(dir / "hang.yml", "%YAML:1.\n----s\n-  -\n ");
  for (const char* name : {"mesh.ply", "other.json", "newer.json", "empty.json", "bad_kind.json",
                           "truncated.json", "missing.json", "old.yml", "hang.yml"}) {
    try {
      ObjectnessModel::load(dir / name);
      ADD_FAILURE() << name << " loaded";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  // fuzz_model's second OpenCV YAML hang, with a correct header: refused as YAML, not read.
  const auto hang = std::filesystem::path(OBJSCAN_SOURCE_DIR) /
                    "tests/discovery/fuzz_regressions/opencv_yaml_hang.yml";
  try {
    ObjectnessModel::load(hang);
    ADD_FAILURE() << hang << " loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("old YAML form"), std::string::npos) << e.what();
  }
}

TEST(ObjectnessModel, DamagedModelFilesNameWhatIsWrong) {
  testing::TempDir dir;
  std::vector<MeasureRow> rows;
  std::vector<int> labels;
  discData(11, 120, rows, labels);
  const auto saved = [&](ScoreKind kind) {
    const auto path = dir / (std::string(toString(kind)) + ".json");
    ObjectnessModel::train(kind, MeasureNormaliser{}, rows, labels).save(path);
    return nlohmann::json::parse(testing::readBytes(path));
  };
  const auto expectRefused = [&](const std::string& text, const std::string& why) {
    testing::writeBytes(dir / "damaged.json", text);
    try {
      ObjectnessModel::load(dir / "damaged.json");
      ADD_FAILURE() << "loaded: " << text.substr(0, 300);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("damaged.json"), std::string::npos) << e.what();
    }
  };
  // `model` with `change` made to it is refused, saying `why`.
  const auto expectChangeRefused = [&](nlohmann::json model,
                                       const std::function<void(nlohmann::json&)>& change,
                                       const std::string& why) {
    change(model);
    expectRefused(model.dump(), why);
  };
  // The untouched files load: each refusal below is the change's doing.
  const nlohmann::json svm = saved(ScoreKind::kRbfSvm);
  const nlohmann::json knn = saved(ScoreKind::kNearestNeighbour);
  const nlohmann::json bayes = saved(ScoreKind::kNaiveBayes);
  for (const auto* model : {&svm, &knn, &bayes}) {
    testing::writeBytes(dir / "intact.json", model->dump());
    EXPECT_NO_THROW(ObjectnessModel::load(dir / "intact.json"));
  }
  using J = nlohmann::json;
  // A deviation below 0 turns a measure around, a tiny one blows it up; the score's sign is 1 or
  // -1. Each is named by its key. (0 is what train writes for a measure that does not vary.)
  for (const auto* model : {&svm, &knn, &bayes}) {
    expectChangeRefused(
        *model, [](J& m) { m["sd"][0] = -1.0; }, "\"sd\": the deviation of compactness is -1");
    expectChangeRefused(
        *model, [](J& m) { m["sd"][2] = 1e-40; }, "\"sd\": the deviation of smoothness is 1e-40");
    expectChangeRefused(
        *model, [](J& m) { m["sign"] = 0.5; }, "\"sign\" is 0.5; it is 1 or -1");
    expectChangeRefused(
        *model, [](J& m) { m["sign"] = 0; }, "\"sign\" is 0; it is 1 or -1");
    expectChangeRefused(
        *model, [](J& m) { m["sign"] = -3; }, "\"sign\" is -3; it is 1 or -1");
  }
  {
    J unvarying = svm;
    unvarying["sd"][0] = 0.0;
    testing::writeBytes(dir / "unvarying.json", unvarying.dump());
    EXPECT_NO_THROW(ObjectnessModel::load(dir / "unvarying.json"));
  }
  expectChangeRefused(
      svm, [](J& m) { m["svm"]["alpha"].push_back(1.0); }, "one per support vector");
  expectChangeRefused(
      svm, [](J& m) { m["svm"]["rho"] = nullptr; }, "rho must be a number");
  expectChangeRefused(
      svm, [](J& m) { m["svm"]["rho"] = 1e31; }, "rho is not finite or out of range");
  expectChangeRefused(
      svm,
      [](J& m) {
        m["svm"]["support_vectors"][0] = {1, 2};
      },
      "must hold 6 numbers, one per measure");
  expectChangeRefused(
      svm, [](J& m) { m.erase("svm"); }, "without its support vectors");
  expectChangeRefused(
      knn, [](J& m) { m["knn"]["labels"][0] = 7; }, "labels are 0 or 1");
  expectChangeRefused(
      knn, [](J& m) { m["knn"]["labels"].push_back(1); }, "one per sample");
  expectChangeRefused(
      knn, [](J& m) { m["k"] = 100000; }, "k must be between");
  // Numbers past an int where an int belongs (converting them was undefined behaviour; found by
  // fuzz_model: tests/discovery/fuzz_regressions/model_version_past_int.json).
  expectChangeRefused(
      knn, [](J& m) { m["k"] = 1e300; }, "k must be a whole number");
  expectChangeRefused(
      knn, [](J& m) { m["knn"]["labels"][0] = 4294967297ULL; },
      "a nearest_neighbour label is out of range");
  expectChangeRefused(
      knn, [](J& m) { m["objscan_model"] = 18446744073709551615ULL; },
      "objscan_model (the version) is out of range");
  const auto found = std::filesystem::path(OBJSCAN_SOURCE_DIR) /
                     "tests/discovery/fuzz_regressions/model_version_past_int.json";
  testing::expectInputError([&] { ObjectnessModel::load(found); }, found,
                            "objscan_model (the version) must be a whole number");
  expectChangeRefused(
      bayes, [](J& m) { m["bayes"]["var0"][0] = -1.0; }, "variances must be positive");
  expectChangeRefused(
      bayes, [](J& m) { m["bayes"]["var1"][2] = 1e-320; }, "variances must be positive");
  expectChangeRefused(
      bayes, [](J& m) { m["bayes"]["mean0"].push_back(0.0); }, "one per measure");
}

TEST(ObjectnessModel, TrainingRejectsTooFewExamplesOfAClass) {
  std::vector<MeasureRow> rows(20);
  std::vector<int> labels(20, 0);
  labels[0] = labels[1] = 1;
  EXPECT_THROW(ObjectnessModel::train(ScoreKind::kRbfSvm, MeasureNormaliser{}, rows, labels),
               std::invalid_argument);
  EXPECT_THROW(scoreKindFromString("svm"), std::invalid_argument);
  EXPECT_EQ(scoreKindFromString("rbf_svm"), ScoreKind::kRbfSvm);
}

TEST(LeaveOneSceneOut, EqualsTrainingOnTheOtherScenesByHandAndSkipsWhatCannotTrain) {
  // Three "scenes" of separable blobs: the held-out scores are those of a model trained on the
  // other two, scene by scene (the brute-force reference), ranked together.
  std::vector<MeasureRow> rows, part;
  std::vector<int> labels, part_labels;
  std::vector<std::size_t> scene_of;
  for (std::size_t s = 0; s < 3; ++s) {
    blobData(static_cast<std::uint32_t>(10 + s), 60, part, part_labels);
    rows.insert(rows.end(), part.begin(), part.end());
    labels.insert(labels.end(), part_labels.begin(), part_labels.end());
    scene_of.insert(scene_of.end(), part.size(), s);
  }
  const HeldOutScenes held = leaveOneSceneOut(ScoreKind::kLinearSvm, MeasureNormaliser{}, rows,
                                              labels, scene_of);
  EXPECT_EQ(held.scenes, 3u);
  EXPECT_EQ(held.skipped, 0u);
  EXPECT_EQ(held.rows, rows.size());
  std::vector<double> scores;
  std::vector<int> truth;
  for (std::size_t s = 0; s < 3; ++s) {
    std::vector<MeasureRow> train;
    std::vector<int> ytrain;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (scene_of[i] != s) {
        train.push_back(rows[i]);
        ytrain.push_back(labels[i]);
      }
    }
    const ObjectnessModel m =
        ObjectnessModel::train(ScoreKind::kLinearSvm, MeasureNormaliser{}, train, ytrain);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      if (scene_of[i] == s) {
        scores.push_back(m.scoreNormalised(rows[i]));
        truth.push_back(labels[i]);
      }
    }
  }
  EXPECT_DOUBLE_EQ(held.ap, averagePrecision(scores, truth));
  EXPECT_GE(held.ap, 0.95);  // two unit Gaussians 2 apart in 6-D, as above
  EXPECT_DOUBLE_EQ(held.min_score, *std::min_element(scores.begin(), scores.end()));
  EXPECT_DOUBLE_EQ(held.max_score, *std::max_element(scores.begin(), scores.end()));
  // One scene: nothing to hold out. A scene whose removal leaves too few objects: skipped.
  const HeldOutScenes one = leaveOneSceneOut(ScoreKind::kLinearSvm, MeasureNormaliser{}, rows,
                                             labels, std::vector<std::size_t>(rows.size(), 0));
  EXPECT_EQ(one.scenes, 0u);
  EXPECT_TRUE(std::isnan(one.ap));
  std::vector<int> few = labels;
  for (std::size_t i = 0; i < few.size(); ++i) few[i] = scene_of[i] == 0 ? few[i] : 0;
  const HeldOutScenes skipped =
      leaveOneSceneOut(ScoreKind::kLinearSvm, MeasureNormaliser{}, rows, few, scene_of);
  EXPECT_EQ(skipped.scenes, 2u);  // scenes 1 and 2 (trained on scene 0's objects)
  EXPECT_EQ(skipped.skipped, 1u);
}

}  // namespace
}  // namespace objscan::discovery
