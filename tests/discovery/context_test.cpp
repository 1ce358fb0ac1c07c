// A candidate's context and the object set: on a table, a box standing on it, a box stacked on
// that one and a box floating 15 cm above the table; what stands on what, how the object set
// orders them, and that its hypotheses never share a vertex.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include "objscan/discovery/context.h"
#include "objscan/discovery/discover.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"
#include "objscan/discovery/supports.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

using objscan::testing::addGridTriangles;
using objscan::testing::makeHeightField;

constexpr float kTable = 0.25f;  ///< the table's height, metres

/// Appends an axis-aligned box of side `side` whose bottom face is at `bottom` (centred on x, y)
/// as six separate n x n grids, each with its own face's normal, and returns its vertices.
std::vector<std::int32_t> addBox(TriangleMesh& mesh, float x, float y, float bottom, float side,
                                 int n = 10) {
  std::vector<std::int32_t> vertices;
  const Eigen::Vector3f centre(x, y, bottom + side / 2);
  for (int axis = 0; axis < 3; ++axis) {
    for (const float sign : {-1.0f, 1.0f}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const std::int32_t first = static_cast<std::int32_t>(mesh.positions.size());
      Eigen::Vector3f normal = Eigen::Vector3f::Zero();
      normal[axis] = sign;
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          Eigen::Vector3f p = centre + normal * (side / 2);
          p[u] += side * (static_cast<float>(i) / static_cast<float>(n - 1) - 0.5f);
          p[v] += side * (static_cast<float>(j) / static_cast<float>(n - 1) - 0.5f);
          vertices.push_back(static_cast<std::int32_t>(mesh.positions.size()));
          mesh.positions.push_back(p);
          mesh.normals.push_back(normal);
        }
      }
      TriangleMesh grid;
      addGridTriangles(grid, n, n);
      for (const Eigen::Vector3i& t : grid.triangles) {
        // Counter-clockwise seen from outside whichever face this is.
        const bool flip = (sign < 0.0f);
        mesh.triangles.emplace_back(first + t[0], first + (flip ? t[2] : t[1]),
                                    first + (flip ? t[1] : t[2]));
      }
    }
  }
  std::sort(vertices.begin(), vertices.end());
  return vertices;
}

struct Scene {
  TriangleMesh mesh;
  std::vector<Segment> boxes;  ///< standing, stacked, floating
};

Scene tableWithBoxes() {
  Scene s;
  s.mesh = makeHeightField(161, 0.4f, [](float, float) { return kTable; });
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, -0.15f, 0.0f, kTable, 0.08f)));
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, -0.15f, 0.0f, kTable + 0.08f, 0.06f)));
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, 0.15f, 0.0f, kTable + 0.15f, 0.06f)));
  return s;
}

std::vector<SegmentContext> contextsOf(const Scene& s) {
  const MeshGraph graph = buildMeshGraph(s.mesh);
  const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
  EXPECT_EQ(supports.planes.size(), 1u);
  return segmentContexts(s.mesh, graph, supports, s.boxes);
}

TEST(Context, ABoxOnTheTableStandsOnItsSupportOneOnTopOnItAndOneInTheAirOnNothing) {
  const Scene s = tableWithBoxes();
  const std::vector<SegmentContext> c = contextsOf(s);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c[0].footing, Footing::kSupport);
  EXPECT_EQ(c[1].footing, Footing::kOnSurface);
  EXPECT_EQ(c[2].footing, Footing::kNone);
  // Heights of the lowest vertex over the table, to the millimetre.
  EXPECT_NEAR(c[0].height_m, 0.0, 1e-3);
  EXPECT_NEAR(c[1].height_m, 0.08, 1e-3);
  EXPECT_NEAR(c[2].height_m, 0.15, 1e-3);
  // Each box face is a region of its own off the table (it shares no edge with anything): a
  // candidate's share is of the region it starts in.
  for (const SegmentContext& k : c) EXPECT_DOUBLE_EQ(k.share_of_region, 1.0);
  // The noise scale: the boxes' grid spacing (8 or 6 cm over 9 intervals) and diagonals.
  EXPECT_GT(c[0].mean_edge_m, 0.08 / 9);
  EXPECT_LT(c[0].mean_edge_m, 0.08 / 9 * std::sqrt(2.0));
  EXPECT_TRUE(std::isnan(c[0].observation));  // the mesh has no fusion weights
}

