// Recurrence on hand-made catalogs whose answers can be worked out on paper, and against a
// brute-force reading of the paper's definition on random catalogs.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <vector>

#include "objscan/discovery/recurrence.h"

namespace objscan::discovery {
namespace {

RecurrenceEntry entry(std::int64_t scene, const Eigen::Vector3f& extents,
                      const std::array<double, 5>& measures) {
  return RecurrenceEntry{scene, extents, measures};
}

const Eigen::Vector3f kSize(0.2f, 0.1f, 0.05f);

/// Only the first measure varies; the other four are constant (standard deviation 0).
std::array<double, 5> first(double m0) { return {m0, 7.0, 7.0, 7.0, 7.0}; }

TEST(Recurrence, MeanDistanceToTheKNearestInNormalisedUnits) {
  // First measure 0, 1, 2, 3, 4: mean 2, population variance (4 + 1 + 0 + 1 + 4) / 5 = 2.
  // The query (0, scene 1) sees scene 2's values 1 and 2 as its k = 2 nearest, at 1 / sqrt(2)
  // and 2 / sqrt(2): the mean is 1.5 / sqrt(2). The constant measures count for nothing, even
  // where the query differs from them.
  const RecurrenceIndex index({entry(1, kSize, first(0)), entry(2, kSize, first(1)),
                               entry(2, kSize, first(2)), entry(2, kSize, first(3)),
                               entry(2, kSize, first(4))});
  EXPECT_EQ(index.size(), 5u);
  const std::array<double, 5> query = {0.0, 100.0, -3.0, 7.0, 0.0};
  EXPECT_NEAR(index.recurrence(kSize, query, 1, 2), 1.5 / std::sqrt(2.0), 1e-12);
  // k = 10 with four qualifying: the mean over those four, (1 + 2 + 3 + 4) / 4 / sqrt(2).
  EXPECT_NEAR(index.recurrence(kSize, query, 1), 2.5 / std::sqrt(2.0), 1e-12);
  // k = 1 from between the values: 2.6 is 0.4 from 3.
  EXPECT_NEAR(index.recurrence(kSize, first(2.6), 1, 1), 0.4 / std::sqrt(2.0), 1e-12);
}

TEST(Recurrence, SeveralMeasuresAddInQuadrature) {
  // Two varying measures, each over {-1, +1} (mean 0, sd 1) and {-10, +10} (mean 0, sd 10):
  // the query (1, 10) of scene 9 is at distance sqrt(2^2 + 2^2) from (-1, -10), 2 from (-1, 10)
  // and from (1, -10), 0 from (1, 10).
  const std::vector<RecurrenceEntry> entries = {
      entry(1, kSize, {-1, -10, 0, 0, 0}), entry(2, kSize, {-1, 10, 0, 0, 0}),
      entry(3, kSize, {1, -10, 0, 0, 0}), entry(4, kSize, {1, 10, 0, 0, 0})};
  const RecurrenceIndex index(entries);
  const std::array<double, 5> query = {1, 10, 0, 0, 0};
  EXPECT_NEAR(index.recurrence(kSize, query, 9, 4), (std::sqrt(8.0) + 2 + 2 + 0) / 4, 1e-12);
  EXPECT_NEAR(index.recurrence(kSize, query, 9, 3), (2 + 2 + 0) / 3.0, 1e-12);
}

TEST(Recurrence, NormalisationMakesTheUnitsOfAMeasureIrrelevant) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<RecurrenceEntry> entries, rescaled;
  for (int i = 0; i < 200; ++i) {
    const std::array<double, 5> m = {u(rng), u(rng), u(rng), u(rng), u(rng)};
    entries.push_back(entry(i % 5, kSize, m));
    std::array<double, 5> r = m;
    r[1] = 1000.0 * r[1] - 42.0;  // e.g. millimetres and an offset
    r[4] = 0.001 * r[4];
    rescaled.push_back(entry(i % 5, kSize, r));
  }
  const RecurrenceIndex a(entries), b(rescaled);
  const std::array<double, 5> q = {0.3, 0.6, 0.1, 0.9, 0.5};
  const std::array<double, 5> q_rescaled = {0.3, 1000.0 * 0.6 - 42.0, 0.1, 0.9, 0.001 * 0.5};
  const double expected = a.recurrence(kSize, q, 0);
  EXPECT_TRUE(std::isfinite(expected));
  EXPECT_NEAR(b.recurrence(kSize, q_rescaled, 0), expected, 1e-9);
}

TEST(Recurrence, EntriesOfTheExcludedSceneDoNotCount) {
  // Scene 1 holds an exact match; scene 2's only entry is 2 units away (values -1, 1, mean 0,
  // sd 1, plus the query's own-scene duplicate: values -1, -1, 1 -> mean -1/3, sd sqrt(8/9)).
  const RecurrenceIndex index(
      {entry(1, kSize, first(-1)), entry(1, kSize, first(-1)), entry(2, kSize, first(1))});
  const double sd = std::sqrt(8.0 / 9.0);
  EXPECT_NEAR(index.recurrence(kSize, first(-1), 1), 2.0 / sd, 1e-12);
  EXPECT_NEAR(index.recurrence(kSize, first(-1), 2), 0.0, 1e-12);
}

TEST(Recurrence, SegmentsOutsideTheWindowAreIgnoredEvenWhenIdentical) {
  // Query extents (0.2, 0.1, 0.05): the window is [0.15, 0.25] x [0.075, 0.125] x
  // [0.0375, 0.0625]. Just outside along each axis, in both directions, with identical measures;
  // just inside, one 1 unit away in measures (values 0 and 1 among -1, 0, 1, ... see below).
  std::vector<RecurrenceEntry> entries;
  const std::array<Eigen::Vector3f, 6> outside = {
      Eigen::Vector3f(0.149f, 0.1f, 0.05f),  Eigen::Vector3f(0.251f, 0.1f, 0.05f),
      Eigen::Vector3f(0.2f, 0.0745f, 0.05f), Eigen::Vector3f(0.2f, 0.1255f, 0.05f),
      Eigen::Vector3f(0.2f, 0.1f, 0.0374f),  Eigen::Vector3f(0.2f, 0.1f, 0.0626f)};
  for (const Eigen::Vector3f& e : outside) entries.push_back(entry(2, e, first(0)));
  const Eigen::Vector3f inside(0.151f, 0.124f, 0.0376f);
  entries.push_back(entry(3, inside, first(1)));
  // Values: six 0s and one 1: mean 1/7, variance 6/49, so a unit step is 7 / sqrt(6).
  const RecurrenceIndex index(entries);
  EXPECT_NEAR(index.recurrence(kSize, first(0), 1), 7.0 / std::sqrt(6.0), 1e-12);
  // Widening the window to 30 % takes the six in (and they match exactly): k = 6 gives 0.
  EXPECT_NEAR(index.recurrence(kSize, first(0), 1, 6, 0.30), 0.0, 1e-12);
  // A window of 0 admits only identical extents.
  EXPECT_TRUE(std::isnan(index.recurrence(kSize, first(0), 1, 10, 0.0)));
  EXPECT_NEAR(index.recurrence(inside, first(0), 1, 10, 0.0), 7.0 / std::sqrt(6.0), 1e-12);
}

TEST(Recurrence, NaNWhenNoOtherSceneQualifies) {
  const RecurrenceIndex only_own({entry(4, kSize, first(0)), entry(4, kSize, first(1))});
  EXPECT_TRUE(std::isnan(only_own.recurrence(kSize, first(0), 4)));
  const RecurrenceIndex empty({});
  EXPECT_EQ(empty.size(), 0u);
  EXPECT_TRUE(std::isnan(empty.recurrence(kSize, first(0), 4)));
  EXPECT_TRUE(empty.recurrences({entry(4, kSize, first(0))}, 4).size() == 1 &&
              std::isnan(empty.recurrences({entry(4, kSize, first(0))}, 4)[0]));
  // A query whose size is not a size matches nothing.
  const RecurrenceIndex other({entry(5, kSize, first(0))});
  EXPECT_TRUE(std::isnan(other.recurrence(Eigen::Vector3f(0.2f, NAN, 0.05f), first(0), 4)));
  EXPECT_TRUE(std::isnan(other.recurrence(Eigen::Vector3f(0.2f, -0.1f, 0.05f), first(0), 4)));
  EXPECT_NEAR(other.recurrence(kSize, first(0), 4), 0.0, 1e-12);
}

TEST(Recurrence, NonFiniteMeasuresCountAsTheMean) {
  // The NaN entry leaves the statistics to the finite values (0 and 2: mean 1, sd 1) and sits at
  // the mean: 1 unit from a query at 2 or 0.
  const RecurrenceIndex index(
      {entry(1, kSize, first(0)), entry(1, kSize, first(2)), entry(2, kSize, first(NAN))});
  EXPECT_NEAR(index.recurrence(kSize, first(2), 1), 1.0, 1e-12);
  EXPECT_NEAR(index.recurrence(kSize, first(NAN), 1), 0.0, 1e-12);
}

TEST(Recurrence, RejectsMeaninglessArguments) {
  const RecurrenceIndex index({entry(1, kSize, first(0))});
  EXPECT_THROW(index.recurrence(kSize, first(0), 2, 0), std::invalid_argument);
  EXPECT_THROW(index.recurrence(kSize, first(0), 2, 10, -0.1), std::invalid_argument);
  EXPECT_THROW(index.recurrence(kSize, first(0), 2, 10, NAN), std::invalid_argument);
  EXPECT_THROW(index.recurrences({}, 2, -1), std::invalid_argument);
}

/// Each measure's population standard deviation over the entries.
std::array<double, 5> standardDeviations(const std::vector<RecurrenceEntry>& entries) {
  std::array<double, 5> mean{}, sd{};
  for (std::size_t j = 0; j < 5; ++j) {
    for (const auto& e : entries) mean[j] += e.measures[j];
    mean[j] /= static_cast<double>(entries.size());
    for (const auto& e : entries) sd[j] += (e.measures[j] - mean[j]) * (e.measures[j] - mean[j]);
    sd[j] = std::sqrt(sd[j] / static_cast<double>(entries.size()));
  }
  return sd;
}

/// The paper's definition read literally: normalise over all entries, scan all of them.
double bruteForce(const std::vector<RecurrenceEntry>& entries, const RecurrenceEntry& q,
                  std::int64_t exclude, int k, double window) {
  const std::array<double, 5> sd = standardDeviations(entries);
  std::vector<double> distances;
  for (const auto& e : entries) {
    if (e.scene_id == exclude) continue;
    bool in = true;
    for (int d = 0; d < 3; ++d) {
      in = in && std::abs(double{e.extents[d]} - double{q.extents[d]}) <= window * q.extents[d];
    }
    if (!in) continue;
    double d2 = 0.0;
    for (std::size_t j = 0; j < 5; ++j) {
      const double diff = (e.measures[j] - q.measures[j]) / sd[j];
      d2 += diff * diff;
    }
    distances.push_back(std::sqrt(d2));
  }
  if (distances.empty()) return NAN;
  std::sort(distances.begin(), distances.end());
  const std::size_t n = std::min<std::size_t>(distances.size(), static_cast<std::size_t>(k));
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) sum += distances[i];
  return sum / static_cast<double>(n);
}

