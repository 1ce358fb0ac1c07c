// Support surfaces (objscan's extension of the paper's segmentation): the table under two mounds
// is found and cut from them, so that segmentation cannot join an object to its support.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>

#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"
#include "objscan/discovery/segmentation.h"
#include "objscan/discovery/supports.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

using objscan::testing::makeHeightField;

/// A low, smooth mound (3 cm tall, radius `radius` with a 4 cm wide foot) centred at (cx, 0).
float mound(float x, float y, float cx, float radius) {
  const float r = std::hypot(x - cx, y);
  const float t = std::clamp((radius - r) / 0.04f, 0.0f, 1.0f);
  return 0.03f * t * t * (3.0f - 2.0f * t);
}

/// An 0.8 x 0.8 m table on a 4 mm grid (40,401 vertices), 0.25 m above the origin, with two mounds.
TriangleMesh tableWithMounds() {
  return makeHeightField(201, 0.4f, [](float x, float y) {
    return 0.25f + std::max(mound(x, y, -0.15f, 0.08f), mound(x, y, 0.15f, 0.06f));
  });
}

/// Vertices raised more than `above` over the table, on the side of x's sign `side`.
std::vector<std::int32_t> raised(const TriangleMesh& mesh, float above, float side) {
  std::vector<std::int32_t> v;
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const Eigen::Vector3f& p = mesh.positions[i];
    if (p.z() > 0.25f + above && p.x() * side > 0.0f) v.push_back(static_cast<std::int32_t>(i));
  }
  return v;
}

TEST(Supports, TheTableIsTheOnlySupportAndTheMoundsAreOffIt) {
  const TriangleMesh mesh = tableWithMounds();
  const MeshGraph graph = buildMeshGraph(mesh);
  const Supports s = findSupports(mesh, graph, SupportConfig{}, 3000);
  ASSERT_EQ(s.planes.size(), 1u);
  const SupportPlane& plane = s.planes[0];
  EXPECT_GT(std::abs(plane.normal.z()), 0.9999f);
  // normal . p + offset = 0 at z = 0.25 m, within 1 mm.
  EXPECT_NEAR(plane.offset / plane.normal.z(), -0.25f, 1e-3f);
  ASSERT_EQ(s.on_support.size(), mesh.positions.size());
  std::size_t flat = 0, flat_on = 0, support = 0;
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const Eigen::Vector3f& p = mesh.positions[i];
    support += s.on_support[i];
    // Everything 1 cm or more above the table is off it, whatever its normal.
    if (p.z() > 0.26f) {
      EXPECT_EQ(s.on_support[i], 0) << "vertex " << i;
    }
    // The flat table, clear of the mounds' feet, is on it.
    if (std::hypot(p.x() + 0.15f, p.y()) > 0.09f && std::hypot(p.x() - 0.15f, p.y()) > 0.07f) {
      ++flat;
      flat_on += s.on_support[i];
    }
  }
  EXPECT_EQ(flat_on, flat);
  EXPECT_EQ(plane.vertex_count, support);
}

TEST(Supports, CutsKeepSegmentationFromJoiningAMoundToItsTable) {
  const TriangleMesh mesh = tableWithMounds();
  MeshGraph graph = buildMeshGraph(mesh);
  // At a huge scale, FH joins everything: without cuts the scene is one segment.
  constexpr float kHuge = 1e6f;
  EXPECT_EQ(segmentGraph(graph, kHuge, 50).segment_count, 1u);

  const Supports s = findSupports(mesh, graph, SupportConfig{}, 3000);
  std::size_t expected = 0;
  for (const MeshEdge& e : graph.edges) {
    expected +=
        s.on_support[static_cast<std::size_t>(e.a)] != s.on_support[static_cast<std::size_t>(e.b)];
  }
  const MeshGraph uncut = graph;
  EXPECT_EQ(cutAtSupports(graph, s.on_support), expected);
  EXPECT_GT(expected, 0u);
  for (std::size_t k = 0; k < graph.edges.size(); ++k) {
    const MeshEdge& e = graph.edges[k];
    const bool across =
        s.on_support[static_cast<std::size_t>(e.a)] != s.on_support[static_cast<std::size_t>(e.b)];
    EXPECT_EQ(std::isinf(e.weight), across) << "edge " << k;
    if (!across) {
      EXPECT_EQ(e.weight, uncut.edges[k].weight) << "edge " << k;
    }
  }

  // With the cuts, even the huge scale leaves each mound on its own (with its rounded foot).
  const Segmentation cut = segmentGraph(graph, kHuge, 50);
  EXPECT_EQ(cut.segment_count, 3u);
  for (float side : {-1.0f, 1.0f}) {
    const std::vector<std::int32_t> body = raised(mesh, 0.005f, side);
    const std::int32_t label = cut.labels[static_cast<std::size_t>(body.front())];
    std::vector<std::int32_t> segment;
    for (std::size_t i = 0; i < cut.labels.size(); ++i) {
      if (cut.labels[i] == label) segment.push_back(static_cast<std::int32_t>(i));
    }
    EXPECT_GE(vertexIoU(segment, body), 0.8) << "mound at x " << 0.15f * side;
    // Everything more than the support distance above the table is in it; nothing at the
    // table's height is.
    const std::vector<std::int32_t> high = raised(mesh, 0.0101f, side);
    EXPECT_TRUE(std::includes(segment.begin(), segment.end(), high.begin(), high.end()));
    for (std::int32_t v : segment) {
      EXPECT_GT(mesh.positions[static_cast<std::size_t>(v)].z(), 0.25f + 1e-6f) << "vertex " << v;
    }
  }
}