TEST(Context, ObservationIsTheMeanWeightOverTheScenesMedian) {
  Scene s = tableWithBoxes();
  s.mesh.weights.assign(s.mesh.positions.size(), 10.0f);
  for (std::int32_t v : s.boxes[2].vertices) s.mesh.weights[static_cast<std::size_t>(v)] = 2.5f;
  const std::vector<SegmentContext> c = contextsOf(s);
  EXPECT_DOUBLE_EQ(c[0].observation, 1.0);
  EXPECT_DOUBLE_EQ(c[2].observation, 0.25);
}

TEST(Context, ABoxAsHighAsTheStackedOneButBesideItFloats) {
  Scene s = tableWithBoxes();
  // The floating box moved down to the stacked one's height, 20 cm away from the stack.
  s.boxes.pop_back();
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, 0.1f, 0.1f, kTable + 0.08f, 0.06f)));
  const std::vector<SegmentContext> c = contextsOf(s);
  EXPECT_EQ(c[1].footing, Footing::kOnSurface);
  EXPECT_EQ(c[2].footing, Footing::kNone);
}

// A box resting on the floating box is held by nothing that stands (a leaf resting on a leaf of
// a plant): it stands on nothing, unless stacks need no standing holder (single views).
TEST(Context, WhatRestsOnAFloatingThingStandsOnNothing) {
  Scene s = tableWithBoxes();
  s.boxes.push_back(
      describeSegment(s.mesh, addBox(s.mesh, 0.15f, 0.0f, kTable + 0.15f + 0.06f, 0.03f)));
  const MeshGraph graph = buildMeshGraph(s.mesh);
  const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
  ContextConfig config;
  std::vector<SegmentContext> c = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c[1].footing, Footing::kOnSurface);  // on the box that stands on the table
  EXPECT_EQ(c[2].footing, Footing::kNone);
  EXPECT_EQ(c[3].footing, Footing::kNone);
  config.stacks_need_standing_holder = false;
  c = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  EXPECT_EQ(c[1].footing, Footing::kOnSurface);
  EXPECT_EQ(c[3].footing, Footing::kOnSurface);
  // A third storey: a box on the stacked one stands on it in turn.
  s.boxes.push_back(
      describeSegment(s.mesh, addBox(s.mesh, -0.15f, 0.0f, kTable + 0.08f + 0.06f, 0.04f)));
  const MeshGraph graph3 = buildMeshGraph(s.mesh);
  c = segmentContexts(s.mesh, graph3, findSupports(s.mesh, graph3, SupportConfig{}, 3000), s.boxes,
                      ContextConfig{});
  ASSERT_EQ(c.size(), 5u);
  EXPECT_EQ(c[4].footing, Footing::kOnSurface);
}

/// A square block `height` tall whose top reaches to `half` from the origin along x and y: flat
/// on top, its sides rising over their outer 1 cm.
float block(float x, float y, float half, float height) {
  const float t = std::clamp((half - std::max(std::abs(x), std::abs(y))) / 0.01f, 0.0f, 1.0f);
  return height * t * t * (3.0f - 2.0f * t);
}

/// The vertices of `mesh` higher than `low` over the table and at most `high`.
std::vector<std::int32_t> verticesBetween(const TriangleMesh& mesh, float low, float high) {
  std::vector<std::int32_t> v;
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    const float z = mesh.positions[i].z() - kTable;
    if (z > low && z <= high) v.push_back(static_cast<std::int32_t>(i));
  }
  return v;
}

/// The contexts of a scene with one support as a single view has them (no standing holder for
/// stacks): with the regions as they are, and cut at stacks.
std::pair<std::vector<SegmentContext>, std::vector<SegmentContext>> singleViewContexts(
    const Scene& s) {
  const MeshGraph graph = buildMeshGraph(s.mesh);
  const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
  EXPECT_EQ(supports.planes.size(), 1u);
  ContextConfig config;
  config.stacks_need_standing_holder = false;
  std::pair<std::vector<SegmentContext>, std::vector<SegmentContext>> out;
  out.first = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  config.split_regions_at_stacks = true;
  out.second = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  return out;
}

