// The 3-D view's mesh: the OSVM bytes mesh_view.js decodes, and the ranks painted on it.

#include "objscan/report/mesh_view.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include "test_support.h"

namespace objscan::report {
namespace {

template <typename T>
T at(const std::string& bytes, std::size_t offset) {
  T v{};
  std::memcpy(&v, bytes.data() + offset, sizeof v);
  return v;
}

HypothesisRecord hypothesis(std::size_t rank, std::vector<std::int32_t> vertices,
                            std::string scene = "scene.ply") {
  HypothesisRecord h;
  h.rank = rank;
  h.scene = std::move(scene);
  h.vertices = std::move(vertices);
  return h;
}

TEST(MeshViewPayload, HoldsPositionsColoursRanksAndTrianglesWhereTheHeaderSays) {
  TriangleMesh mesh = testing::makeCube(0.2f);  // 8 vertices, 12 triangles
  for (std::size_t v = 0; v < mesh.positions.size(); ++v)
    mesh.colors.emplace_back(static_cast<std::uint8_t>(v), 2, 3);
  // Vertex 0 is in hypotheses 3 and 1 (1 wins); 7 only in 2; another scene's is ignored.
  const ViewMesh view = viewMesh(mesh,
                                 {hypothesis(3, {0, 1}), hypothesis(1, {0}), hypothesis(2, {7}),
                                  hypothesis(4, {5}, "other.ply")},
                                 "scene.ply", 1000);
  const std::string bytes = meshViewPayload(view);
  const std::size_t n = 8, t = 12;
  ASSERT_EQ(bytes.size(), 20 + n * 12 + n * 4 + n * 2 + t * 12);
  EXPECT_EQ(bytes.substr(0, 4), "OSVM");
  EXPECT_EQ(at<std::uint32_t>(bytes, 4), 1u);
  EXPECT_EQ(at<std::uint32_t>(bytes, 8), n);
  EXPECT_EQ(at<std::uint32_t>(bytes, 12), t);
  EXPECT_EQ(at<std::uint32_t>(bytes, 16), 1u);  // colours
  for (std::size_t v = 0; v < n; ++v) {
    for (int d = 0; d < 3; ++d) EXPECT_EQ(at<float>(bytes, 20 + 12 * v + 4 * d), mesh.positions[v][d]);
    EXPECT_EQ(static_cast<unsigned char>(bytes[20 + 12 * n + 4 * v]), v);
    EXPECT_EQ(static_cast<unsigned char>(bytes[20 + 12 * n + 4 * v + 3]), 255);
  }
  const std::size_t ranks = 20 + 16 * n;
  EXPECT_EQ(at<std::uint16_t>(bytes, ranks + 0), 1);
  EXPECT_EQ(at<std::uint16_t>(bytes, ranks + 2), 3);
  EXPECT_EQ(at<std::uint16_t>(bytes, ranks + 14), 2);
  EXPECT_EQ(at<std::uint16_t>(bytes, ranks + 10), 0) << "another scene's hypothesis";
  const std::size_t triangles = ranks + 2 * n;
  for (std::size_t i = 0; i < t; ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(at<std::uint32_t>(bytes, triangles + 12 * i + 4 * k),
                static_cast<std::uint32_t>(mesh.triangles[i][k]));
    }
  }
  // A hypothesis naming a vertex the mesh lacks is refused, not drawn out of bounds.
  EXPECT_THROW(viewMesh(mesh, {hypothesis(1, {8})}, "scene.ply", 1000), std::invalid_argument);
}

TEST(MeshViewPayload, AnOddVertexCountIsPaddedAndWithoutColoursHasNoColourSection) {
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.triangles = {{0, 1, 2}};
  const std::string bytes = meshViewPayload(viewMesh(mesh, {}, "s", 10));
  EXPECT_EQ(bytes.size(), 20 + 3 * 12 + 4 * 2 + 12u);  // three ranks padded to four
  EXPECT_EQ(at<std::uint32_t>(bytes, 16), 0u);
  EXPECT_EQ(at<std::uint32_t>(bytes, 20 + 36 + 8 + 4), 1u);
}

TEST(MeshViewPayload, ADecimatedPreviewCarriesTheBestRankOfItsClusterAndMapsVertexLists) {
  const TriangleMesh mesh = testing::makeHeightField(200, 0.5f, [](float, float) { return 0.0f; });
  std::vector<std::int32_t> left;
  for (std::int32_t v = 0; v < static_cast<std::int32_t>(mesh.positions.size()); ++v) {
    if (mesh.positions[static_cast<std::size_t>(v)].x() < -0.3f) left.push_back(v);
  }
  const ViewMesh view = viewMesh(mesh, {hypothesis(1, left)}, "scene.ply", 5000);
  ASSERT_LE(view.preview.mesh.triangles.size(), 5000u);
  const std::vector<std::uint32_t> shown = previewVertices(view.preview.vertex_map, left);
  ASSERT_FALSE(shown.empty());
  for (std::size_t i = 1; i < shown.size(); ++i) EXPECT_LT(shown[i - 1], shown[i]);
  std::size_t ranked = 0;
  for (std::size_t p = 0; p < view.ranks.size(); ++p) {
    const bool in = std::binary_search(shown.begin(), shown.end(), static_cast<std::uint32_t>(p));
    EXPECT_EQ(view.ranks[p] == 1, in) << p;
    ranked += view.ranks[p] == 1;
    if (view.ranks[p] == 1) {
      EXPECT_LT(view.preview.mesh.positions[p].x(), -0.28f);
    }
  }
  EXPECT_EQ(ranked, shown.size());
  EXPECT_TRUE(previewVertices(view.preview.vertex_map, {-1, 1 << 30}).empty());
}

}  // namespace
}  // namespace objscan::report
