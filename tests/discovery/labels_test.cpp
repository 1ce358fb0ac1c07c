// Label transfer from a ground-truth mesh, and matching segments to ground-truth objects.

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include "objscan/core/ply_io.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scenes.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

/// A flat square of side `size` at height z, centred on (cx, cy), every vertex labelled `id`.
TriangleMesh square(float cx, float cy, float z, float size, std::int32_t id) {
  TriangleMesh m = testing::makeHeightField(11, size / 2, [&](float, float) { return z; });
  for (Eigen::Vector3f& p : m.positions) p += Eigen::Vector3f(cx, cy, 0.0f);
  m.labels.assign(m.positions.size(), id);
  return m;
}

void append(TriangleMesh& to, const TriangleMesh& part) {
  const auto offset = static_cast<int>(to.positions.size());
  to.positions.insert(to.positions.end(), part.positions.begin(), part.positions.end());
  to.normals.insert(to.normals.end(), part.normals.begin(), part.normals.end());
  to.labels.insert(to.labels.end(), part.labels.begin(), part.labels.end());
  for (const Eigen::Vector3i& t : part.triangles) to.triangles.push_back(t.array() + offset);
}

TEST(TransferLabels, NearestSurfaceWithinOneCentimetreGivesItsObject) {
  // Truth: a floor (0) with two boxes' tops (ids 3 and 7) 10 cm above it.
  TriangleMesh truth = square(0, 0, 0, 1.0f, 0);
  append(truth, square(-0.2f, 0, 0.1f, 0.1f, 3));
  append(truth, square(0.2f, 0, 0.1f, 0.1f, 7));
  TriangleMesh fused;
  fused.positions = {
      {-0.2f, 0.01f, 0.105f},   // 5 mm above object 3's top
      {0.21f, -0.02f, 0.092f},  // 8 mm below object 7's top
      {0.2f, 0.0f, 0.115f},     // 15 mm above object 7: too far
      {0.4f, 0.4f, 0.003f},     // on the floor
      {0.0f, 0.0f, 0.05f},      // in the air, 5 cm from everything
  };
  EXPECT_EQ(transferLabels(fused, truth), (std::vector<std::int32_t>{3, 7, 0, 0, 0}));
  // A wider reach picks up the 15 mm point.
  EXPECT_EQ(transferLabels(fused, truth, 0.02f)[2], 7);
}

TEST(TransferLabels, NeedsLabelledTriangles) {
  TriangleMesh truth = square(0, 0, 0, 1.0f, 1);
  TriangleMesh fused = truth;
  truth.labels.clear();
  EXPECT_THROW(transferLabels(fused, truth), std::invalid_argument);
}

/// A floor 80 cm square at 1 cm spacing with three boxes on it, as a height field: a 12 x 8 x 6 cm
/// box (id 1), a 3 cm cube (id 2, a small object) and a 10 x 10 x 10 cm box (id 3). The floor
/// and the boxes' sides are 0.
TriangleMesh floorWithBoxes() {
  struct Box {
    float x0, x1, y0, y1, h;
    std::int32_t id;
  };
  const Box boxes[] = {{-0.2f, -0.08f, 0.0f, 0.08f, 0.06f, 1},
                       {0.1f, 0.13f, -0.1f, -0.07f, 0.03f, 2},
                       {0.05f, 0.15f, 0.1f, 0.2f, 0.1f, 3}};
  const auto on = [&](float x, float y) -> const Box* {
    for (const Box& b : boxes) {
      if (x >= b.x0 - 1e-4f && x <= b.x1 + 1e-4f && y >= b.y0 - 1e-4f && y <= b.y1 + 1e-4f) {
        return &b;
      }
    }
    return nullptr;
  };
  TriangleMesh m = testing::makeHeightField(81, 0.4f, [&](float x, float y) {
    const Box* b = on(x, y);
    return b ? b->h : 0.0f;
  });
  for (const Eigen::Vector3f& p : m.positions) {
    const Box* b = on(p.x(), p.y());
    m.labels.push_back(b ? b->id : 0);
  }
  return m;
}

/// The share of vertices whose labels differ.
double differing(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) n += a[i] != b[i];
  return static_cast<double>(n) / static_cast<double>(a.size());
}

/// The share of the vertices that `truth` labels `id` that `labels` label `id` too.
double kept(const std::vector<std::int32_t>& labels, const std::vector<std::int32_t>& truth,
            std::int32_t id) {
  std::size_t both = 0, of_truth = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    of_truth += truth[i] == id;
    both += truth[i] == id && labels[i] == id;
  }
  return of_truth ? static_cast<double>(both) / static_cast<double>(of_truth) : 0.0;
}

/// `mesh` moved by 0.6 degrees and 13 mm (mostly up), as a drifting fusion with a depth bias is
/// displaced from the truth.
Eigen::Isometry3f displacement() {
  Eigen::Isometry3f T = Eigen::Isometry3f::Identity();
  T.linear() = Eigen::AngleAxisf(0.6f * std::numbers::pi_v<float> / 180.0f,
                                 Eigen::Vector3f(0.3f, 1.0f, 0.2f).normalized())
                   .matrix();
  T.translation() = Eigen::Vector3f(0.004f, -0.003f, 0.012f);
  return T;
}