// A stack as a single view's mesh shows it, one connected surface: a 13 cm block 6 cm tall on
// the table and a 9 cm block on it, 6 cm taller. As one region, each block is less than half
// of it; cut at the stack, each block is all of its storey and the pair spans two. The upper
// block's segment may leave a strip of its side out: the cut follows the block, not the segment,
// and the strip counts for no candidate.
TEST(Context, CutAtAStackEachStoreyIsARegionOfItsOwnAndThePairSpansTwo) {
  Scene s;
  s.mesh = makeHeightField(241, 0.3f, [](float x, float y) {
    return kTable + block(x, y, 0.065f, 0.06f) + block(x, y, 0.045f, 0.06f);
  });
  const std::vector<std::int32_t> upper = verticesBetween(s.mesh, 0.062f, 1.0f);
  std::vector<std::int32_t> strip_out;  // the upper block less a strip of one side
  for (std::int32_t v : upper) {
    const Eigen::Vector3f& p = s.mesh.positions[static_cast<std::size_t>(v)];
    if (!(p.x() > 0.037f && p.z() - kTable < 0.115f)) strip_out.push_back(v);
  }
  ASSERT_LT(strip_out.size(), upper.size());
  s.boxes = {describeSegment(s.mesh, verticesBetween(s.mesh, 1e-4f, 0.062f)),
             describeSegment(s.mesh, upper), describeSegment(s.mesh, strip_out),
             describeSegment(s.mesh, verticesBetween(s.mesh, 1e-4f, 1.0f))};
  const auto [joined, cut] = singleViewContexts(s);
  ASSERT_EQ(cut.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(cut[i].footing, joined[i].footing) << i;
  EXPECT_EQ(cut[0].footing, Footing::kSupport);
  EXPECT_EQ(cut[1].footing, Footing::kOnSurface);
  EXPECT_EQ(cut[2].footing, Footing::kOnSurface);
  EXPECT_EQ(cut[3].footing, Footing::kSupport);
  // One region: the pair is nearly all of it (the rest is the table's ring around the lower
  // block's foot, which the support leaves out), each block less than half.
  EXPECT_GT(joined[3].share_of_region, 0.9);
  EXPECT_LT(joined[1].share_of_region, 0.5);
  EXPECT_LT(joined[0].share_of_region, 0.55);
  // Cut: the upper block is all of its storey, and so is its segment short of a strip; the lower
  // block nearly all of its own (with that ring of the table); the pair counts against one
  // storey, by the part of it there.
  EXPECT_GT(cut[1].share_of_region, 0.99);
  EXPECT_GT(cut[2].share_of_region, 0.99);
  EXPECT_GT(cut[0].share_of_region, 0.8);
  EXPECT_LT(cut[3].share_of_region, 0.5);

  // A 6 cm block on a 12 cm one is about a fifth of the pair's region: under the least share a
  // storey needs (a quarter), it stays part of the region, as a crumb on a leaf does.
  Scene small;
  small.mesh = makeHeightField(241, 0.3f, [](float x, float y) {
    return kTable + block(x, y, 0.06f, 0.06f) + block(x, y, 0.03f, 0.06f);
  });
  small.boxes = {describeSegment(small.mesh, verticesBetween(small.mesh, 0.062f, 1.0f)),
                 describeSegment(small.mesh, verticesBetween(small.mesh, 1e-4f, 0.062f))};
  const SegmentContext on_top = singleViewContexts(small).second[0];
  EXPECT_EQ(on_top.footing, Footing::kOnSurface);
  EXPECT_GT(on_top.share_of_region, 0.15);
  EXPECT_LT(on_top.share_of_region, 0.25);
}

// What a block rests on must stand for the block to make a storey: a 6 cm block on a 10 cm board
// floating 15 cm over the table (as a part of an object rests on another part of it whose foot is
// hidden) is a third of the board's region, enough for a storey, yet stays part of it.
TEST(Context, ABlockOnAFloatingBoardMakesNoStorey) {
  Scene s;
  s.mesh = makeHeightField(
      161, 0.4f, [](float x, float y) { return kTable + block(x - 0.2f, y, 0.03f, 0.05f); });
  const std::int32_t first = static_cast<std::int32_t>(s.mesh.positions.size());
  const TriangleMesh board = makeHeightField(
      41, 0.05f, [](float x, float y) { return kTable + 0.15f + block(x, y, 0.03f, 0.05f); });
  s.mesh.positions.insert(s.mesh.positions.end(), board.positions.begin(), board.positions.end());
  s.mesh.normals.insert(s.mesh.normals.end(), board.normals.begin(), board.normals.end());
  for (const Eigen::Vector3i& t : board.triangles) {
    s.mesh.triangles.push_back(t + Eigen::Vector3i::Constant(first));
  }
  std::vector<std::int32_t> standing, on_board, board_only, on_top;
  for (std::int32_t v = 0; v < static_cast<std::int32_t>(s.mesh.positions.size()); ++v) {
    const float z = s.mesh.positions[static_cast<std::size_t>(v)].z() - kTable;
    if (v < first) {
      if (z > 1e-4f) standing.push_back(v);
      continue;
    }
    on_board.push_back(v);
    (z > 0.152f ? on_top : board_only).push_back(v);
  }
  s.boxes = {describeSegment(s.mesh, standing), describeSegment(s.mesh, board_only),
             describeSegment(s.mesh, on_top), describeSegment(s.mesh, on_board)};
  const auto [joined, cut] = singleViewContexts(s);
  ASSERT_EQ(cut.size(), 4u);
  EXPECT_EQ(cut[0].footing, Footing::kSupport);
  EXPECT_EQ(cut[1].footing, Footing::kNone);
  EXPECT_EQ(cut[2].footing, Footing::kOnSurface);
  EXPECT_GT(joined[2].share_of_region, 0.25);
  EXPECT_LT(joined[2].share_of_region, 0.5);
  for (std::size_t i = 0; i < cut.size(); ++i) {
    EXPECT_DOUBLE_EQ(cut[i].share_of_region, joined[i].share_of_region) << i;
  }
}

// A board 10 cm over the table, too small to be a support (1681 vertices; supports need 3000)
// and no candidate: a box on it stands on its broad level surface. A board hardly larger than
// the box (7 cm square, a leaf) is no broad surface.
TEST(Context, ABoxOnABroadBoardThatIsNoSupportStandsOnItsSurface) {
  for (const int n : {41, 15}) {  // 5 mm apart
    Scene s = tableWithBoxes();
    const float half = 0.0025f * static_cast<float>(n - 1);
    const TriangleMesh board = makeHeightField(n, half, [](float, float) { return 0.0f; });
    const std::int32_t first = static_cast<std::int32_t>(s.mesh.positions.size());
    for (const Eigen::Vector3f& p : board.positions) {
      s.mesh.positions.emplace_back(p.x(), 0.25f + p.y(), kTable + 0.1f);
      s.mesh.normals.push_back(Eigen::Vector3f::UnitZ());
    }
    for (const Eigen::Vector3i& t : board.triangles) s.mesh.triangles.push_back(t.array() + first);
    s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, 0.0f, 0.25f, kTable + 0.1f, 0.06f)));
    const MeshGraph graph = buildMeshGraph(s.mesh);
    const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
    EXPECT_EQ(supports.planes.size(), 1u);
    const std::vector<SegmentContext> c = segmentContexts(s.mesh, graph, supports, s.boxes);
    ASSERT_EQ(c.size(), 4u);
    EXPECT_EQ(c[3].footing, n == 41 ? Footing::kOnSurface : Footing::kNone) << n;
  }
}