/// A shelf's corner: an 0.8 m wide wall (y = 0, facing +y) and floor (z = 0, facing +z), each
/// 0.4 m deep, meeting in a fold rounded to a 12 mm radius, on a 4 mm grid.
TriangleMesh shelfCorner() {
  constexpr float kRadius = 0.012f, kStep = 0.004f, kDepth = 0.4f;
  // The profile in (y, z): down the wall, round the fold, out along the floor.
  std::vector<Eigen::Vector2f> profile;
  for (float z = kDepth; z > kRadius; z -= kStep) profile.emplace_back(0.0f, z);
  for (int k = 0; k < 5; ++k) {
    const float a = static_cast<float>(M_PI) * (1.0f + 0.5f * static_cast<float>(k) / 5.0f);
    profile.emplace_back(kRadius + kRadius * std::cos(a), kRadius + kRadius * std::sin(a));
  }
  for (float y = kRadius; y <= kDepth; y += kStep) profile.emplace_back(y, 0.0f);
  TriangleMesh mesh;
  const int n = 201;
  for (const Eigen::Vector2f& q : profile) {
    for (int i = 0; i < n; ++i) {
      mesh.positions.emplace_back(-0.4f + 0.8f * static_cast<float>(i) / (n - 1), q.x(), q.y());
    }
  }
  testing::addGridTriangles(mesh, static_cast<int>(profile.size()), n);
  mesh.computeNormals();
  return mesh;
}

TEST(Supports, TheFoldBetweenTwoSupportsIsASupportToo) {
  const TriangleMesh mesh = shelfCorner();
  ASSERT_GT(mesh.normals[0].y(), 0.99f);      // the wall faces the room
  ASSERT_GT(mesh.normals.back().z(), 0.99f);  // so does the floor
  const Supports s = findSupports(mesh, buildMeshGraph(mesh), SupportConfig{}, 3000);
  ASSERT_EQ(s.planes.size(), 2u);
  for (const SupportPlane& p : s.planes) {
    EXPECT_GT(std::max(std::abs(p.normal.y()), std::abs(p.normal.z())), 0.9999f);
  }
  // The fold's middle vertices are tilted 25-65 degrees from both planes: on neither plane, but
  // within 1 cm of both. Every vertex ends up on a support, so nothing can join along the fold.
  EXPECT_GE(s.fold_vertices, 201u);
  EXPECT_EQ(s.planes[0].vertex_count + s.planes[1].vertex_count + s.fold_vertices,
            mesh.positions.size());
  EXPECT_EQ(static_cast<std::size_t>(std::count(s.on_support.begin(), s.on_support.end(), 1)),
            mesh.positions.size());
}