TEST(AlignToTruth, LaysADisplacedFusionBackOntoItsTruth) {
  const TriangleMesh truth = floorWithBoxes();
  // The "fusion": the same surface cut into triangles along the cells' other diagonals, each
  // vertex 0.5 mm off at random, displaced.
  TriangleMesh fused = truth;
  fused.labels.clear();
  const int n = 81;
  fused.triangles.clear();
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int v = j * n + i;
      fused.triangles.emplace_back(v, v + 1, v + n);
      fused.triangles.emplace_back(v + 1, v + n + 1, v + n);
    }
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> jitter(-0.0005f, 0.0005f);
  const Eigen::Isometry3f T_mesh_truth = displacement();
  for (Eigen::Vector3f& p : fused.positions) {
    p = T_mesh_truth * (p + Eigen::Vector3f(jitter(rng), jitter(rng), jitter(rng)));
  }

  const TruthAlignment a = alignToTruth(fused, truth);
  const Eigen::Isometry3f residual = a.T_truth_mesh * T_mesh_truth;  // identity when exact
  // Within 1 mm anywhere on the 80 cm floor: a tenth of the labels' reach. (The other diagonals
  // slant the boxes' sides differently, which pulls the fit by a fraction of a millimetre.)
  float worst = 0.0f;
  for (const Eigen::Vector3f& p : truth.positions) {
    worst = std::max(worst, (residual * p - p).norm());
  }
  EXPECT_LT(worst, 0.001f);
  EXPECT_TRUE(a.converged);
  EXPECT_LE(a.iterations, 10);
  EXPECT_NEAR(a.moved_m, 0.013f, 0.002f);
  EXPECT_GT(a.rms_before_m, 0.003f);
  EXPECT_LT(a.rms_after_m, 0.0008f) << "the jitter's own RMS is 0.5 mm";
  EXPECT_LE(a.samples, 5000u);
  EXPECT_GT(a.pairs, a.samples * 9 / 10) << "nearly every picked vertex is within reach";
}

TEST(AlignToTruth, TheLabelsFollowTheMeshBack) {
  const TriangleMesh truth = floorWithBoxes();
  TriangleMesh fused = truth;
  for (Eigen::Vector3f& p : fused.positions) p = displacement() * p;
  fused.labels.clear();
  // Unmoved, most of the small cube's top lies over 1 cm from any true surface and counts as
  // background; moved back, every label is the truth's.
  EXPECT_LT(kept(transferLabels(fused, truth), truth.labels, 2), 0.5);
  const TruthAlignment a = alignToTruth(fused, truth);
  TriangleMesh moved = fused;
  for (Eigen::Vector3f& p : moved.positions) p = a.T_truth_mesh * p;
  const std::vector<std::int32_t> labels = transferLabels(moved, truth);
  for (std::int32_t id : {1, 2, 3}) EXPECT_EQ(kept(labels, truth.labels, id), 1.0) << id;
  EXPECT_LT(differing(labels, truth.labels), 0.001);

  // The same through a scene's files, as eval --align-truth reads them.
  const testing::TempDir dir;
  writePly(dir / "scene_gt.ply", truth);
  const GroundTruthObjects plain = truthFromMesh(dir / "scene_gt.ply", fused);
  const GroundTruthObjects aligned = truthFromMesh(dir / "scene_gt.ply", fused, true);
  const auto cube =
      static_cast<std::size_t>(std::count(truth.labels.begin(), truth.labels.end(), 2));
  EXPECT_EQ(cube, 16u) << "4 x 4 vertices on its top";
  EXPECT_LT(plain.objectSize(2), cube / 2);
  EXPECT_EQ(aligned.objectSize(2), cube);
}

TEST(AlignToTruth, AMeshInPlaceStaysThere) {
  const TriangleMesh truth = floorWithBoxes();
  const TruthAlignment a = alignToTruth(truth, truth);
  EXPECT_TRUE(a.converged);
  EXPECT_LE(a.iterations, 2);
  EXPECT_LT(a.moved_m, 1e-5f);
  EXPECT_LT(a.rms_after_m, 1e-5f);
}

TEST(AlignToTruth, ALonePlaneMovesBackAlongItsNormalWithoutSliding) {
  // A tilted plane leaves three motions free (along it, and turning about its normal): the fit
  // must not wander along them.
  TriangleMesh truth =
      testing::makeHeightField(41, 0.3f, [](float x, float y) { return 0.2f * x + 0.1f * y; });
  truth.labels.assign(truth.positions.size(), 0);
  const Eigen::Vector3f normal = Eigen::Vector3f(-0.2f, -0.1f, 1.0f).normalized();
  TriangleMesh fused = truth;
  for (Eigen::Vector3f& p : fused.positions) p += 0.005f * normal;
  const TruthAlignment a = alignToTruth(fused, truth);
  EXPECT_TRUE(a.converged);
  EXPECT_LE(a.iterations, 5);
  for (const Eigen::Vector3f& p : fused.positions) {
    ASSERT_LT((a.T_truth_mesh * p - (p - 0.005f * normal)).norm(), 0.0001f) << "0.1 mm";
  }
}