TEST(Context, AFlatPatchOnTheTableRisingLessThanACentimetreIsAPatchOfIt) {
  Scene s = tableWithBoxes();
  // A 6 cm square 5 mm over the table, facing up: what the support's 1 cm band leaves of a
  // noisy table.
  std::vector<std::int32_t> patch;
  const std::int32_t first = static_cast<std::int32_t>(s.mesh.positions.size());
  for (int j = 0; j < 10; ++j) {
    for (int i = 0; i < 10; ++i) {
      patch.push_back(static_cast<std::int32_t>(s.mesh.positions.size()));
      s.mesh.positions.emplace_back(0.1f + 0.006f * i, -0.2f + 0.006f * j, kTable + 0.005f);
      s.mesh.normals.emplace_back(0.0f, 0.0f, 1.0f);
    }
  }
  TriangleMesh grid;
  addGridTriangles(grid, 10, 10);
  for (const Eigen::Vector3i& t : grid.triangles) s.mesh.triangles.push_back(t.array() + first);
  s.boxes.push_back(describeSegment(s.mesh, patch));
  const std::vector<SegmentContext> c = contextsOf(s);
  EXPECT_EQ(c[0].footing, Footing::kSupport);
  EXPECT_NEAR(c[0].rise_m, 0.08, 1e-3);
  EXPECT_EQ(c[3].footing, Footing::kPatch);
  EXPECT_NEAR(c[3].rise_m, 0.005, 1e-4);
  // The flat table's noise is 0, so only the least rise of 1 cm decides.
  EXPECT_NEAR(c[3].support_noise_m, 0.0, 1e-4);
  EXPECT_TRUE(std::isnan(c[2].rise_m));  // floating: no support to rise over
}

TEST(Context, BadConfigsAndSupportFlagsAreRefused) {
  const Scene s = tableWithBoxes();
  const MeshGraph graph = buildMeshGraph(s.mesh);
  Supports supports;
  supports.on_support.assign(3, 0);
  EXPECT_THROW(segmentContexts(s.mesh, graph, supports, s.boxes), std::invalid_argument);
  supports.on_support.assign(s.mesh.positions.size(), 0);
  ContextConfig bad;
  bad.gap_m = -0.01f;
  EXPECT_THROW(segmentContexts(s.mesh, graph, supports, s.boxes, bad), std::invalid_argument);
  bad = ContextConfig{};
  bad.below_m = std::nanf("");
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  // Without supports nothing stands.
  for (const SegmentContext& c : segmentContexts(s.mesh, graph, supports, s.boxes)) {
    EXPECT_EQ(c.footing, Footing::kNone);
  }
}

