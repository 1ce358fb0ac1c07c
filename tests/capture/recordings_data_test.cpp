// The recordings shipped in recordings/ replay through OpenNI2 to the data they were made from.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "build_paths.h"
#include "objscan/capture/openni.h"
#include "objscan/capture/tum_folder.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;

TEST(ShippedRecordings, TumDeskReplaysTheTumDepthToTheMillimetre) {
  const TumFolder tum(fs::path(OBJSCAN_DATA_DIR) / "tum_fr2_desk_50");
  auto replay = openOniFile(fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk.oni");
  ASSERT_EQ(replay->info().frame_count, std::optional<std::size_t>(50));
  EXPECT_DOUBLE_EQ(replay->info().intrinsics.fx_px, 520.9);  // TUM's freiburg2 calibration
  EXPECT_DOUBLE_EQ(replay->info().intrinsics.cy_px, 249.7);
  ASSERT_TRUE(replay->info().ground_truth.has_value());
  std::size_t frames = 0;
  for (FrameResult r = replay->next(); r.status != FrameStatus::kEndOfStream; r = replay->next()) {
    ASSERT_EQ(r.status, FrameStatus::kOk) << r.reason;
    const std::size_t i = frames++;
    ASSERT_LT(i, tum.size());
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_NEAR(r.frame.stamp_s, tum.frames()[i].depth_stamp_s, 1e-6);
    // TUM stores depth x 5000 (0.2 mm units) of a sensor that measures whole millimetres.
    const fs::path depth_png = tum.frames()[i].depth.is_absolute()
                                   ? tum.frames()[i].depth
                                   : tum.dir() / tum.frames()[i].depth;
    const cv::Mat png = cv::imread(depth_png.string(), cv::IMREAD_ANYDEPTH);
    ASSERT_EQ(png.size(), r.frame.depth_m.size());
    std::size_t mismatches = 0;
    for (int v = 0; v < png.rows; ++v) {
      for (int u = 0; u < png.cols; ++u) {
        const long expected_mm = std::lround(png.at<std::uint16_t>(v, u) / 5.0);
        const long got_mm = std::lround(r.frame.depth_m.at<float>(v, u) * 1000.0);
        mismatches += expected_mm != got_mm ? 1 : 0;
      }
    }
    EXPECT_EQ(mismatches, 0u);
    EXPECT_FALSE(r.frame.color_rgb.empty());
  }
  EXPECT_EQ(frames, 50u);
}

TEST(ShippedRecordings, SyntheticDeskHasItsGroundTruth) {
  const fs::path dir = fs::path(OBJSCAN_SOURCE_DIR) / "recordings";
  auto replay = openOniFile(dir / "synth_desk.oni");
  ASSERT_EQ(replay->info().frame_count, std::optional<std::size_t>(90));
  ASSERT_TRUE(replay->info().ground_truth.has_value());
  EXPECT_EQ(replay->info().ground_truth->size(), 90u);
  EXPECT_TRUE(fs::is_regular_file(dir / "synth_desk.scene_gt.ply"));
  EXPECT_TRUE(fs::is_regular_file(dir / "synth_desk.scene_gt.json"));
  // The first frame's stamp is on the ground truth's clock.
  const FrameResult first = replay->next();
  ASSERT_EQ(first.status, FrameStatus::kOk);
  EXPECT_NEAR(first.frame.stamp_s, replay->info().ground_truth->poses.front().stamp_s, 1e-6);
}

}  // namespace
}  // namespace objscan::capture
