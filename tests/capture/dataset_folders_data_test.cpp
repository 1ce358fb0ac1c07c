// Opens the real dataset samples in ../shared/data through openFolderSource (label: data).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "build_paths.h"
#include "objscan/capture/folder_source.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;

const fs::path kDataDir = fs::path(OBJSCAN_DATA_DIR);

TEST(DatasetFolders, SevenScenesSampleHas300FramesWithItsCalibrationAndPoses) {
  const fs::path dir = kDataDir / "7scenes_300";
  const auto source = openFolderSource(dir);
  const SourceInfo& info = source->info();
  EXPECT_EQ(info.frame_count, 300u);
  EXPECT_EQ(info.description, "7-Scenes folder " + dir.string() + ", 300 frames");
  EXPECT_EQ(info.intrinsics.fx_px, 585.0);
  EXPECT_EQ(info.intrinsics.fy_px, 585.0);
  EXPECT_EQ(info.intrinsics.cx_px, 320.0);
  EXPECT_EQ(info.intrinsics.cy_px, 240.0);
  EXPECT_EQ(info.intrinsics.width_px, 640);
  EXPECT_EQ(info.intrinsics.height_px, 480);
  EXPECT_EQ(info.intrinsics_origin, (dir / "camera-intrinsics.txt").string());

  // Frame 0's pose, read here independently of the library.
  ASSERT_TRUE(info.ground_truth.has_value());
  ASSERT_EQ(info.ground_truth->size(), 300u);
  std::ifstream pose_file(dir / "frame-000000.pose.txt");
  Eigen::Matrix4d expected;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) ASSERT_TRUE(pose_file >> expected(r, c));
  }
  const Eigen::Matrix4d pose0 = info.ground_truth->poses[0].T_W_C.matrix().cast<double>();
  EXPECT_LT((pose0 - expected).cwiseAbs().maxCoeff(), 1e-6) << pose0;
  EXPECT_EQ(info.ground_truth->poses[0].stamp_s, 0.0);
  EXPECT_DOUBLE_EQ(info.ground_truth->poses[299].stamp_s, 299.0 / 30.0);

  // Frame 0's depth is the PNG's millimetres / 1000 at every pixel.
  const cv::Mat raw = cv::imread((dir / "frame-000000.depth.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  const FrameResult first = source->next();
  ASSERT_EQ(first.status, FrameStatus::kOk) << first.reason;
  EXPECT_NO_THROW(first.frame.validate());
  EXPECT_FALSE(first.frame.color_rgb.empty());
  int mismatches = 0, valid = 0;
  for (int v = 0; v < raw.rows; ++v) {
    for (int u = 0; u < raw.cols; ++u) {
      const std::uint16_t mm = raw.at<std::uint16_t>(v, u);
      const float want = mm == 65535 ? 0.0f : static_cast<float>(mm) / 1000.0f;
      mismatches += first.frame.depth_m.at<float>(v, u) != want;
      valid += want > 0.0f;
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(valid, 640 * 480 / 2) << "an indoor scene at Kinect range: mostly valid readings";
  const std::uint16_t centre = raw.at<std::uint16_t>(240, 320);
  EXPECT_EQ(first.frame.depth_m.at<float>(240, 320), static_cast<float>(centre) / 1000.0f);

  // Every other frame decodes too.
  int ok = 1;
  for (FrameResult r = source->next(); r.status != FrameStatus::kEndOfStream; r = source->next()) {
    EXPECT_EQ(r.status, FrameStatus::kOk) << r.reason;
    ok += r.status == FrameStatus::kOk;
  }
  EXPECT_EQ(ok, 300);
}

TEST(DatasetFolders, TumDeskSampleHas50FramesWithGroundTruth) {
  const fs::path dir = kDataDir / "tum_fr2_desk_50";
  // The sample carries TUM's published freiburg2 calibration as intrinsics.json (../shared/data's
  // README): the folder alone gives it, and an override still wins over it.
  const Intrinsics freiburg2{520.9, 521.0, 325.1, 249.7, 640, 480};
  {
    const auto plain = openFolderSource(dir);
    EXPECT_EQ(plain->info().intrinsics, freiburg2);
    EXPECT_NE(plain->info().intrinsics_origin.find("intrinsics.json"), std::string::npos)
        << plain->info().intrinsics_origin;
    const auto overridden = openFolderSource(dir, {}, Intrinsics::xtionDefault(), "the Xtion's");
    EXPECT_EQ(overridden->info().intrinsics, Intrinsics::xtionDefault());
    EXPECT_EQ(overridden->info().intrinsics_origin, "the Xtion's");
  }
  const auto source = openFolderSource(dir, {}, freiburg2, "TUM freiburg2 calibration");
  const SourceInfo& info = source->info();
  EXPECT_EQ(info.frame_count, 50u);
  EXPECT_EQ(info.description, "TUM folder " + dir.string() + ", 50 frames");
  EXPECT_EQ(info.intrinsics.fx_px, 520.9);
  EXPECT_EQ(info.intrinsics_origin, "TUM freiburg2 calibration");
  ASSERT_TRUE(info.ground_truth.has_value());
  EXPECT_EQ(info.ground_truth->size(), 50u);
  int ok = 0;
  for (FrameResult r = source->next(); r.status != FrameStatus::kEndOfStream; r = source->next()) {
    ASSERT_EQ(r.status, FrameStatus::kOk) << r.reason;
    EXPECT_EQ(r.frame.index, ok);
    EXPECT_EQ(r.frame.intrinsics.fx_px, 520.9);
    ++ok;
  }
  EXPECT_EQ(ok, 50);
}

}  // namespace
}  // namespace objscan::capture