/// A room: the floor (z = 0, 1.6 m square), a table top over its middle (z = kTable, 0.8 m
/// square, a single sheet) and a wall along its back (y = 0.4, from the table up to 1.05 m,
/// facing the room). Candidates: a box hung on the wall 35 cm over the table, a 20 cm cube on
/// the floor under the table (its top 5 cm under the table top: a table's leg), one on the
/// floor beside the table, and a 6 cm cube on the floor under the table.
Scene room() {
  Scene s;
  s.mesh = makeHeightField(161, 0.8f, [](float, float) { return 0.0f; });
  auto append = [&s](const TriangleMesh& part) {
    const std::int32_t first = static_cast<std::int32_t>(s.mesh.positions.size());
    s.mesh.positions.insert(s.mesh.positions.end(), part.positions.begin(), part.positions.end());
    s.mesh.normals.insert(s.mesh.normals.end(), part.normals.begin(), part.normals.end());
    for (const Eigen::Vector3i& t : part.triangles) s.mesh.triangles.push_back(t.array() + first);
  };
  append(makeHeightField(161, 0.4f, [](float, float) { return kTable; }));
  TriangleMesh wall = makeHeightField(161, 0.4f, [](float, float) { return 0.0f; });
  for (std::size_t i = 0; i < wall.positions.size(); ++i) {
    const Eigen::Vector3f p = wall.positions[i];
    wall.positions[i] = {p.x(), 0.4f, kTable + 0.4f + p.y()};
    wall.normals[i] = {0.0f, -1.0f, 0.0f};
  }
  append(wall);
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, 0.0f, 0.37f, kTable + 0.35f, 0.06f)));
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, -0.2f, -0.2f, 0.0f, 0.2f)));
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, 0.6f, 0.0f, 0.0f, 0.2f)));
  // A 6 cm cube on the floor under the table: its top 19 cm under it, an object, not a leg.
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, 0.2f, -0.2f, 0.0f, 0.06f)));
  return s;
}

TEST(Context, WithTheCamerasUpABoxOnAWallStandsOnNothingAndATablesLegIsUnderIt) {
  const Scene s = room();
  const MeshGraph graph = buildMeshGraph(s.mesh);
  const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
  ASSERT_EQ(supports.planes.size(), 3u);  // the floor, the table, the wall
  ContextConfig config;
  // Without a hint every support holds: the box on the wall stands on it.
  std::vector<SegmentContext> c = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  EXPECT_EQ(c[0].footing, Footing::kSupport);
  EXPECT_EQ(c[1].footing, Footing::kUnder);
  EXPECT_EQ(c[2].footing, Footing::kSupport);
  // A camera held upright and tilted 20 degrees down at the wall: up in its images is 20 degrees
  // from the room's up, towards the wall, whose free side faces 110 degrees from it; the floor and
  // the table face 20 degrees from it, and are the ground.
  config.view_up = Eigen::Vector3f(0.0f, std::sin(0.35f), std::cos(0.35f));
  c = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  EXPECT_EQ(c[0].footing, Footing::kNone);
  EXPECT_NEAR(c[0].height_m, 0.35, 1e-3);  // measured from the table under it
  EXPECT_EQ(c[1].footing, Footing::kUnder);
  EXPECT_NEAR(c[1].rise_m, 0.2, 1e-3);
  EXPECT_EQ(c[2].footing, Footing::kSupport);  // nothing over it
  EXPECT_EQ(c[3].footing, Footing::kSupport);  // too far under the table
  // A camera on its side: no support faces within 60 degrees of its up, and every one holds.
  config.view_up = Eigen::Vector3f(1.0f, 0.0f, 0.0f);
  c = segmentContexts(s.mesh, graph, supports, s.boxes, config);
  EXPECT_EQ(c[0].footing, Footing::kSupport);
  config.view_up = Eigen::Vector3f::Zero();
  EXPECT_THROW(config.validate(), std::invalid_argument);
}

