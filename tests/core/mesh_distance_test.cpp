#include "objscan/core/mesh_distance.h"

#include <gtest/gtest.h>

#include <random>

#include "test_support.h"

namespace objscan {
namespace {

TEST(MeshDistance, MatchesBruteForceNearARandomMesh) {
  // A 50 cm tangle of 120 random triangles.
  std::mt19937 make(3);
  std::uniform_real_distribution<float> coord(-0.25f, 0.25f);
  TriangleMesh small;
  for (int i = 0; i < 60; ++i) small.positions.emplace_back(coord(make), coord(make), coord(make));
  for (int t = 0; t < 120; ++t)
    small.triangles.emplace_back(t % 60, (t * 7 + 1) % 60, (t * 13 + 2) % 60);
  const float radius = 0.02f;
  const MeshDistance grid(small, radius);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  int found = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3f p(u(rng), u(rng), u(rng));
    float brute = std::numeric_limits<float>::infinity();
    for (const auto& t : small.triangles) {
      const Eigen::Vector3f q = MeshDistance::closestOnTriangle(
          p, small.positions[t[0]], small.positions[t[1]], small.positions[t[2]]);
      brute = std::min(brute, (q - p).norm());
    }
    const MeshDistance::Closest c = grid.closest(p);
    if (brute <= radius) {
      ++found;
      ASSERT_FLOAT_EQ(c.distance_m, brute) << "query " << i;
    } else {
      ASSERT_EQ(c.triangle, -1) << "nothing within the radius";
    }
  }
  EXPECT_GT(found, 200);
}

TEST(MeshDistance, RefusesMeshesBeyondTheGrid) {
  TriangleMesh far;
  far.positions = {{0, 0, 0}, {1e9f, 0, 0}, {0, 1, 0}};
  far.triangles = {{0, 1, 2}};
  EXPECT_THROW(MeshDistance(far, 0.001f), std::invalid_argument);
}

TEST(MeshDistance, ClosestPointOnTriangleRegions) {
  const Eigen::Vector3f a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  auto at = [&](float x, float y, float z) {
    return MeshDistance::closestOnTriangle({x, y, z}, a, b, c);
  };
  EXPECT_TRUE(at(0.2f, 0.2f, 5.0f).isApprox(Eigen::Vector3f(0.2f, 0.2f, 0)));  // face
  EXPECT_EQ(at(-1, -1, 0), a);                                                 // vertex regions
  EXPECT_EQ(at(2, -1, 0), b);
  EXPECT_EQ(at(-1, 2, 0), c);
  EXPECT_EQ(at(0.5f, -1, 0), Eigen::Vector3f(0.5f, 0, 0));            // edge ab
  EXPECT_TRUE(at(1, 1, 0).isApprox(Eigen::Vector3f(0.5f, 0.5f, 0)));  // edge bc
}

}  // namespace
}  // namespace objscan
