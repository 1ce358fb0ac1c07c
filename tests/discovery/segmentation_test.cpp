// The mesh graph's edge weights (the paper's Eq. 1) and Felzenszwalb-Huttenlocher segmentation on
// surfaces whose right split is known.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <random>
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

TEST(MeshGraph, EdgesMatchABruteForceListOnARandomMesh) {
  const TriangleMesh mesh = objscan::testing::makeRandomMesh(7, 300, 900, true, false);
  std::set<std::pair<std::int32_t, std::int32_t>> expected;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      expected.emplace(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
    }
  }
  const MeshGraph graph = buildMeshGraph(mesh);
  ASSERT_EQ(graph.edges.size(), expected.size());
  std::size_t e = 0;
  for (const auto& [a, b] : expected) {  // the set's order is (a, b)'s
    const MeshEdge& edge = graph.edges[e++];
    ASSERT_EQ(edge.a, a);
    ASSERT_EQ(edge.b, b);
    const auto i = static_cast<std::size_t>(a), j = static_cast<std::size_t>(b);
    EXPECT_EQ(edge.convex,
              isConvex(mesh.positions[i], mesh.normals[i], mesh.positions[j], mesh.normals[j]));
    EXPECT_EQ(edge.weight, edgeWeight(mesh.normals[i], mesh.normals[j], edge.convex));
  }
}

/// Felzenszwalb-Huttenlocher as plainly as it can be written: the edges sorted by (weight, index)
/// with std::sort, union-find with path halving and union by size, every edge looked at in both
/// passes; labels in order of each segment's first vertex.
std::vector<std::int32_t> referenceLabels(const MeshGraph& graph, float scale,
                                          std::size_t min_size) {
  std::vector<std::size_t> order(graph.edges.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    const float wx = graph.edges[x].weight, wy = graph.edges[y].weight;
    return wx < wy || (wx == wy && x < y);
  });
  std::vector<std::int32_t> parent(graph.vertex_count);
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<std::size_t> size(graph.vertex_count, 1);
  std::vector<float> internal(graph.vertex_count, 0.0f);
  const auto find = [&](std::int32_t x) {
    while (parent[static_cast<std::size_t>(x)] != x) {
      parent[static_cast<std::size_t>(x)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(x)])];
      x = parent[static_cast<std::size_t>(x)];
    }
    return static_cast<std::size_t>(x);
  };
  const auto join = [&](std::size_t a, std::size_t b, float w) {
    if (size[a] < size[b]) std::swap(a, b);
    parent[b] = static_cast<std::int32_t>(a);
    size[a] += size[b];
    internal[a] = w;
  };
  for (std::size_t e : order) {
    const MeshEdge& edge = graph.edges[e];
    const std::size_t a = find(edge.a), b = find(edge.b);
    if (a != b && edge.weight <= std::min(internal[a] + scale / static_cast<float>(size[a]),
                                          internal[b] + scale / static_cast<float>(size[b]))) {
      join(a, b, edge.weight);
    }
  }
  for (std::size_t e : order) {
    const MeshEdge& edge = graph.edges[e];
    const std::size_t a = find(edge.a), b = find(edge.b);
    if (a != b && (size[a] < min_size || size[b] < min_size)) {
      join(a, b, std::max({edge.weight, internal[a], internal[b]}));
    }
  }
  std::vector<std::int32_t> labels(graph.vertex_count), label_of_root(graph.vertex_count, -1);
  std::int32_t next = 0;
  for (std::size_t v = 0; v < graph.vertex_count; ++v) {
    const std::size_t root = find(static_cast<std::int32_t>(v));
    if (label_of_root[root] < 0) label_of_root[root] = next++;
    labels[v] = label_of_root[root];
  }
  return labels;
}

TEST(Segmentation, MatchesAPlainReferenceWithTiedNegativeAndSignedZeroWeights) {
  // A 40 x 40 grid graph whose weights come from a short list, so that most are tied with
  // others and their order decides the merges; -0 and +0 are the same weight.
  const int n = 40;
  MeshGraph graph;
  graph.vertex_count = n * n;
  const float values[] = {-0.5f, -0.0f, 0.0f, 0.001f, 0.25f, 0.25f, 1.0f, 3.0f};
  std::mt19937 random(3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int v = y * n + x;
      for (int w : {x + 1 < n ? v + 1 : -1, y + 1 < n ? v + n : -1}) {
        if (w >= 0) graph.edges.push_back({v, w, values[random() % 8], false});
      }
    }
  }
  for (float scale : {0.0f, 0.3f, 2.0f, 40.0f}) {
    for (std::size_t min_size : {1u, 5u, 60u}) {
      const Segmentation s = segmentGraph(graph, scale, min_size);
      EXPECT_EQ(s.labels, referenceLabels(graph, scale, min_size))
          << "scale " << scale << ", min_size " << min_size;
    }
  }
  // And on a real surface, every scale of segmentAtScales.
  const TriangleMesh mesh = makeHeightField(61, 0.1f, [](float x, float y) {
    return 0.01f * std::sin(60.0f * x) * std::cos(40.0f * y) + bump(x, y);
  });
  const MeshGraph surface = buildMeshGraph(mesh);
  const std::vector<float> scales = {0.01f, 0.1f, 1.0f, 10.0f};
  const std::vector<Segmentation> all = segmentAtScales(surface, scales, 30);
  for (std::size_t i = 0; i < scales.size(); ++i) {
    EXPECT_EQ(all[i].labels, referenceLabels(surface, scales[i], 30)) << "scale " << scales[i];
  }
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
  EXPECT_THROW(segmentAtScales(graph, {1.0f, -1.0f}, 30), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::discovery