/// Extents from 2 cm to 1 m, log-uniform, decreasing; measures on different scales.
std::vector<RecurrenceEntry> randomEntries(std::mt19937* rng, std::size_t n, int scenes) {
  std::uniform_real_distribution<float> log_size(std::log(0.02f), std::log(1.0f));
  std::normal_distribution<double> z(0.0, 1.0);
  std::vector<RecurrenceEntry> out;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3f e(std::exp(log_size(*rng)), std::exp(log_size(*rng)), std::exp(log_size(*rng)));
    std::sort(e.data(), e.data() + 3, std::greater<float>());
    out.push_back(entry(static_cast<std::int64_t>(i % static_cast<std::size_t>(scenes)), e,
                        {0.3 + 0.1 * z(*rng), 0.05 * z(*rng), 0.8 + 0.05 * z(*rng),
                         0.6 + 0.2 * z(*rng), 0.004 * std::abs(z(*rng))}));
  }
  return out;
}

TEST(Recurrence, MatchesABruteForceScanOnRandomCatalogs) {
  std::mt19937 rng(2013);
  const std::vector<RecurrenceEntry> entries = randomEntries(&rng, 3000, 12);
  const std::vector<RecurrenceEntry> queries = randomEntries(&rng, 60, 1);
  const RecurrenceIndex index(entries);
  int finite = 0;
  for (const double window : {0.0, 0.1, 0.25, 0.5, 0.99, 1.0, 3.0}) {
    for (const int k : {1, 10, 50}) {
      const std::vector<double> batch = index.recurrences(queries, 3, k, window);
      ASSERT_EQ(batch.size(), queries.size());
      for (std::size_t i = 0; i < queries.size(); ++i) {
        const double expected = bruteForce(entries, queries[i], 3, k, window);
        const double got = index.recurrence(queries[i].extents, queries[i].measures, 3, k, window);
        if (std::isnan(expected)) {
          EXPECT_TRUE(std::isnan(got)) << "window " << window << " k " << k << " query " << i;
        } else {
          ++finite;
          EXPECT_NEAR(got, expected, 1e-9) << "window " << window << " k " << k << " query " << i;
        }
        EXPECT_TRUE(got == batch[i] || (std::isnan(got) && std::isnan(batch[i])));
      }
    }
  }
  EXPECT_GT(finite, 900);  // most of the 21 x 60 look-ups find neighbours, so they were checked
}

