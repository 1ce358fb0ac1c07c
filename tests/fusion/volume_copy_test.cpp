// TsdfVolume::copyBlocksInto: the live page's copy of the volume, made a few blocks per frame.

#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/core.hpp>

#include "objscan/fusion/marching_cubes.h"
#include "objscan/fusion/raycast.h"
#include "objscan/fusion/tsdf_volume.h"
#include "test_support.h"

namespace objscan::fusion {
namespace {

/// A depth image of a plane facing the camera at `depth_m`, tilted by `slope` metres per pixel
/// along x, with a colour gradient.
void planeFrame(float depth_m, float slope, cv::Mat* depth, cv::Mat* color) {
  *depth = cv::Mat(120, 160, CV_32FC1);
  *color = cv::Mat(120, 160, CV_8UC3);
  for (int y = 0; y < depth->rows; ++y) {
    for (int x = 0; x < depth->cols; ++x) {
      depth->at<float>(y, x) = depth_m + slope * static_cast<float>(x);
      color->at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(x), 100,
                                             static_cast<std::uint8_t>(y));
    }
  }
}

void expectSameVoxels(const TsdfVolume& a, const TsdfVolume& b) {
  const TriangleMesh ma = extractMesh(a), mb = extractMesh(b);
  ASSERT_GT(ma.positions.size(), 100u);
  EXPECT_TRUE(testing::bitwiseEqual(ma, mb));
  // Every voxel of a sample of the grid, allocated or not, reads the same.
  std::size_t observed = 0;
  for (int x = -40; x < 40; x += 3) {
    for (int y = -40; y < 40; y += 3) {
      for (int z = 100; z < 220; z += 2) {
        const Eigen::Vector3i g(x, y, z);
        const std::optional<Voxel> va = a.voxelAt(g), vb = b.voxelAt(g);
        ASSERT_EQ(va.has_value(), vb.has_value()) << g.transpose();
        if (va) {
          observed += va->weight > 0.0f ? 1 : 0;
          EXPECT_EQ(va->tsdf, vb->tsdf);
          EXPECT_EQ(va->weight, vb->weight);
        }
      }
    }
  }
  EXPECT_GT(observed, 100u);  // the sample meets the surface's band
  // The copy raycasts as the volume does (its block list, its colours).
  const Intrinsics k = testing::centredCamera(160, 120, 130.0);
  const ModelMaps ra = raycast(a, k, Pose::Identity(), 0.3f, 3.0f, true);
  const ModelMaps rb = raycast(b, k, Pose::Identity(), 0.3f, 3.0f, true);
  EXPECT_GT(ra.hits, 1000u);
  EXPECT_EQ(ra.hits, rb.hits);
  ASSERT_EQ(ra.colors.size(), rb.colors.size());
  for (std::size_t i = 0; i < ra.vertices_W.size(); ++i) {
    if (!std::isfinite(ra.vertices_W[i].x())) continue;
    ASSERT_EQ(ra.vertices_W[i], rb.vertices_W[i]) << i;
    ASSERT_EQ(ra.colors[i], rb.colors[i]) << i;
  }
}

TEST(TsdfVolumeCopy, InChunksTheCopyEqualsTheVolumeAndFollowsItsUpdates) {
  VolumeConfig config;
  config.voxel_size_m = 0.01f;
  TsdfVolume volume(config), copy(config);
  const Intrinsics k = testing::centredCamera(160, 120, 130.0);
  cv::Mat depth, color;
  planeFrame(1.5f, 0.0f, &depth, &color);
  volume.integrate(depth, color, k, Pose::Identity());
  // A few blocks at a time, as the live page copies it over several frames.
  std::size_t next = 0, calls = 0;
  while (next < volume.blockCount()) {
    next = volume.copyBlocksInto(copy, next, 7);
    ++calls;
  }
  EXPECT_EQ(calls, (volume.blockCount() + 6) / 7);
  EXPECT_EQ(copy.blockCount(), volume.blockCount());
  expectSameVoxels(volume, copy);

  // The volume changes and grows; copying again from the start brings the copy up to date.
  planeFrame(1.4f, 0.002f, &depth, &color);
  volume.integrate(depth, color, k, Pose::Identity());
  ASSERT_GT(volume.blockCount(), copy.blockCount());
  EXPECT_EQ(volume.copyBlocksInto(copy, 0, volume.blockCount()), volume.blockCount());
  EXPECT_EQ(copy.blockCount(), volume.blockCount());
  expectSameVoxels(volume, copy);
}

TEST(TsdfVolumeCopy, RefusesAVolumeOfAnotherVoxelSizeAndNeverLeavesAGap) {
  VolumeConfig config;
  config.voxel_size_m = 0.01f;
  TsdfVolume volume(config), copy(config);
  VolumeConfig other = config;
  other.voxel_size_m = 0.02f;
  TsdfVolume wrong(other);
  cv::Mat depth, color;
  planeFrame(1.5f, 0.0f, &depth, &color);
  volume.integrate(depth, color, testing::centredCamera(160, 120, 130.0), Pose::Identity());
  EXPECT_THROW(volume.copyBlocksInto(wrong, 0, 10), std::invalid_argument);
  // Asked to start past what the copy holds, it starts where the copy ends.
  EXPECT_EQ(volume.copyBlocksInto(copy, 50, 10), 10u);
  EXPECT_EQ(copy.blockCount(), 10u);
}

}  // namespace
}  // namespace objscan::fusion