/// The three boxes as candidates, with the same measures each, plus the two lower ones as one
/// candidate (a coarser scale's segment) that scores best.
SceneCandidates candidatesOf(const Scene& s) {
  SceneCandidates c;
  c.segments = s.boxes;
  std::vector<std::int32_t> both = s.boxes[0].vertices;
  both.insert(both.end(), s.boxes[1].vertices.begin(), s.boxes[1].vertices.end());
  std::sort(both.begin(), both.end());
  c.segments.push_back(describeSegment(s.mesh, both));
  ShapeMeasures m;
  m.compactness = 0.5;
  c.measures.assign(c.segments.size(), m);
  c.measures[3].compactness = 0.9;  // the pair looks most compact
  const MeshGraph graph = buildMeshGraph(s.mesh);
  const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
  // The boxes are six separate grids each, so the stacked box floats over the standing one, as no
  // fused box on a box does: what floats over a candidate is tested on its own below.
  ContextConfig config;
  config.judge_cover = false;
  c.context = segmentContexts(s.mesh, graph, supports, c.segments, config);
  c.effective.evidence_vertices = 100;
  return c;
}

TEST(ObjectSet, StandingCandidatesComeFirstAndNoTwoObjectsShareAVertex) {
  const Scene s = tableWithBoxes();
  const SceneCandidates candidates = candidatesOf(s);
  MeasureNormaliser normaliser;
  normaliser.sd[0] = 0.1;  // compactness alone decides the score
  const ObjectnessModel model = ObjectnessModel::average(normaliser);
  DiscoveryConfig config;
  const std::vector<Hypothesis> ranked = rankObjects(s.mesh, candidates, model, config);
  // The pair (on the table, best score) first; the floating box, which shares no vertex with
  // it, second: an object. The two boxes of the pair are alternatives.
  ASSERT_GE(ranked.size(), 2u);
  EXPECT_EQ(ranked[0].object_rank, 1u);
  EXPECT_EQ(ranked[0].segment.vertices, candidates.segments[3].vertices);
  EXPECT_EQ(ranked[0].context.footing, Footing::kSupport);
  EXPECT_EQ(ranked[1].object_rank, 2u);
  EXPECT_EQ(ranked[1].segment.vertices, s.boxes[2].vertices);
  std::set<std::int32_t> seen;
  std::size_t objects = 0;
  for (const Hypothesis& h : ranked) {
    if (h.object_rank == 0) continue;
    ++objects;
    for (std::int32_t v : h.segment.vertices) EXPECT_TRUE(seen.insert(v).second) << v;
  }
  EXPECT_EQ(objects, 2u);
  // The alternatives follow, by score: the two boxes of the pair (suppression keeps them: each
  // overlaps the pair by less than IoU 0.7).
  ASSERT_EQ(ranked.size(), 4u);
  EXPECT_EQ(ranked[2].object_rank, 0u);
  EXPECT_EQ(ranked[3].object_rank, 0u);
  // The object score weighs the (positive) score by the evidence, n / (n + 100) of it, adds
  // 0.1 ln(share of its region) and takes the floating penalty (1.0) from a floating candidate.
  const double n = static_cast<double>(s.boxes[2].vertices.size());
  EXPECT_GT(ranked[1].score, 0.0);
  EXPECT_NEAR(
      ranked[1].object_score,
      ranked[1].score * n / (n + 100) + 0.1 * std::log(ranked[1].context.share_of_region) - 1.0,
      1e-9);
}

TEST(ObjectSet, AStandingBoxOutranksAFloatingOneThatScoresALittleBetter) {
  const Scene s = tableWithBoxes();
  SceneCandidates candidates = candidatesOf(s);
  candidates.segments.resize(3);
  candidates.measures.resize(3);
  candidates.context.resize(3);
  candidates.measures[2].compactness = 0.6;  // the floating box looks best
  MeasureNormaliser normaliser;
  normaliser.sd[0] = 0.1;
  const ObjectnessModel model = ObjectnessModel::average(normaliser);
  DiscoveryConfig config;
  std::vector<Hypothesis> ranked = rankObjects(s.mesh, candidates, model, config);
  ASSERT_EQ(ranked.size(), 3u);
  EXPECT_EQ(ranked[0].segment.vertices, s.boxes[0].vertices);  // on the table
  EXPECT_EQ(ranked[1].segment.vertices, s.boxes[1].vertices);  // on the box: 0.3 less
  EXPECT_EQ(ranked[2].segment.vertices, s.boxes[2].vertices);  // in the air: 1.0 less
  EXPECT_GT(ranked[2].score, ranked[0].score);
  // A score better by more than the penalty still comes first.
  candidates.measures[2].compactness = 1.5;
  ranked = rankObjects(s.mesh, candidates, model, config);
  EXPECT_EQ(ranked[0].segment.vertices, s.boxes[2].vertices);
  // Off, the paper's list: by score alone.
  config.objects.enabled = false;
  const std::vector<Hypothesis> paper = rankObjects(s.mesh, candidates, model, config);
  EXPECT_EQ(paper[0].segment.vertices, s.boxes[2].vertices);
  EXPECT_EQ(paper[0].object_rank, 0u);
  EXPECT_TRUE(std::isnan(paper[0].object_score));
}