TEST(Supports, EveryBoardOfAShelfIsFoundThoughEachIsAFewPercentOfTheScene) {
  // A floor (1.6 m square, 1 cm grid), clutter beside it (500 chips 5 cm square, turned every
  // way: no plane holds a support's worth of them) and three shelf boards 0.24 m square at 0.45,
  // 0.85 and 1.25 m: once the floor is taken, each board is under 4 % of what is left. A plane
  // hypothesis drawn from three points needs all three on one board (1 in 17,000 draws); one vertex
  // with its normal needs 1 in 26.
  TriangleMesh mesh = makeHeightField(161, 0.8f, [](float, float) { return 0.0f; });
  auto append = [&mesh](TriangleMesh part, const Eigen::Vector3f& shift) {
    const std::int32_t first = static_cast<std::int32_t>(mesh.positions.size());
    for (const Eigen::Vector3f& p : part.positions) mesh.positions.push_back(p + shift);
    mesh.normals.insert(mesh.normals.end(), part.normals.begin(), part.normals.end());
    for (const Eigen::Vector3i& t : part.triangles) mesh.triangles.push_back(t.array() + first);
  };
  std::mt19937 random(7);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (int i = 0; i < 500; ++i) {
    TriangleMesh chip = makeHeightField(13, 0.025f, [](float, float) { return 0.0f; });
    const Eigen::Matrix3f turn =
        Eigen::Quaternionf(Eigen::Vector4f(unit(random), unit(random), unit(random), unit(random)))
            .normalized()
            .toRotationMatrix();
    for (std::size_t v = 0; v < chip.positions.size(); ++v) {
      chip.positions[v] = turn * chip.positions[v];
      chip.normals[v] = turn * chip.normals[v];
    }
    append(chip, {2.0f + 0.5f * unit(random), 0.5f * unit(random), 0.75f + 0.75f * unit(random)});
  }
  const float heights[] = {0.45f, 0.85f, 1.25f};
  for (const float h : heights) {
    append(makeHeightField(61, 0.12f, [](float, float) { return 0.0f; }), {-1.2f, 0.0f, h});
  }
  const Supports s = findSupports(mesh, buildMeshGraph(mesh), SupportConfig{}, 3000);
  ASSERT_EQ(s.planes.size(), 4u);
  EXPECT_EQ(s.planes[0].vertex_count, 161u * 161u);  // the floor first, the largest
  for (std::size_t k = 1; k < 4; ++k) {
    EXPECT_GT(std::abs(s.planes[k].normal.z()), 0.9999f);
    EXPECT_EQ(s.planes[k].vertex_count, 61u * 61u);
  }
  std::vector<float> found;
  for (std::size_t k = 1; k < 4; ++k) {
    found.push_back(-s.planes[k].offset / s.planes[k].normal.z());
  }
  std::sort(found.begin(), found.end());
  for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(found[k], heights[k], 1e-3f);
}

TEST(Supports, FollowTheTableWhereFusionBendsIt) {
  // The table of tableWithMounds bent as a fusion bends one (the sensor's fixed depth error,
  // here exaggerated): a bowl 2.2 cm deeper in the middle than at the corners. A plane fitted to
  // it lies some 7 mm over the middle, so the corners are more than 1 cm off it.
  const auto bend = [](float x, float y) { return 0.07f * (x * x + y * y); };
  const TriangleMesh mesh = makeHeightField(201, 0.4f, [&](float x, float y) {
    return 0.25f + bend(x, y) + std::max(mound(x, y, -0.15f, 0.08f), mound(x, y, 0.15f, 0.06f));
  });
  const Supports s = findSupports(mesh, buildMeshGraph(mesh), SupportConfig{}, 3000);
  ASSERT_EQ(s.planes.size(), 1u);
  const SupportPlane& plane = s.planes[0];
  EXPECT_TRUE(plane.curved);
  std::size_t table = 0, table_on = 0, off_the_plane = 0;
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const Eigen::Vector3f& p = mesh.positions[i];
    const float over_table = p.z() - 0.25f - bend(p.x(), p.y());
    // Everything 1 cm or more above the bent table is off it.
    if (over_table > 0.01f) {
      EXPECT_EQ(s.on_support[i], 0) << "vertex " << i << ", " << over_table << " m up";
    }
    if (std::hypot(p.x() + 0.15f, p.y()) > 0.09f && std::hypot(p.x() - 0.15f, p.y()) > 0.07f) {
      // The table clear of the mounds' feet: all of it on the support, and its height over the
      // support's own surface within 1.5 mm of none.
      ++table;
      table_on += s.on_support[i];
      EXPECT_NEAR(plane.height(p), 0.0f, 0.0015f) << p.transpose();
      off_the_plane += std::abs(plane.planeHeight(p)) > 0.01f;
    }
  }
  EXPECT_EQ(table_on, table);
  EXPECT_GT(off_the_plane, table / 50) << "the plane alone would have left the corners out";
  // Beyond the table, the surface goes on along its tangent at the table's edge: the bowl does
  // not climb on as its square would (28 cm deep 2 m out).
  const auto surface = [&](float x, float y) {
    const Eigen::Vector3f p(x, y, 0.25f);
    return plane.planeHeight(p) - plane.height(p);
  };
  for (const Eigen::Vector2f& direction : {Eigen::Vector2f(1, 0), Eigen::Vector2f(0, -1)}) {
    const Eigen::Vector2f edge = 0.4f * direction, inside = 0.39f * direction;
    const Eigen::Vector2f far = 2.0f * direction;
    const float slope = (surface(edge.x(), edge.y()) - surface(inside.x(), inside.y())) / 0.01f;
    EXPECT_NEAR(surface(far.x(), far.y()), surface(edge.x(), edge.y()) + 1.6f * slope, 2e-3f);
  }
}

