#include "objscan/core/triangle_mesh.h"

#include <gtest/gtest.h>

#include <limits>

#include "test_support.h"

namespace objscan {
namespace {

void expectInvalid(const TriangleMesh& m, const std::string& needle) {
  try {
    m.validate();
    ADD_FAILURE() << "validate() accepted a mesh that should fail with: " << needle;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(TriangleMesh, ValidCubePasses) { EXPECT_NO_THROW(testing::makeCube().validate()); }

TEST(TriangleMesh, ValidateRejectsNonFinitePositionsAndNormals) {
  TriangleMesh m = testing::makeCube();
  m.positions[3].y() = std::numeric_limits<float>::quiet_NaN();
  expectInvalid(m, "vertex 3 has a non-finite position");
  m = testing::makeCube();
  m.normals.assign(8, Eigen::Vector3f::UnitZ());
  m.normals[6].x() = std::numeric_limits<float>::infinity();
  expectInvalid(m, "vertex 6 has a non-finite normal");
}

TEST(TriangleMesh, ValidateRejectsIndicesOutOfRange) {
  TriangleMesh m = testing::makeCube();
  m.triangles[4] = {0, 8, 1};
  expectInvalid(m, "triangle 4 refers to vertex 8, but the mesh has 8 vertices");
  m.triangles[4] = {-1, 2, 1};
  expectInvalid(m, "refers to vertex -1");
}

TEST(TriangleMesh, ValidateRejectsDegenerateTriangles) {
  TriangleMesh m = testing::makeCube();
  m.triangles[2] = {5, 1, 5};
  expectInvalid(m, "triangle 2 is degenerate");
}

TEST(TriangleMesh, ValidateRejectsAttributeCountMismatch) {
  TriangleMesh m = testing::makeCube();
  m.normals.assign(7, Eigen::Vector3f::UnitZ());
  expectInvalid(m, "7 normals for 8 vertices");
  m = testing::makeCube();
  m.colors.assign(9, Rgb8(1, 2, 3));
  expectInvalid(m, "9 colours for 8 vertices");
  m = testing::makeCube();
  m.labels.assign(3, 1);
  expectInvalid(m, "3 labels for 8 vertices");
  m = testing::makeCube();
  m.weights.assign(9, 1.0f);
  expectInvalid(m, "9 weights for 8 vertices");
  m = testing::makeCube();
  m.ignore.assign(2, 1);
  expectInvalid(m, "2 ignore flags for 8 vertices");
}

TEST(TriangleMesh, ValidateRejectsWeightsThatAreNotFiniteOrAreNegative) {
  TriangleMesh m = testing::makeCube();
  m.weights.assign(8, 0.0f);  // zero is a weight: never observed
  EXPECT_NO_THROW(m.validate());
  m.weights[5] = std::numeric_limits<float>::quiet_NaN();
  expectInvalid(m, "vertex 5 has the weight nan");
  m.weights[5] = std::numeric_limits<float>::infinity();
  expectInvalid(m, "vertex 5 has the weight inf");
  m.weights[5] = -1.0f;
  expectInvalid(m, "vertex 5 has the weight -1");
}

TEST(TriangleMesh, CubeBoundsAndAreaAreExact) {
  const TriangleMesh m = testing::makeCube(2.0f);
  EXPECT_EQ(m.bounds().min(), Eigen::Vector3f(-1, -1, -1));
  EXPECT_EQ(m.bounds().max(), Eigen::Vector3f(1, 1, 1));
  EXPECT_DOUBLE_EQ(m.surfaceArea(), 24.0);  // 6 faces of 2 x 2 m
  EXPECT_TRUE(TriangleMesh{}.bounds().isEmpty());
}

TEST(TriangleMesh, CubeTrianglesFaceOutwards) {
  const TriangleMesh m = testing::makeCube();
  for (const auto& t : m.triangles) {
    const Eigen::Vector3f a = m.positions[t[0]], b = m.positions[t[1]], c = m.positions[t[2]];
    const Eigen::Vector3f normal = (b - a).cross(c - a);
    EXPECT_GT(normal.dot((a + b + c) / 3.0f), 0.0f) << t.transpose();
  }
}

TEST(TriangleMesh, SubsetKeepsTheVerticesAttributesAndInnerTriangles) {
  // A 3 x 3 vertex grid, two triangles per cell; labels = vertex index.
  TriangleMesh m = testing::makeHeightField(3, 1.0f, [](float, float) { return 0.0f; });
  m.colors.assign(9, Rgb8(1, 2, 3));
  m.labels = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  m.weights = {0.5f, 1.5f, 2.5f, 3.5f, 4.5f, 5.5f, 6.5f, 7.5f, 8.5f};
  m.ignore = {1, 0, 0, 1, 0, 0, 1, 0, 0};
  // The left two columns: vertices 0, 1, 3, 4, 6, 7 (rows of 3): the two left cells, 4 triangles.
  const TriangleMesh s = m.subset({0, 1, 3, 4, 6, 7});
  ASSERT_EQ(s.positions.size(), 6u);
  EXPECT_EQ(s.positions[2], m.positions[3]);
  EXPECT_EQ(s.normals[5], m.normals[7]);
  EXPECT_EQ(s.labels, (std::vector<std::int32_t>{0, 1, 3, 4, 6, 7}));
  EXPECT_EQ(s.weights, (std::vector<float>{0.5f, 1.5f, 3.5f, 4.5f, 6.5f, 7.5f}));
  EXPECT_EQ(s.ignore, (std::vector<std::uint8_t>{1, 0, 1, 0, 1, 0}));
  EXPECT_EQ(s.colors.size(), 6u);
  EXPECT_EQ(s.triangles.size(), 4u);
  EXPECT_NO_THROW(s.validate());
  EXPECT_NEAR(s.surfaceArea(), m.surfaceArea() / 2, 1e-6);
  EXPECT_THROW(m.subset({3, 1}), std::invalid_argument);
  EXPECT_THROW(m.subset({9}), std::invalid_argument);
  // A mesh without weights or flags gives a subset without them.
  m.weights.clear();
  m.ignore.clear();
  const TriangleMesh bare = m.subset({0, 1, 3});
  EXPECT_FALSE(bare.hasWeights());
  EXPECT_FALSE(bare.hasIgnore());
}

TEST(MeshSubsets, ManyPartsOfOneMeshAreWhatSubsetGives) {
  // A random mesh (awkward floats, triangles in no order), every third vertex and a run of them.
  const TriangleMesh m = testing::makeRandomMesh(7, 300, 900);
  const MeshSubsets parts(m);
  std::vector<std::int32_t> thirds, run, all;
  for (std::int32_t v = 0; v < 300; ++v) {
    if (v % 3 == 0) thirds.push_back(v);
    if (v >= 40 && v < 200) run.push_back(v);
    all.push_back(v);
  }
  for (const auto& part : {thirds, run, all, std::vector<std::int32_t>{}}) {
    // Against the rule itself: the triangles whose three vertices are in the part, in the mesh's
    // order, each vertex renumbered to its place in the part.
    std::vector<std::int32_t> place(m.positions.size(), -1);
    for (std::size_t i = 0; i < part.size(); ++i) place[part[i]] = static_cast<std::int32_t>(i);
    std::vector<Eigen::Vector3i> inner;
    for (const Eigen::Vector3i& t : m.triangles) {
      const Eigen::Vector3i r(place[t[0]], place[t[1]], place[t[2]]);
      if (r.minCoeff() >= 0) inner.push_back(r);
    }
    const TriangleMesh s = parts.subset(part);
    EXPECT_EQ(s.triangles, inner);
    ASSERT_EQ(s.positions.size(), part.size());
    for (std::size_t i = 0; i < part.size(); ++i) {
      EXPECT_EQ(s.positions[i], m.positions[part[i]]);
      EXPECT_EQ(s.colors[i], m.colors[part[i]]);
      EXPECT_EQ(s.labels[i], m.labels[part[i]]);
    }
  }
  EXPECT_EQ(parts.subset(all), m);
  EXPECT_THROW(parts.subset({5, 5}), std::invalid_argument);
  EXPECT_THROW(parts.subset({300}), std::invalid_argument);

  // A degenerate triangle (a vertex twice) is kept like any other; one with an index outside the
  // mesh is in no part.
  TriangleMesh odd = m;
  odd.triangles.emplace_back(4, 4, 10);
  odd.triangles.emplace_back(4, 10, 300);
  const TriangleMesh s = MeshSubsets(odd).subset({4, 10});
  ASSERT_EQ(s.triangles.size(), 1u);
  EXPECT_EQ(s.triangles[0], Eigen::Vector3i(0, 0, 1));
}

}  // namespace
}  // namespace objscan