/// The standing box as the only candidate.
SceneCandidates standingBoxAlone(const Scene& s) {
  SceneCandidates candidates = candidatesOf(s);
  candidates.segments.resize(1);
  candidates.context.resize(1);
  candidates.measures.resize(1);
  return candidates;
}

/// A normaliser under which compactness alone (spread 0.1) scores a candidate.
MeasureNormaliser compactnessOnly() {
  MeasureNormaliser normaliser;
  normaliser.sd[0] = 0.1;
  return normaliser;
}

TEST(ObjectSet, FewVerticesDrawAPositiveScoreDownAndANegativeOneFurtherDown) {
  const Scene s = tableWithBoxes();
  SceneCandidates candidates = standingBoxAlone(s);
  const MeasureNormaliser normaliser = compactnessOnly();
  DiscoveryConfig config;
  const double n = static_cast<double>(s.boxes[0].vertices.size()), f = n / (n + 100);
  for (const double compactness : {0.5, -0.5}) {
    candidates.measures[0].compactness = compactness;
    const std::vector<Hypothesis> ranked =
        rankObjects(s.mesh, candidates, ObjectnessModel::average(normaliser), config);
    ASSERT_EQ(ranked.size(), 1u);
    const double score = ranked[0].score;
    EXPECT_NEAR(ranked[0].object_score, (score > 0 ? score * f : score / f), 1e-9) << score;
    EXPECT_LT(ranked[0].object_score, score);
  }
}

TEST(ObjectSet, ACandidateSeenRarelyCountsItsVerticesByHowOftenTheyWereSeen) {
  const Scene s = tableWithBoxes();
  SceneCandidates candidates = standingBoxAlone(s);
  const MeasureNormaliser normaliser = compactnessOnly();
  DiscoveryConfig config;
  const double n = static_cast<double>(s.boxes[0].vertices.size());  // 600
  auto objectScore = [&](double observation) {
    candidates.context[0].observation = observation;
    const std::vector<Hypothesis> ranked =
        rankObjects(s.mesh, candidates, ObjectnessModel::average(normaliser), config);
    return std::pair(ranked.at(0).score, ranked.at(0).object_score);
  };
  // Seen as often as the scene's typical surface, or more, or with no weights (a single view):
  // every vertex counts.
  for (const double observation : {1.0, 3.0, std::nan("")}) {
    const auto [score, object_score] = objectScore(observation);
    EXPECT_NEAR(object_score, score * n / (n + 100), 1e-9) << observation;
  }
  // A tenth as often: 60 vertices' worth of evidence. Never seen: one vertex's, not a division
  // by zero.
  const auto [score, tenth] = objectScore(0.1);
  EXPECT_NEAR(tenth, score * 60 / 160, 1e-9);
  EXPECT_NEAR(objectScore(0.0).second, score * 1 / 101, 1e-9);
  config.objects.weigh_by_observation = false;
  EXPECT_NEAR(objectScore(0.1).second, score * n / (n + 100), 1e-9);
}

TEST(ObjectSet, ACandidateAllTakenIsLeftOutAndOneBarelyTakenLosesTheTakenVertices) {
  const Scene s = tableWithBoxes();
  SceneCandidates candidates;
  // B: the standing box plus two vertices of the floating box, scoring best; then the standing
  // box itself and the floating box, 2 of whose 600 vertices B holds.
  const Segment& standing = s.boxes[0];
  const Segment& floating = s.boxes[2];
  std::vector<std::int32_t> b = standing.vertices;
  b.push_back(floating.vertices[0]);
  b.push_back(floating.vertices[1]);
  std::sort(b.begin(), b.end());
  candidates.segments = {describeSegment(s.mesh, b), standing, floating};
  ShapeMeasures m;
  m.compactness = 0.5;
  candidates.measures.assign(3, m);
  candidates.measures[0].compactness = 0.9;
  candidates.context.assign(3, SegmentContext{});
  candidates.effective.evidence_vertices = 100;
  MeasureNormaliser normaliser;
  normaliser.sd[0] = 0.1;
  DiscoveryConfig config;
  const std::vector<Hypothesis> ranked =
      rankObjects(s.mesh, candidates, ObjectnessModel::average(normaliser), config);
  // The floating box joins without the two vertices B holds; the standing box, all B's, is no
  // object, and suppression drops it too (IoU with B above 0.7).
  ASSERT_EQ(ranked.size(), 2u);
  EXPECT_EQ(ranked[0].segment.vertices, b);
  EXPECT_EQ(ranked[1].object_rank, 2u);
  EXPECT_EQ(ranked[1].segment.vertices.size(), floating.vertices.size() - 2);
  for (std::int32_t v : ranked[1].segment.vertices) {
    EXPECT_FALSE(std::binary_search(b.begin(), b.end(), v));
  }
}

