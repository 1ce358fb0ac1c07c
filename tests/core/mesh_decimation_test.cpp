// decimateByClustering: the preview objscan view and the report draw of a large mesh.

#include "objscan/core/mesh_decimation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <set>

#include "objscan/core/mesh_distance.h"
#include "test_support.h"

namespace objscan {
namespace {

/// A wavy 1 m square, n × n vertices, coloured by x.
TriangleMesh wave(int n) {
  TriangleMesh mesh = testing::makeHeightField(
      n, 0.5f, [](float x, float y) { return 0.05f * std::sin(8 * x) * std::cos(6 * y); });
  mesh.computeNormals();
  for (const Eigen::Vector3f& p : mesh.positions) {
    const auto r = static_cast<std::uint8_t>(std::lround(255 * (p.x() + 0.5f)));
    mesh.colors.emplace_back(r, 40, 255 - r);
  }
  return mesh;
}

TEST(DecimateByClustering, AMeshWithinTheLimitIsReturnedAsItIs) {
  const TriangleMesh mesh = wave(50);
  const DecimatedMesh d = decimateByClustering(mesh, mesh.triangles.size());
  EXPECT_EQ(d.mesh, mesh);
  std::vector<std::int32_t> identity(mesh.positions.size());
  std::iota(identity.begin(), identity.end(), 0);
  EXPECT_EQ(d.vertex_map, identity);
  EXPECT_EQ(d.cell_m, 0.0f);
  EXPECT_THROW(decimateByClustering(mesh, 0), std::invalid_argument);
}

TEST(DecimateByClustering, FitsTheLimitStaysOnTheSurfaceAndMapsEveryVertex) {
  const TriangleMesh mesh = wave(250);  // 124,002 triangles
  for (const std::size_t limit : {30000u, 4000u}) {
    const DecimatedMesh d = decimateByClustering(mesh, limit);
    ASSERT_NO_THROW(d.mesh.validate());
    EXPECT_LE(d.mesh.triangles.size(), limit);
    // Not far below it either: the cell grows by a quarter at a time, so at worst it has
    // (1/1.25)^2 = 64 % of the triangles it could have (and clustering loses a little more).
    EXPECT_GE(d.mesh.triangles.size(), limit / 2) << limit;
    ASSERT_EQ(d.vertex_map.size(), mesh.positions.size());
    std::set<std::int32_t> used;
    for (const Eigen::Vector3i& t : d.mesh.triangles) used.insert({t[0], t[1], t[2]});
    EXPECT_EQ(used.size(), d.mesh.positions.size()) << "every preview vertex is used";
    // Each vertex goes to a preview vertex within its cell's diagonal.
    const float reach = std::sqrt(3.0f) * d.cell_m;
    std::size_t unmapped = 0;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      const std::int32_t p = d.vertex_map[v];
      if (p < 0) {
        ++unmapped;
        continue;
      }
      ASSERT_LT(p, static_cast<std::int32_t>(d.mesh.positions.size()));
      EXPECT_LE((mesh.positions[v] - d.mesh.positions[static_cast<std::size_t>(p)]).norm(), reach)
          << v;
    }
    EXPECT_LT(unmapped, mesh.positions.size() / 100) << "only vertices of collapsed triangles";
    // The preview lies on the surface, within a cell (the wave bends less than that). The look-up
    // reaches just that far (a farther vertex finds nothing, at infinity, and fails): a wider
    // reach made this check most of the test's time under the sanitizers.
    const MeshDistance surface(mesh, 1.01f * d.cell_m);
    for (const Eigen::Vector3f& p : d.mesh.positions) {
      EXPECT_LE(surface.closest(p).distance_m, d.cell_m);
    }
    // Colours are averages of neighbours: the left edge stays red-ish, the right blue-ish.
    const Eigen::AlignedBox3f box = d.mesh.bounds();
    for (std::size_t i = 0; i < d.mesh.positions.size(); ++i) {
      const float x = d.mesh.positions[i].x();
      if (x < box.min().x() + 0.05f) {
        EXPECT_LT(d.mesh.colors[i][0], 40);
      }
      if (x > box.max().x() - 0.05f) {
        EXPECT_GT(d.mesh.colors[i][0], 215);
      }
      EXPECT_NEAR(d.mesh.normals[i].norm(), 1.0f, 1e-4f);
    }
  }
}

TEST(DecimateByClustering, WeightsAreAveragedAndIgnoreFlagsKept) {
  TriangleMesh mesh = wave(80);
  for (const Eigen::Vector3f& p : mesh.positions) {
    mesh.weights.push_back(1.0f + 10.0f * (p.x() + 0.5f));  // 1 .. 11 across the square
    mesh.ignore.push_back(p.x() < 0.0f ? 1 : 0);
  }
  const DecimatedMesh d = decimateByClustering(mesh, 2000);
  ASSERT_GT(d.cell_m, 0.0f) << "clustered, not copied";
  ASSERT_NO_THROW(d.mesh.validate());
  ASSERT_EQ(d.mesh.weights.size(), d.mesh.positions.size());
  ASSERT_EQ(d.mesh.ignore.size(), d.mesh.positions.size());
  // A cluster's weight is the mean of its members', which all lie within a cell's edge in x; its
  // flag is one member's, so it matches every member's away from x = 0.
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const std::int32_t p = d.vertex_map[v];
    if (p < 0) continue;
    const auto i = static_cast<std::size_t>(p);
    EXPECT_NEAR(d.mesh.weights[i], mesh.weights[v], 10.0f * d.cell_m + 1e-5f) << v;
    if (std::abs(mesh.positions[v].x()) > d.cell_m) {
      EXPECT_EQ(d.mesh.ignore[i], mesh.ignore[v]) << v;
    }
  }
}

}  // namespace
}  // namespace objscan
