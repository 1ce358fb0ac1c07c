// The mesh graph's edge weights (the paper's Eq. 1) and Felzenszwalb-Huttenlocher segmentation on
// surfaces whose right split is known.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <stdexcept>
#include <vector>

#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segmentation.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

using objscan::testing::makeHeightField;

/// A 2 cm tall, flat-topped bump of radius 4 cm on a 20 x 20 cm table: its rim is convex, its
/// foot (where it meets the table) concave.
float bump(float x, float y) {
  const float r = std::sqrt(x * x + y * y);
  const float t = std::clamp((0.05f - r) / 0.02f, 0.0f, 1.0f);  // 1 inside 3 cm, 0 beyond 5 cm
  return 0.02f * t * t * (3.0f - 2.0f * t);                     // smoothstep
}

TEST(MeshGraph, EdgeWeightsFollowEquationOne) {
  const Eigen::Vector3f up(0, 0, 1);
  // Flat: weight 0 and not convex.
  EXPECT_FALSE(isConvex({0, 0, 0}, up, {1, 0, 0}, up));
  EXPECT_EQ(edgeWeight(up, up, false), 0.0f);
  // A ridge (normals tilting apart away from the edge) is convex, a valley concave, whichever end
  // is read first.
  const Eigen::Vector3f left = Eigen::Vector3f(-0.5f, 0, 1).normalized();
  const Eigen::Vector3f right = Eigen::Vector3f(0.5f, 0, 1).normalized();
  EXPECT_TRUE(isConvex({-1, 0, 0}, left, {1, 0, 0}, right));
  EXPECT_TRUE(isConvex({1, 0, 0}, right, {-1, 0, 0}, left));
  EXPECT_FALSE(isConvex({-1, 0, 0}, right, {1, 0, 0}, left));
  const float d = 1.0f - left.dot(right);  // 0.4 for these normals
  EXPECT_NEAR(d, 0.4f, 1e-6f);
  EXPECT_FLOAT_EQ(edgeWeight(left, right, true), d * d);
  EXPECT_FLOAT_EQ(edgeWeight(left, right, false), d);
}

TEST(MeshGraph, EveryTriangleEdgeOnceWithItsWeight) {
  const TriangleMesh grid = makeHeightField(3, 1.0f, [](float, float) { return 0.0f; });
  const MeshGraph graph = buildMeshGraph(grid);
  EXPECT_EQ(graph.vertex_count, 9u);
  // A 2 x 2-cell grid: 12 grid lines plus 4 diagonals.
  ASSERT_EQ(graph.edges.size(), 16u);
  std::set<std::pair<int, int>> seen;
  for (const MeshEdge& e : graph.edges) {
    EXPECT_LT(e.a, e.b);
    EXPECT_TRUE(seen.emplace(e.a, e.b).second);
    EXPECT_EQ(e.weight, 0.0f);  // a plane
  }
  TriangleMesh no_normals = grid;
  no_normals.normals.clear();
  EXPECT_THROW(buildMeshGraph(no_normals), std::invalid_argument);
}

TEST(Segmentation, SplitsABumpFromItsTableAtTheConcaveFoot) {
  const TriangleMesh mesh = makeHeightField(81, 0.1f, bump);  // 2.5 mm spacing
  const MeshGraph graph = buildMeshGraph(mesh);
  const Segmentation s = segmentGraph(graph, 0.5f, 50);
  // The bump's top and the table's corner end up apart; the top and the rim stay together.
  const auto labelAt = [&](float x, float y) {
    std::size_t best = 0;
    float best_d = 1e9f;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      const float d = (mesh.positions[v].head<2>() - Eigen::Vector2f(x, y)).norm();
      if (d < best_d) {
        best_d = d;
        best = v;
      }
    }
    return s.labels[best];
  };
  EXPECT_NE(labelAt(0, 0), labelAt(0.09f, 0.09f));
  EXPECT_EQ(labelAt(0, 0), labelAt(0.035f, 0));  // on the convex rim
  EXPECT_EQ(labelAt(0.09f, 0.09f), labelAt(-0.09f, 0.09f));
  // The bump's segment holds at least everything within 4 cm of its centre (its top and rim).
  std::size_t top_size = 0;
  for (std::int32_t l : s.labels) top_size += l == labelAt(0, 0) ? 1 : 0;
  std::size_t inside = 0;
  for (const Eigen::Vector3f& p : mesh.positions) inside += p.head<2>().norm() < 0.04f ? 1 : 0;
  EXPECT_GE(top_size, inside);
}

TEST(Segmentation, LargerScalesGiveFewerSegmentsAndSmallOnesAreMerged) {
  const TriangleMesh mesh = makeHeightField(61, 0.1f, [](float x, float y) {
    return 0.01f * std::sin(60.0f * x) * std::cos(40.0f * y);  // a bumpy sheet
  });
  const MeshGraph graph = buildMeshGraph(mesh);
  const std::vector<Segmentation> s = segmentAtScales(graph, {0.01f, 0.1f, 1.0f, 100.0f}, 30);
  ASSERT_EQ(s.size(), 4u);
  for (std::size_t i = 1; i < s.size(); ++i) {
    EXPECT_LE(s[i].segment_count, s[i - 1].segment_count) << "scale " << s[i].scale;
  }
  EXPECT_EQ(s.back().segment_count, 1u);
  for (const Segmentation& seg : s) {
    std::map<std::int32_t, std::size_t> sizes;
    for (std::int32_t l : seg.labels) ++sizes[l];
    EXPECT_EQ(sizes.size(), seg.segment_count);
    for (const auto& [label, size] : sizes) EXPECT_GE(size, 30u) << "scale " << seg.scale;
  }
  EXPECT_THROW(segmentGraph(graph, -1.0f, 30), std::invalid_argument);
  EXPECT_THROW(segmentGraph(graph, std::nanf(""), 30), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::discovery