// A pot on the table with three leaves floating over it (a plant whose stems the mesh lost), a
// box beside it with nothing over it, and a block on the table with a smaller block on it, all
// one surface with the table (as a fused stack is): the leaves cover the pot; the upper storey,
// whose surface runs down to the table, covers nothing.
TEST(Context, LeavesFloatingOverAPotCoverItAndAStackOfOneSurfaceDoesNot) {
  constexpr float kStep = 0.015f, kUpper = 0.05f;
  const auto stack = [](float x, float y) {
    if (std::abs(x - 0.15f) <= 0.02f && std::abs(y) <= 0.02f) return kTable + kUpper;
    if (std::abs(x - 0.15f) <= 0.04f && std::abs(y) <= 0.04f) return kTable + kStep;
    return kTable;
  };
  Scene s;
  s.mesh = makeHeightField(161, 0.4f, stack);
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, -0.15f, 0.0f, kTable, 0.08f)));
  s.boxes.push_back(describeSegment(s.mesh, addBox(s.mesh, -0.15f, 0.2f, kTable, 0.08f)));
  for (const float x : {-0.17f, -0.15f, -0.13f}) {
    addBox(s.mesh, x, 0.0f, kTable + 0.12f + x + 0.15f + 0.02f, 0.02f, 8);
  }
  // Not over it: a leaf from 30.5 cm over its top, and one 9 cm from its middle (it reaches
  // 5.7 cm).
  addBox(s.mesh, -0.15f, 0.0f, kTable + 0.08f + 0.305f, 0.02f, 8);
  addBox(s.mesh, -0.06f, 0.0f, kTable + 0.2f, 0.02f, 8);
  std::vector<std::int32_t> lower;
  for (std::size_t v = 0; v < 161 * 161; ++v) {
    if (std::abs(s.mesh.positions[v].z() - (kTable + kStep)) < 1e-4f) {
      lower.push_back(static_cast<std::int32_t>(v));
    }
  }
  s.boxes.push_back(describeSegment(s.mesh, lower));
  const std::vector<SegmentContext> c = contextsOf(s);
  ASSERT_EQ(c.size(), 3u);
  for (const SegmentContext& k : c) EXPECT_EQ(k.footing, Footing::kSupport);
  // 3 leaves of 6 x 64 vertices over the pot's 600.
  EXPECT_NEAR(c[0].covered_share, 3.0 * 6 * 64 / 600, 1e-9);
  EXPECT_EQ(c[1].covered_share, 0.0);
  EXPECT_EQ(c[2].covered_share, 0.0);
  // Off, nothing is measured.
  const MeshGraph graph = buildMeshGraph(s.mesh);
  const Supports supports = findSupports(s.mesh, graph, SupportConfig{}, 3000);
  ContextConfig off;
  off.judge_cover = false;
  EXPECT_TRUE(std::isnan(segmentContexts(s.mesh, graph, supports, s.boxes, off)[0].covered_share));
  // Measured alike, the bare box comes before the covered pot, which pays the whole penalty
  // (covered by more than four tenths of its own vertex count).
  SceneCandidates candidates;
  candidates.segments = {s.boxes[0], s.boxes[1]};
  candidates.context = {c[0], c[1]};
  ShapeMeasures m;
  m.compactness = 0.6;
  candidates.measures.assign(2, m);
  candidates.effective.evidence_vertices = 100;
  const DiscoveryConfig config;
  const std::vector<Hypothesis> ranked =
      rankObjects(s.mesh, candidates, ObjectnessModel::average(compactnessOnly()), config);
  ASSERT_EQ(ranked.size(), 2u);
  EXPECT_EQ(ranked[0].segment.vertices, s.boxes[1].vertices);
  EXPECT_NEAR(ranked[0].object_score - ranked[1].object_score, config.objects.covered_penalty,
              1e-9);
  // Covered by a quarter of its vertex count, half way up the ramp from a tenth to four tenths:
  // half the penalty.
  candidates.context[0].covered_share = 0.25;
  const std::vector<Hypothesis> half =
      rankObjects(s.mesh, candidates, ObjectnessModel::average(compactnessOnly()), config);
  EXPECT_NEAR(half[0].object_score - half[1].object_score, 0.5 * config.objects.covered_penalty,
              1e-9);
}

}  // namespace
}  // namespace objscan::discovery
