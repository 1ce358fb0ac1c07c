#include "objscan/capture/synthetic/shapes.h"

#include <gtest/gtest.h>

#include <map>
#include <numbers>

namespace objscan::capture {
namespace {

/// Volume enclosed by a closed mesh; positive when its triangles face outwards.
double signedVolume(const TriangleMesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) {
    v += m.positions[t[0]].cast<double>().dot(
             m.positions[t[1]].cast<double>().cross(m.positions[t[2]].cast<double>())) /
         6.0;
  }
  return v;
}

/// Every directed edge appears exactly once and its reverse exactly once: closed and
/// consistently oriented.
bool closedAndOriented(const TriangleMesh& m) {
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : m.triangles) {
    for (int k = 0; k < 3; ++k) ++edges[{t[k], t[(k + 1) % 3]}];
  }
  for (const auto& [e, count] : edges) {
    if (count != 1 || edges.count({e.second, e.first}) == 0) return false;
  }
  return true;
}

TEST(Shapes, EveryBuiltinIsAClosedOutwardSolidRestingOnTheGround) {
  ASSERT_EQ(shapes::builtinNames().size(), 11u);
  for (const std::string& name : shapes::builtinNames()) {
    for (const float variation : {0.0f, 0.5f, 0.99f}) {
      SCOPED_TRACE(name + " variation " + std::to_string(variation));
      const TriangleMesh m = shapes::builtin(name, variation);
      ASSERT_NO_THROW(m.validate());
      EXPECT_TRUE(closedAndOriented(m));
      EXPECT_GT(signedVolume(m), 1e-6) << "outward normals enclose a positive volume";
      const Eigen::AlignedBox3f box = m.bounds();
      EXPECT_NEAR(box.min().z(), 0.0f, 1e-6f);
      EXPECT_NEAR(box.min().x() + box.max().x(), 0.0f, 1e-5f);
      EXPECT_NEAR(box.min().y() + box.max().y(), 0.0f, 1e-5f);
      // Household objects: from 5 cm to 50 cm across.
      EXPECT_GT(box.sizes().maxCoeff(), 0.05f);
      EXPECT_LT(box.sizes().maxCoeff(), 0.50f);
    }
  }
  EXPECT_THROW(shapes::builtin("teapot"), std::invalid_argument);
}

TEST(Shapes, LatheCylinderHasTheAnalyticVolume) {
  // r = 0.1, h = 0.2 with 256 segments: the inscribed polygon's area is
  // (n/2) r^2 sin(2 pi / n), within 0.01 % of pi r^2.
  const int n = 256;
  const TriangleMesh m = shapes::lathe({{0, 0}, {0.1f, 0}, {0.1f, 0.2f}, {0, 0.2f}}, n);
  const double expected = 0.5 * n * 0.01 * std::sin(2.0 * std::numbers::pi / n) * 0.2;
  EXPECT_NEAR(signedVolume(m), expected, 1e-9);
  EXPECT_TRUE(closedAndOriented(m));
}

TEST(Shapes, BoxAndTubeAreClosedWithTheRightVolume) {
  EXPECT_NEAR(signedVolume(shapes::box(0.1f, 0.2f, 0.3f)), 0.006, 1e-9);
  const TriangleMesh straight =
      shapes::tube([](float t) { return Eigen::Vector3f(0, 0, 0.5f * t); },
                   [](float) { return 0.05f; }, 10, 128);
  EXPECT_TRUE(closedAndOriented(straight));
  EXPECT_NEAR(signedVolume(straight), std::numbers::pi * 0.05 * 0.05 * 0.5, 2e-5);
}

}  // namespace
}  // namespace objscan::capture
