// Segment statistics and the paper's hard filters on point sets whose shape is known.

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>

#include "objscan/discovery/segment.h"

namespace objscan::discovery {
namespace {

/// A solid grid of 11^3 points filling a box of the given size, rotated and moved away from the
/// origin (so that nothing depends on the frame).
TriangleMesh box(const Eigen::Vector3f& size) {
  TriangleMesh mesh;
  const Eigen::Matrix3f R =
      Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized()).toRotationMatrix();
  for (int i = 0; i <= 10; ++i) {
    for (int j = 0; j <= 10; ++j) {
      for (int k = 0; k <= 10; ++k) {
        const Eigen::Vector3f p =
            (Eigen::Vector3f(i, j, k) / 10.0f - Eigen::Vector3f::Constant(0.5f)).cwiseProduct(size);
        mesh.positions.push_back(R * p + Eigen::Vector3f(2.0f, -1.0f, 0.5f));
      }
    }
  }
  return mesh;
}

std::vector<std::int32_t> all(const TriangleMesh& mesh) {
  std::vector<std::int32_t> v(mesh.positions.size());
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<std::int32_t>(i);
  return v;
}

TEST(Segment, ExtentsAndEigenvaluesOfABox) {
  const TriangleMesh mesh = box({0.3f, 0.1f, 0.05f});
  const Segment s = describeSegment(mesh, all(mesh));
  EXPECT_NEAR(s.extents[0], 0.3f, 1e-5f);
  EXPECT_NEAR(s.extents[1], 0.1f, 1e-5f);
  EXPECT_NEAR(s.extents[2], 0.05f, 1e-5f);
  EXPECT_TRUE(s.centroid.isApprox(Eigen::Vector3f(2.0f, -1.0f, 0.5f), 1e-5f));
  // A uniform grid of n + 1 = 11 points over length L has variance L^2 (n + 2) / (12 n).
  const auto variance = [](float length) { return length * length * 12.0f / 120.0f; };
  EXPECT_NEAR(s.eigenvalues[0], variance(0.3f), 1e-6f);
  EXPECT_NEAR(s.eigenvalues[1], variance(0.1f), 1e-6f);
  EXPECT_NEAR(s.eigenvalues[2], variance(0.05f), 1e-6f);
  EXPECT_THROW(describeSegment(mesh, {}), std::invalid_argument);
  EXPECT_THROW(describeSegment(mesh, {0, 99999}), std::invalid_argument);
}

TEST(Segment, EachHardFilterRejectsWhatItShould) {
  const SegmentFilter filter;
  const auto why = [&](const Eigen::Vector3f& size) {
    const TriangleMesh mesh = box(size);
    return rejection(describeSegment(mesh, all(mesh)), filter).value_or("");
  };
  EXPECT_EQ(why({0.10f, 0.08f, 0.08f}), "");  // a mug
  // A fork, 19 x 2.5 x 2 cm: lambda1 / lambda0 = (2.5 / 19)^2 = 0.017, which the paper's 0.05
  // rejected as a stick.
  EXPECT_EQ(why({0.19f, 0.025f, 0.02f}), "");
  SegmentFilter paper;
  paper.min_lambda1_over_lambda0 = 0.05f;
  const TriangleMesh fork = box({0.19f, 0.025f, 0.02f});
  EXPECT_NE(rejection(describeSegment(fork, all(fork)), paper).value_or("").find("too thin"),
            std::string::npos);
  EXPECT_NE(why({1.20f, 0.30f, 0.30f}).find("larger than 1.00 m"), std::string::npos);
  EXPECT_NE(why({0.30f, 0.30f, 0.005f}).find("thinner than 10 mm"), std::string::npos);
  // A 90 cm stick 5 cm across: lambda1 / lambda0 = (5 / 90)^2 = 0.003.
  EXPECT_NE(why({0.90f, 0.05f, 0.05f}).find("too thin"), std::string::npos);
  // A 90 cm square board 2.5 cm thick: lambda2 / lambda0 = (2.5 / 90)^2 = 0.0008.
  EXPECT_NE(why({0.90f, 0.90f, 0.025f}).find("too flat"), std::string::npos);
}

TEST(Segment, CandidatesKeepLargeEnoughSegmentsThatPassAndIoUCountsSharedVertices) {
  TriangleMesh mesh = box({0.10f, 0.08f, 0.08f});  // 1331 points
  Segmentation seg;
  seg.scale = 2.0f;
  seg.segment_count = 2;
  seg.labels.assign(mesh.positions.size(), 0);
  for (std::size_t v = 0; v < 100; ++v) seg.labels[v] = 1;  // too small at min_size 500
  const std::vector<Segment> c = candidateSegments(mesh, {seg}, 500, SegmentFilter{});
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].vertices.size(), mesh.positions.size() - 100);
  EXPECT_EQ(c[0].vertices.front(), 100);
  EXPECT_EQ(c[0].scale, 2.0f);
  EXPECT_DOUBLE_EQ(vertexIoU({1, 2, 3, 4}, {3, 4, 5}), 2.0 / 5.0);
  EXPECT_DOUBLE_EQ(vertexIoU({1, 2}, {1, 2}), 1.0);
  EXPECT_DOUBLE_EQ(vertexIoU({1}, {2}), 0.0);
}

