// Training sets from the labels people give catalog segments (objscan view): which labels are
// used, and that their measures are the ones discover computes for the same scenes.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "objscan/core/error.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/scenes.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

namespace fs = std::filesystem;
using objscan::testing::TempDir;

/// A 1.2 m table (4 mm grid) with a round 4 cm tall mound of radius 6 cm at (x, 0) and an
/// elongated one of 6 x 10 cm at (-x, 0.05); a content hash of its own per `x`.
SceneInput table(float x) {
  const auto mound = [](float dx, float dy, float sx, float sy) {
    const float r = std::sqrt(dx * dx / (sx * sx) + dy * dy / (sy * sy));
    const float t = std::clamp((1.0f - r) / 0.4f, 0.0f, 1.0f);
    return 0.04f * t * t * (3.0f - 2.0f * t);
  };
  TriangleMesh mesh = testing::makeHeightField(301, 0.6f, [&](float px, float py) {
    return std::max(mound(px - x, py, 0.06f, 0.06f), mound(px + x, py - 0.05f, 0.06f, 0.10f));
  });
  return sceneFromMesh("table " + std::to_string(x), std::move(mesh), "table" + std::to_string(x));
}

/// The grid's density needs a smaller m_size than the paper's (see discover_test.cpp).
DiscoveryConfig config(int min_size = 200) {
  DiscoveryConfig c;
  c.min_size = min_size;
  return c;
}

/// Bit for bit, NaN as NaN.
void expectSameMeasures(const ShapeMeasures& got, const ShapeMeasures& want) {
  const auto a = measureValues(got), b = measureValues(want);
  for (std::size_t m = 0; m < a.size(); ++m) {
    if (std::isnan(b[m])) {
      EXPECT_TRUE(std::isnan(a[m])) << m;
    } else {
      EXPECT_EQ(a[m], b[m]) << m;
    }
  }
}

TEST(CatalogTrainingSet, UsesObjectAndNotLabelsOfTheseSettingsWithDiscoversMeasures) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  SceneDiscoveryOptions options;
  options.config = config();
  options.catalog = file;
  options.progress_label.clear();
  const SceneDiscovery run = discoverScenes({table(0.15f), table(0.2f)}, options);
  // The same table measured with other settings: its labels are not comparable.
  SceneDiscoveryOptions other = options;
  other.config = config(300);
  discoverScenes({table(0.15f)}, other);

  // Label the first scene's segments as a person who wants round things would: the round mound's
  // (x > 0) objects, the elongated one's not, one unsure; the second scene's first segment only;
  // every segment of the other settings' scene.
  Catalog catalog(file);
  const std::vector<CatalogScene> known = catalog.scenes();
  ASSERT_EQ(known.size(), 3u);
  std::size_t objects = 0, not_objects = 0, other_settings = 0;
  std::vector<std::int64_t> used;
  for (std::size_t s = 0; s < 3; ++s) {
    const std::vector<CatalogSegment> segments = catalog.segments(known[s].id, false);
    ASSERT_FALSE(segments.empty());
    for (std::size_t i = 0; i < segments.size(); ++i) {
      const int label = segments[i].centroid.x() > 0.0f ? 1 : 0;
      if (s == 2) {
        catalog.setLabel(segments[i].id, label, "ana");
        ++other_settings;
      } else if (s == 0 && i == 0) {
        catalog.setLabel(segments[i].id, static_cast<int>(SegmentLabel::kUnsure), "ana");
      } else if (s == 0 || i == 0) {
        catalog.setLabel(segments[i].id, label, "ana");
        (label == 1 ? objects : not_objects) += 1;
        used.push_back(segments[i].id);
      }
    }
  }
  ASSERT_GE(objects, 1u);
  ASSERT_GE(not_objects, 1u);

  const CatalogTrainingSet set = catalogTrainingSet(file, config());
  EXPECT_EQ(set.scenes, 2u);
  EXPECT_EQ(set.unsure, 1u);
  EXPECT_EQ(set.other_settings, other_settings);
  ASSERT_EQ(set.labels.size(), objects + not_objects);
  EXPECT_EQ(std::count(set.labels.begin(), set.labels.end(), 1),
            static_cast<std::ptrdiff_t>(objects));
  EXPECT_EQ(set.segment_ids, used);
  ASSERT_EQ(set.measures.size(), set.labels.size());

  // The measures and the normaliser are discover's for these scenes with this catalog:
  // recurrence against the other table, normalised over both tables' candidates.
  const SceneDiscovery again = discoverScenes({table(0.15f), table(0.2f)}, options);
  ASSERT_TRUE(again.scenes[0].from_catalog && again.scenes[1].from_catalog);
  std::size_t finite = 0;
  for (std::size_t k = 0; k < set.segment_ids.size(); ++k) {
    for (const DiscoveredScene& scene : again.scenes) {
      const std::vector<CatalogSegment> segments = catalog.segments(scene.scene_id, false);
      for (std::size_t i = 0; i < segments.size(); ++i) {
        if (segments[i].id != set.segment_ids[k]) continue;
        const ShapeMeasures& want = scene.candidates.measures[i];
        expectSameMeasures(set.measures[k], want);
        finite += std::isfinite(set.measures[k].recurrence);
      }
    }
  }
  // Each table's mounds have their like in the other: recurrence is defined for every one.
  EXPECT_EQ(finite, set.segment_ids.size());

  for (std::size_t m = 0; m < kMeasureCount; ++m) {
    EXPECT_DOUBLE_EQ(set.normaliser.mean[m], again.normaliser.mean[m]) << m;
    EXPECT_DOUBLE_EQ(set.normaliser.sd[m], again.normaliser.sd[m]) << m;
  }
  EXPECT_EQ(again.normaliser.mean, run.normaliser.mean);
}

TEST(CatalogTrainingSet, NoLabelsIsAnEmptySetAndAMissingCatalogAnInputError) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  objscan::testing::expectInputError([&] { catalogTrainingSet(file, config()); }, file,
                                     "no such catalog");
  EXPECT_FALSE(fs::exists(file));  // not created by looking
  { Catalog catalog(file); }
  const CatalogTrainingSet set = catalogTrainingSet(file, config());
  EXPECT_EQ(set.scenes, 0u);
  EXPECT_TRUE(set.labels.empty());
}

}  // namespace
}  // namespace objscan::discovery