TEST(TransferVertexLabels, EachVertexTakesTheNearestLabelledVertexWithinOneAndAHalfCentimetres) {
  // A hand-labelled fusion: three vertices, the last one ignored (a plant, say).
  TriangleMesh labelled;
  labelled.positions = {{0, 0, 0}, {0.1f, 0, 0}, {0.2f, 0, 0}};
  labelled.labels = {0, 10, 20};
  labelled.ignore = {0, 0, 1};
  TriangleMesh other;
  other.positions = {
      {0.005f, 0, 0},          // 5 mm from the background vertex
      {0.1f, 0.014f, 0},       // 14 mm from object 10
      {0.21f, 0, 0},           // 1 cm from the ignored vertex: ignored too
      {0.1f, 0.016f, 0},       // 16 mm from object 10: too far, so ignored
  };
  const LabelTransfer t = transferVertexLabels(other, labelled);
  EXPECT_EQ(t.labels, (std::vector<std::int32_t>{0, 10, 20, 0}));
  EXPECT_EQ(t.ignore, (std::vector<std::uint8_t>{0, 0, 1, 1}));
  labelled.labels.clear();
  EXPECT_THROW(transferVertexLabels(other, labelled), std::invalid_argument);
}

TEST(GroundTruthObjects, IgnoredVerticesCountInNoObjectAndNoHypothesis) {
  // Vertices 0-9: object 1, of which 8 and 9 ignored (the band where it meets the table);
  // 10-19: background, of which 15-19 ignored (a plant).
  std::vector<std::int32_t> labels(20, 0);
  for (int v = 0; v < 10; ++v) labels[v] = 1;
  std::vector<std::uint8_t> ignore(20, 0);
  for (int v : {8, 9, 15, 16, 17, 18, 19}) ignore[static_cast<std::size_t>(v)] = 1;
  const GroundTruthObjects truth(labels, ignore);
  EXPECT_EQ(truth.objectSize(1), 8u);
  // Object 1 with its ignored band and the plant: IoU 8 / 8.
  const ObjectMatch a = truth.bestMatch({0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 15, 16});
  EXPECT_EQ(a.object_id, 1);
  EXPECT_DOUBLE_EQ(a.iou, 1.0);
  // Half the object and two counted background vertices: 4 / (6 + 8 - 4).
  EXPECT_DOUBLE_EQ(truth.bestMatch({0, 1, 2, 3, 10, 11}).iou, 0.4);
  EXPECT_DOUBLE_EQ(truth.ignoredShare({15, 16, 17, 10}), 0.75);
  EXPECT_DOUBLE_EQ(GroundTruthObjects(labels).ignoredShare({15, 16}), 0.0);
  EXPECT_THROW(GroundTruthObjects(labels, std::vector<std::uint8_t>(3, 0)), std::invalid_argument);
}

TEST(GroundTruthObjects, BestMatchIsTheObjectWithTheHighestVertexIoU) {
  // Vertices 0-9: object 1; 10-13: object 2; 14-19: none.
  std::vector<std::int32_t> labels(20, 0);
  for (int v = 0; v < 10; ++v) labels[v] = 1;
  for (int v = 10; v < 14; ++v) labels[v] = 2;
  const GroundTruthObjects truth(labels);
  EXPECT_EQ(truth.objectIds(), (std::vector<std::int32_t>{1, 2}));
  EXPECT_EQ(truth.objectSize(1), 10u);
  EXPECT_EQ(truth.objectSize(5), 0u);

  // 8 of object 1 and 2 others: IoU 8 / (10 + 10 - 8) = 2/3.
  const ObjectMatch a = truth.bestMatch({0, 1, 2, 3, 4, 5, 6, 7, 14, 15});
  EXPECT_EQ(a.object_id, 1);
  EXPECT_NEAR(a.iou, 8.0 / 12.0, 1e-12);
  EXPECT_FALSE(isObject(a));
  EXPECT_TRUE(isObject(a, 0.5));
  // All of object 2 and one more vertex: 4 / 5.
  const ObjectMatch b = truth.bestMatch({10, 11, 12, 13, 16});
  EXPECT_EQ(b.object_id, 2);
  EXPECT_NEAR(b.iou, 0.8, 1e-12);
  EXPECT_TRUE(isObject(b));
  EXPECT_TRUE(isObject(b, 0.8));
  // Touching no object.
  EXPECT_EQ(truth.bestMatch({15, 16}).object_id, 0);
  EXPECT_THROW(truth.bestMatch({25}), std::invalid_argument);
  EXPECT_THROW(GroundTruthObjects({0, -1}), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::discovery