TEST(Segment, RepeatsAcrossScalesAreDescribedOnceAndFoundByFirstOfEach) {
  const TriangleMesh mesh = box({0.10f, 0.08f, 0.08f});  // 1331 points
  const auto split = [&](float scale, std::size_t at, bool swap_labels) {
    Segmentation seg;
    seg.scale = scale;
    seg.segment_count = 2;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      seg.labels.push_back((v < at) != swap_labels ? 0 : 1);
    }
    return seg;
  };
  // Scale 3 repeats scale 2's two segments under swapped labels; scale 4 cuts elsewhere.
  const std::vector<Segment> c = candidateSegments(
      mesh, {split(2.0f, 700, false), split(3.0f, 700, true), split(4.0f, 600, false)}, 500,
      SegmentFilter{});
  ASSERT_EQ(c.size(), 6u);
  const float scales[] = {2, 2, 3, 3, 4, 4};
  for (std::size_t i = 0; i < c.size(); ++i) {
    // Each exactly as if described on its own, with its own scale.
    const Segment alone = describeSegment(mesh, c[i].vertices, scales[i]);
    EXPECT_EQ(c[i].scale, scales[i]);
    EXPECT_EQ(c[i].centroid, alone.centroid);
    EXPECT_EQ(c[i].axes, alone.axes);
    EXPECT_EQ(c[i].eigenvalues, alone.eigenvalues);
    EXPECT_EQ(c[i].extents, alone.extents);
  }
  EXPECT_EQ(c[2].vertices.front(), 700);  // scale 3's label 0 is the part from 700 on
  EXPECT_EQ(firstOfEach(c), (std::vector<std::size_t>{0, 1, 1, 0, 4, 5}));
  EXPECT_TRUE(firstOfEach({}).empty());
}

TEST(Segment, SuppressionKeepsTheBetterOfOverlappingSegments) {
  const auto range = [](std::int32_t from, std::int32_t to) {
    Segment s;
    for (std::int32_t v = from; v < to; ++v) s.vertices.push_back(v);
    return s;
  };
  // A and B share 90 of 100 vertices (IoU 0.9); C is apart; D overlaps B by IoU 0.25 only.
  const std::vector<Segment> segments = {range(0, 100), range(0, 90), range(200, 300),
                                         range(60, 120)};
  const std::vector<std::size_t> kept = suppressOverlaps(segments, {0.5, 0.8, 0.1, 0.3});
  EXPECT_EQ(kept, (std::vector<std::size_t>{1, 3, 2}));
  // Exactly at the threshold is not "more similar than" it.
  EXPECT_EQ(suppressOverlaps({range(0, 10), range(0, 7)}, {1.0, 0.5}, 0.7).size(), 2u);
  EXPECT_THROW(suppressOverlaps(segments, {1.0}), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::discovery