// The neighbours themselves (the collection page's "objects across scenes"): the same entries,
// in the same order, as sorting every qualifying entry by distance; their mean is recurrence().
TEST(Recurrence, NearestAreTheBruteForcesNearestInOrderAndAverageToTheRecurrence) {
  std::mt19937 rng(29);
  const std::vector<RecurrenceEntry> entries = randomEntries(&rng, 2000, 7);
  const std::vector<RecurrenceEntry> queries = randomEntries(&rng, 40, 1);
  const RecurrenceIndex index(entries);
  const std::array<double, 5> sd = standardDeviations(entries);
  std::size_t checked = 0;
  for (const RecurrenceEntry& q : queries) {
    std::vector<std::pair<double, std::size_t>> all;
    for (std::size_t i = 0; i < entries.size(); ++i) {
      const RecurrenceEntry& e = entries[i];
      bool in = e.scene_id != 2;
      for (int d = 0; d < 3; ++d) {
        in = in && std::abs(double{e.extents[d]} - double{q.extents[d]}) <= 0.25 * q.extents[d];
      }
      if (!in) continue;
      double d2 = 0.0;
      for (std::size_t j = 0; j < 5; ++j) {
        d2 += std::pow((e.measures[j] - q.measures[j]) / sd[j], 2);
      }
      all.emplace_back(std::sqrt(d2), i);
    }
    std::sort(all.begin(), all.end());
    const std::vector<RecurrenceNeighbour> got = index.nearest(q.extents, q.measures, 2, 10);
    ASSERT_EQ(got.size(), std::min<std::size_t>(all.size(), 10));
    double sum = 0.0;
    for (std::size_t n = 0; n < got.size(); ++n) {
      EXPECT_EQ(got[n].entry, all[n].second);
      EXPECT_NEAR(got[n].distance, all[n].first, 1e-9);
      EXPECT_NE(entries[got[n].entry].scene_id, 2);
      sum += got[n].distance;
    }
    if (!got.empty()) {
      EXPECT_NEAR(index.recurrence(q.extents, q.measures, 2, 10),
                  sum / static_cast<double>(got.size()), 1e-12);
      ++checked;
    } else {
      EXPECT_TRUE(std::isnan(index.recurrence(q.extents, q.measures, 2, 10)));
    }
  }
  EXPECT_GT(checked, 20u);  // most queries have neighbours, so the order was checked
}

TEST(Recurrence, MovedIndexAnswersTheSame) {
  RecurrenceIndex a({entry(1, kSize, first(0)), entry(2, kSize, first(2))});
  const double before = a.recurrence(kSize, first(0), 1);
  RecurrenceIndex b(std::move(a));
  EXPECT_EQ(b.recurrence(kSize, first(0), 1), before);
  EXPECT_EQ(b.size(), 2u);
}

}  // namespace
}  // namespace objscan::discovery
