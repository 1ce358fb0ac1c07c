#include "objscan/render/snapshots.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "objscan/core/palette.h"
#include "test_support.h"

namespace objscan::render {
namespace {

using objscan::testing::makeCube;
using objscan::testing::makeHeightField;

/// Appends `part` to `scene` and returns the indices its vertices got.
std::vector<std::int32_t> append(TriangleMesh& scene, const TriangleMesh& part) {
  const auto offset = static_cast<std::int32_t>(scene.positions.size());
  std::vector<std::int32_t> indices;
  for (std::size_t i = 0; i < part.positions.size(); ++i) {
    scene.positions.push_back(part.positions[i]);
    indices.push_back(offset + static_cast<std::int32_t>(i));
  }
  for (const Eigen::Vector3i& t : part.triangles) {
    scene.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  }
  return indices;
}

TriangleMesh translated(TriangleMesh mesh, const Eigen::Vector3f& t) {
  for (Eigen::Vector3f& p : mesh.positions) p += t;
  return mesh;
}

/// A 1.2 m table (z = 0, z up) with six 10 cm cubes standing on it in a row along x. Boxes
/// `boxes[i]` holds each cube's vertices; `centres` their centres.
struct Tabletop {
  TriangleMesh scene;
  std::vector<std::vector<std::int32_t>> boxes;
  std::vector<Eigen::Vector3f> centres;
};

Tabletop tabletop() {
  Tabletop t;
  append(t.scene, makeHeightField(41, 0.6f, [](float, float) { return 0.0f; }));
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3f centre(-0.4f + 0.16f * i, 0.1f * static_cast<float>(i % 2), 0.05f);
    t.boxes.push_back(append(t.scene, translated(makeCube(0.1f), centre)));
    t.centres.push_back(centre);
  }
  return t;
}

std::vector<PaintedHypothesis> topFive(const Tabletop& t) {
  std::vector<PaintedHypothesis> hypotheses;
  // Ranks in another order than the boxes, so that a rank cannot be confused with an index.
  const int box_of_rank[5] = {3, 0, 5, 1, 4};
  for (int r = 0; r < 5; ++r) {
    hypotheses.push_back({static_cast<std::size_t>(r + 1), 1.0 - 0.1 * r, t.boxes[box_of_rank[r]]});
  }
  return hypotheses;
}

/// A camera path 1 m from the table's centre, 0.7 m up, sweeping 40 degrees, looking at it.
Trajectory sweep() {
  Trajectory trajectory;
  for (int i = 0; i < 20; ++i) {
    const double a = (-20.0 + 2.0 * i) * 3.14159265 / 180.0;
    const Eigen::Vector3f eye(static_cast<float>(std::sin(a)), -static_cast<float>(std::cos(a)),
                              0.7f);
    const Eigen::Vector3f z = (-eye).normalized();
    const Eigen::Vector3f x = z.cross(Eigen::Vector3f::UnitZ()).normalized();
    StampedPose p;
    p.stamp_s = i / 30.0;
    p.T_W_C.linear().col(0) = x;
    p.T_W_C.linear().col(1) = z.cross(x);
    p.T_W_C.linear().col(2) = z;
    p.T_W_C.translation() = eye;
    trajectory.poses.push_back(p);
  }
  return trajectory;
}

Intrinsics centredCameraForTest() { return objscan::testing::centredCamera(640, 480, 554.0); }

/// Where a world point lands in the view's image (pixels) and its depth.
Eigen::Vector3d project(const SnapshotView& view, const Eigen::Vector3f& p_W) {
  const Eigen::Vector3f p = view.T_W_C.inverse() * p_W;
  return {view.intrinsics.fx_px * p.x() / p.z() + view.intrinsics.cx_px,
          view.intrinsics.fy_px * p.y() / p.z() + view.intrinsics.cy_px, p.z()};
}

TEST(Snapshots, SceneUpIsTheTablesNormal) {
  const Tabletop t = tabletop();
  EXPECT_GT(sceneUp(t.scene).dot(Eigen::Vector3f::UnitZ()), std::cos(1e-3f));
  // Upside down (winding reversed), the surfaces face down: so does "up".
  TriangleMesh flipped = t.scene;
  for (Eigen::Vector3i& tri : flipped.triangles) std::swap(tri[1], tri[2]);
  EXPECT_LT(sceneUp(flipped).dot(Eigen::Vector3f::UnitZ()), -std::cos(1e-3f));
}

TEST(Snapshots, OverviewFromTheTrajectoryLooksItsWayAndFramesEveryHypothesis) {
  const Tabletop t = tabletop();
  const Trajectory trajectory = sweep();
  const auto hypotheses = topFive(t);
  const SnapshotView view = overviewView(t.scene, &trajectory, hypotheses, 640, 480);
  EXPECT_EQ(view.kind, ViewKind::kTrajectory);
  // The mean viewing direction of the symmetric sweep is that of its middle pose.
  const Eigen::Vector3f middle = (-Eigen::Vector3f(0.0f, -1.0f, 0.7f)).normalized();
  EXPECT_GT(view.T_W_C.linear().col(2).dot(middle), std::cos(0.02f));
  // Every hypothesis vertex is in the picture, inside the margin. Of the scene, at most 2 % may
  // lie beyond each edge (the table's far corners do), and the framing is tight: vertices reach
  // within 5 % of an edge or beyond it.
  std::array<int, 4> beyond{};
  double closest_edge = 1e9;
  for (const Eigen::Vector3f& p : t.scene.positions) {
    const Eigen::Vector3d q = project(view, p);
    ASSERT_GT(q.z(), 0.0);
    beyond[0] += q.x() < 0.0;
    beyond[1] += q.x() > 639.0;
    beyond[2] += q.y() < 0.0;
    beyond[3] += q.y() > 479.0;
    closest_edge = std::min({closest_edge, q.x(), 639.0 - q.x(), q.y(), 479.0 - q.y()});
  }
  for (int side = 0; side < 4; ++side) {
    EXPECT_LE(beyond[side], 0.02 * t.scene.positions.size() + 1) << "side " << side;
  }
  EXPECT_LT(closest_edge, 0.05 * 480);
  for (const PaintedHypothesis& h : hypotheses) {
    for (std::int32_t v : h.vertices) {
      const Eigen::Vector3d q = project(view, t.scene.positions[v]);
      EXPECT_GT(q.x(), 0.02 * 640);
      EXPECT_LT(q.x(), 0.98 * 640);
      EXPECT_GT(q.y(), 0.02 * 480);
      EXPECT_LT(q.y(), 0.98 * 480);
    }
  }
}

TEST(Snapshots, BareMeshGetsAThreeQuarterView) {
  const Tabletop t = tabletop();
  const SnapshotView view = overviewView(t.scene, nullptr, topFive(t), 640, 480);
  EXPECT_EQ(view.kind, ViewKind::kThreeQuarter);
  const Eigen::Vector3f forward = view.T_W_C.linear().col(2);
  // 35 degrees down onto the table.
  EXPECT_NEAR(std::asin(-forward.z()) * 180.0 / 3.14159265, 35.0, 0.5);
  // Image up is world up, as far as the tilt allows.
  EXPECT_LT(view.T_W_C.linear().col(1).z(), -0.8f);
  EXPECT_EQ(overviewView(t.scene, nullptr, topFive(t), 640, 480, ViewKind::kTop).kind,
            ViewKind::kTop);
  EXPECT_THROW(overviewView(t.scene, nullptr, {}, 640, 480, ViewKind::kTrajectory),
               std::invalid_argument);
  EXPECT_THROW(parseViewKind("side"), std::invalid_argument);
}

TEST(Snapshots, OverviewPaintsExactlyTheHypothesesInTheirRankColours) {
  const Tabletop t = tabletop();
  const auto hypotheses = topFive(t);
  const Trajectory trajectory = sweep();
  SnapshotRenderer renderer(t.scene, hypotheses);
  const SnapshotView view = overviewView(t.scene, &trajectory, hypotheses, 640, 480);
  const Snapshot shot = renderer.overview(view);
  ASSERT_EQ(shot.bgr.size(), cv::Size(640, 480));
  EXPECT_EQ(shot.labelled, (std::vector<std::size_t>{1, 2, 3, 4, 5}));

  // Every pixel painted with rank r lies where that rank's cube projects (its corners' bounding
  // rectangle, one pixel of slack), and most show the rank's colour, shaded (the rest are the
  // outline and the label).
  const int box_of_rank[6] = {-1, 3, 0, 5, 1, 4};
  std::map<int, cv::Rect2d> projected;
  for (int r = 1; r <= 5; ++r) {
    cv::Rect2d box(1e9, 1e9, 0, 0);
    double x1 = -1e9, y1 = -1e9;
    for (std::int32_t v : t.boxes[box_of_rank[r]]) {
      const Eigen::Vector3d q = project(view, t.scene.positions[v]);
      box.x = std::min(box.x, q.x() - 1.0);
      box.y = std::min(box.y, q.y() - 1.0);
      x1 = std::max(x1, q.x() + 1.0);
      y1 = std::max(y1, q.y() + 1.0);
    }
    box.width = x1 - box.x;
    box.height = y1 - box.y;
    projected[r] = box;
  }
  std::map<int, int> pixels, coloured;
  for (int y = 0; y < shot.ranks.rows; ++y) {
    for (int x = 0; x < shot.ranks.cols; ++x) {
      const int r = shot.ranks.at<std::int32_t>(y, x);
      if (r == 0) continue;
      ASSERT_GE(r, 1);
      ASSERT_LE(r, 5);
      ++pixels[r];
      EXPECT_TRUE(projected[r].contains(cv::Point2d(x, y)))
          << "rank " << r << " at " << x << "," << y;
      const cv::Vec3b c = shot.bgr.at<cv::Vec3b>(y, x);
      const auto want = kRankPalette[r - 1];
      const Eigen::Vector3d got_rgb(c[2], c[1], c[0]), want_rgb(want[0], want[1], want[2]);
      if (got_rgb.norm() > 0 && got_rgb.normalized().dot(want_rgb.normalized()) > 0.995) {
        ++coloured[r];
      }
    }
  }
  EXPECT_EQ(pixels.size(), 5u);
  for (const auto& [rank, count] : pixels) {
    EXPECT_GT(count, 200) << "rank " << rank;
    EXPECT_GT(coloured[rank], 0.6 * count) << "rank " << rank;
  }
  // The sixth cube is scene: no palette colour there, but the paled grey.
  const Eigen::Vector3d sixth = project(view, t.centres[2] + Eigen::Vector3f(0, 0, 0.05f));
  const cv::Vec3b top =
      shot.bgr.at<cv::Vec3b>(static_cast<int>(sixth.y()), static_cast<int>(sixth.x()));
  EXPECT_EQ(shot.ranks.at<std::int32_t>(static_cast<int>(sixth.y()), static_cast<int>(sixth.x())),
            0);
  EXPECT_LT(std::max({top[0], top[1], top[2]}) - std::min({top[0], top[1], top[2]}), 12);
}

TEST(Snapshots, AHiddenHypothesisIsPaintedButNotLabelled) {
  Tabletop t = tabletop();
  // A board 30 cm wide and 15 cm high, 20 cm in front of cube 3, hides it from a camera low down
  // at -y; from above or from the side, the cube shows.
  TriangleMesh board = makeCube(1.0f);
  for (Eigen::Vector3f& p : board.positions)
    p = p.cwiseProduct(Eigen::Vector3f(0.3f, 0.02f, 0.15f));
  append(t.scene,
         translated(board, Eigen::Vector3f(t.centres[3].x(), t.centres[3].y() - 0.2f, 0.075f)));
  std::vector<PaintedHypothesis> hypotheses = {{1, 1.0, t.boxes[3]}, {2, 0.5, t.boxes[0]}};
  SnapshotRenderer renderer(t.scene, hypotheses);
  SnapshotView view;
  view.intrinsics = centredCameraForTest();
  view.T_W_C.linear() << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // looking along +y, z up
  view.T_W_C.translation() = Eigen::Vector3f(0.0f, -1.5f, 0.1f);
  const Snapshot shot = renderer.overview(view);
  EXPECT_EQ(shot.labelled, (std::vector<std::size_t>{2}));
  // The close-up looks round the wall: from one of its other directions, rank 1 is seen.
  const Snapshot close = renderer.closeUp(0, view, 320, 240);
  EXPECT_EQ(close.labelled, (std::vector<std::size_t>{1}));
  EXPECT_GT(cv::countNonZero(close.ranks == 1), 0.05 * 320 * 240);
}

TEST(Snapshots, CloseUpFillsAboutTwoThirdsOfThePicture) {
  const Tabletop t = tabletop();
  const auto hypotheses = topFive(t);
  const Trajectory trajectory = sweep();
  SnapshotRenderer renderer(t.scene, hypotheses);
  const SnapshotView view = overviewView(t.scene, &trajectory, hypotheses, 640, 480);
  for (std::size_t i = 0; i < hypotheses.size(); ++i) {
    const Snapshot close = renderer.closeUp(i, view, 320, 240);
    const cv::Rect box = cv::boundingRect(close.ranks == static_cast<int>(hypotheses[i].rank));
    // The cube's bounding sphere spans 70 % of the height; the cube itself a bit less.
    EXPECT_GT(box.height, 0.35 * 240) << i;
    EXPECT_LT(box.height, 0.75 * 240) << i;
    EXPECT_NEAR(box.x + box.width / 2.0, 160.0, 0.1 * 320) << i;
    EXPECT_NEAR(box.y + box.height / 2.0, 120.0, 0.1 * 240) << i;
  }
}

TEST(Snapshots, ContactSheetIsAGridOfCaptionedTiles) {
  const Tabletop t = tabletop();
  const auto hypotheses = topFive(t);
  std::vector<cv::Mat> tiles;
  for (std::size_t i = 0; i < hypotheses.size(); ++i) {
    tiles.emplace_back(120, 160, CV_8UC3, cv::Scalar(10.0 * i, 0, 0));
  }
  const cv::Mat sheet = contactSheet(tiles, hypotheses);
  // 5 tiles: 3 columns, 2 rows; 8 px gaps; a 28 px caption under each tile.
  EXPECT_EQ(sheet.cols, 3 * (160 + 8) + 8);
  EXPECT_EQ(sheet.rows, 2 * (120 + 28 + 8) + 8);
  EXPECT_EQ(sheet.at<cv::Vec3b>(8 + 60, 8 + 168 + 80), cv::Vec3b(10, 0, 0));  // tile 2's pixel
  // Each caption starts with a swatch of its rank's colour.
  const auto second = kRankPalette[1];
  EXPECT_EQ(sheet.at<cv::Vec3b>(8 + 120 + 14, 8 + 168 + 13),
            cv::Vec3b(second[2], second[1], second[0]));
  tiles.pop_back();
  EXPECT_THROW(contactSheet(tiles, hypotheses), std::invalid_argument);
}

TEST(Snapshots, BadHypothesesAreRefused) {
  const Tabletop t = tabletop();
  const auto n = static_cast<std::int32_t>(t.scene.positions.size());
  EXPECT_THROW(SnapshotRenderer(t.scene, {{1, 0.0, {0, n}}}), std::invalid_argument);
  EXPECT_THROW(SnapshotRenderer(t.scene, {{0, 0.0, {0}}}), std::invalid_argument);
  EXPECT_THROW(SnapshotRenderer(t.scene, {{1, 0.0, {-1}}}), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::render