TEST(Supports, ATableWhoseNormalsScatterAsASingleViewsDoIsFoundWithAveragedNormals) {
  // tableWithMounds with each vertex normal tilted at random by up to 60 degrees (median about
  // 42), as a single view's per-pixel normals scatter: most of the table fails the 25 degree test
  // alone, and what passes is a speckle of pieces too small to be a support. Averaged over two
  // rings of neighbours the normals lie within a few degrees of up, and the table is one support.
  TriangleMesh mesh = tableWithMounds();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (Eigen::Vector3f& n : mesh.normals) {
    Eigen::Vector3f axis(unit(rng), unit(rng), 0.0f);
    if (axis.norm() == 0.0f) axis = Eigen::Vector3f::UnitX();
    n = Eigen::AngleAxisf(std::acos(1.0f - 0.25f * (1.0f + unit(rng))), axis.normalized()) * n;
  }
  const MeshGraph graph = buildMeshGraph(mesh);
  const auto table = [&](const Supports& s) {
    std::size_t flat = 0, on = 0;
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      if (mesh.positions[i].z() > 0.2501f) continue;
      ++flat;
      on += s.on_support[i];
    }
    return static_cast<double>(on) / static_cast<double>(flat);
  };
  const Supports own = findSupports(mesh, graph, SupportConfig{}, 3000);
  EXPECT_LT(table(own), 0.5) << "the scattered normals alone";
  SupportConfig averaged;
  EXPECT_EQ(averaged.normal_rings, 0) << "fused meshes keep their own normals";
  averaged.normal_rings = averaged.single_view_normal_rings;
  const Supports s = findSupports(mesh, graph, averaged, 3000);
  ASSERT_EQ(s.planes.size(), 1u);
  EXPECT_GT(table(s), 0.95);
  // The mounds stay off it.
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    if (mesh.positions[i].z() > 0.26f) {
      EXPECT_EQ(s.on_support[i], 0) << i;
    }
  }
}

TEST(Supports, NoSupportOnCurvedOrSmallSurfaces) {
  // A deep bowl: its normals stay within 25 degrees of any one direction only over about 5 cm
  // (at most some 500 vertices), short of a support.
  const TriangleMesh bowl =
      makeHeightField(201, 0.4f, [](float x, float y) { return 5.0f * (x * x + y * y); });
  Supports s = findSupports(bowl, buildMeshGraph(bowl), SupportConfig{}, 3000);
  EXPECT_TRUE(s.planes.empty());
  EXPECT_EQ(std::count(s.on_support.begin(), s.on_support.end(), 1), 0);
  // A flat 20 x 20 cm patch of 2601 vertices: smaller than a support.
  const TriangleMesh patch = makeHeightField(51, 0.1f, [](float, float) { return 0.0f; });
  s = findSupports(patch, buildMeshGraph(patch), SupportConfig{}, 3000);
  EXPECT_TRUE(s.planes.empty());
  // ... which is a support when the limit is below its size.
  s = findSupports(patch, buildMeshGraph(patch), SupportConfig{}, 2000);
  ASSERT_EQ(s.planes.size(), 1u);
  EXPECT_EQ(s.planes[0].vertex_count, patch.positions.size());
}

TEST(Supports, BadArgumentsAreRejected) {
  TriangleMesh mesh = tableWithMounds();
  const MeshGraph graph = buildMeshGraph(mesh);
  SupportConfig bad;
  bad.max_angle_deg = 90.0f;
  EXPECT_THROW(findSupports(mesh, graph, bad, 3000), std::invalid_argument);
  bad = SupportConfig{};
  bad.distance_m = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(findSupports(mesh, graph, bad, 3000), std::invalid_argument);
  MeshGraph copy = graph;
  EXPECT_THROW(cutAtSupports(copy, std::vector<std::uint8_t>(3, 0)), std::invalid_argument);
  mesh.normals.clear();
  EXPECT_THROW(findSupports(mesh, graph, SupportConfig{}, 3000), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::discovery
