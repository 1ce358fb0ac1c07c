#include "objscan/capture/tum_folder.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "objscan/core/error.h"
#include "objscan/core/trajectory.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

using objscan::testing::TempDir;
using objscan::testing::writeBytes;

/// Writes a 4x3 TUM folder with frames whose depth pixel (u, v) is 1000 * (frame + 1) + 10 * v + u
/// raw units, and whose colour is (R, G, B) = (frame, u, v).
void makeFolder(const std::filesystem::path& dir, int frames,
                const std::vector<double>& rgb_offsets_s) {
  std::filesystem::create_directories(dir / "rgb");
  std::filesystem::create_directories(dir / "depth");
  std::string rgb_txt = "# color images\n# timestamp filename\n", depth_txt = "# depth maps\n";
  for (int f = 0; f < frames; ++f) {
    cv::Mat depth(3, 4, CV_16UC1), bgr(3, 4, CV_8UC3);
    for (int v = 0; v < 3; ++v) {
      for (int u = 0; u < 4; ++u) {
        depth.at<std::uint16_t>(v, u) = static_cast<std::uint16_t>(1000 * (f + 1) + 10 * v + u);
        bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(v, u, f);  // OpenCV stores B, G, R
      }
    }
    depth.at<std::uint16_t>(0, 0) = 0;  // no reading
    const double t = 100.0 + f / 30.0;
    const std::string name = std::to_string(f) + ".png";
    cv::imwrite((dir / "depth" / name).string(), depth);
    cv::imwrite((dir / "rgb" / name).string(), bgr);
    depth_txt += std::to_string(t) + " depth/" + name + "\n";
    rgb_txt += std::to_string(t + rgb_offsets_s[f]) + " rgb/" + name + "\n";
  }
  writeBytes(dir / "rgb.txt", rgb_txt);
  writeBytes(dir / "depth.txt", depth_txt);
  writeBytes(
      dir / "intrinsics.json",
      R"({"fx": 5, "fy": 5, "cx": 1.5, "cy": 1, "width": 4, "height": 3, "depth_factor": 1000})");
}

TEST(TumFolder, DepthIsRawOverFactorAndColourIsRgbOrder) {
  TempDir dir;
  makeFolder(dir.path(), 2, {0.0, 0.0});
  const TumFolder folder(dir.path());
  ASSERT_EQ(folder.size(), 2u);
  EXPECT_TRUE(folder.intrinsicsFromFile());
  EXPECT_DOUBLE_EQ(folder.depthFactor(), 1000.0);
  const RgbdFrame frame = folder.load(1);
  EXPECT_NO_THROW(frame.validate());
  EXPECT_EQ(frame.depth_m.at<float>(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(frame.depth_m.at<float>(2, 3), 2.023f);  // (2000 + 20 + 3) / 1000
  EXPECT_EQ(frame.color_rgb.at<cv::Vec3b>(2, 3), cv::Vec3b(1, 3, 2));
  EXPECT_NEAR(frame.stamp_s, 100.0 + 1 / 30.0, 1e-6);
}

TEST(TumFolder, PairsDepthWithNearestColourWithinTwentyMilliseconds) {
  TempDir dir;
  // Frame 1's colour is 25 ms late: too far from depth 1 (and depth 2 has its own colour 4 ms
  // away, nearer than frame 1's at 8 ms), so depth 1 is skipped as associate.py does.
  makeFolder(dir.path(), 3, {0.005, 0.025, -0.004});
  const TumFolder folder(dir.path());
  ASSERT_EQ(folder.size(), 2u);
  EXPECT_EQ(folder.frames()[0].rgb, "rgb/0.png");
  EXPECT_EQ(folder.frames()[1].depth, "depth/2.png");
  EXPECT_EQ(folder.frames()[1].rgb, "rgb/2.png");
  EXPECT_NE(folder.associationSource().find("nearest"), std::string::npos);
}

TEST(TumFolder, AssociationFileInEitherColumnOrderWithGroundTruth) {
  TempDir dir;
  makeFolder(dir.path(), 2, {0.0, 0.0});
  writeBytes(dir / "associations.txt",
             "100.0 depth/0.png 100.0 rgb/0.png\n"
             "100.033 depth/1.png 100.033 rgb/1.png 100.03 1 2 3 0 0 0 1\n");
  EXPECT_THROW(TumFolder{dir.path()}, InputError) << "4 or 12 fields on every line";
  writeBytes(dir / "associations.txt",
             "100.0 depth/0.png 100.0 rgb/0.png 100.0 0 0 0 0 0 0 1\n"
             "100.033 depth/1.png 100.033 rgb/1.png 100.03 1 2 3 0 0 0 1\n");
  {
    const TumFolder folder(dir.path());
    ASSERT_EQ(folder.size(), 2u);
  }
  const std::string good = testing::readBytes(dir / "associations.txt");
  writeBytes(dir / "associations.txt",
             good.substr(0, good.find('\n') + 1) +
                 "100.033 depth/1.png 100.033 rgb/1.png 100.03 1 2 3 0 0 0 2\n");
  testing::expectInputError([&] { TumFolder f(dir.path()); }, dir / "associations.txt",
                            "line 2: ground-truth pose quaternion (qx qy qz qw) has norm 2");
  writeBytes(dir / "associations.txt", good);
  const TumFolder folder(dir.path());
  EXPECT_EQ(folder.frames()[1].depth, "depth/1.png");
  EXPECT_EQ(folder.frames()[1].rgb, "rgb/1.png");
  ASSERT_TRUE(folder.groundTruth().has_value());
  EXPECT_EQ(folder.groundTruth()->poses[1].T_W_C.translation(), Eigen::Vector3f(1, 2, 3));
}

TEST(TumFolder, RgbFirstAssociationsAndUnsortedIndexFiles) {
  TempDir dir;
  makeFolder(dir.path(), 3, {0.0, 0.004, 0.0});
  // associate.py rgb.txt depth.txt order, as TUM's own tools write it.
  writeBytes(dir / "associations.txt",
             "100.000000 rgb/0.png 100.000000 depth/0.png\n"
             "100.037333 rgb/1.png 100.033333 depth/1.png\n");
  TumFolder folder(dir.path());
  ASSERT_EQ(folder.size(), 2u);
  EXPECT_EQ(folder.frames()[1].rgb, "rgb/1.png");
  EXPECT_EQ(folder.frames()[1].depth, "depth/1.png");
  EXPECT_NEAR(folder.frames()[1].rgb_stamp_s - folder.frames()[1].depth_stamp_s, 0.004, 1e-9);

  // Without associations, an rgb.txt in reverse order pairs exactly as a sorted one does.
  std::filesystem::remove(dir / "associations.txt");
  const std::string rgb = testing::readBytes(dir / "rgb.txt");
  auto ls = testing::lines(rgb);
  std::string reversed;
  for (auto it = ls.rbegin(); it != ls.rend(); ++it) reversed += *it + "\n";
  writeBytes(dir / "rgb.txt", reversed);
  const TumFolder unsorted(dir.path());
  ASSERT_EQ(unsorted.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(unsorted.frames()[i].rgb, "rgb/" + std::to_string(i) + ".png");
    EXPECT_EQ(unsorted.frames()[i].depth, "depth/" + std::to_string(i) + ".png");
  }
}

TEST(TumFolder, AssociationsOutOfTimeOrderAreUsedSorted) {
  // Issue 18, defect 3: lines out of order were fused in file order into a trajectory that
  // objscan's own readers then refused.
  TempDir dir;
  makeFolder(dir.path(), 3, {0.0, 0.0, 0.0});
  writeBytes(dir / "associations.txt",
             "100.066 depth/2.png 100.066 rgb/2.png 100.06 2 0 0 0 0 0 1\n"
             "100.0 depth/0.png 100.0 rgb/0.png 100.0 0 0 0 0 0 0 1\n"
             "100.033 depth/1.png 100.033 rgb/1.png 100.03 1 0 0 0 0 0 1\n");
  const TumFolder folder(dir.path());
  ASSERT_EQ(folder.size(), 3u);
  ASSERT_TRUE(folder.groundTruth().has_value());
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(folder.frames()[i].depth, "depth/" + std::to_string(i) + ".png");
    EXPECT_FLOAT_EQ(folder.groundTruth()->poses[i].T_W_C.translation().x(), static_cast<float>(i));
  }
  // What fuse writes from them reads back.
  Trajectory written;
  for (std::size_t i = 0; i < 3; ++i) {
    written.poses.push_back({folder.load(i).stamp_s, folder.groundTruth()->poses[i].T_W_C});
  }
  writeTumTrajectory(dir / "trajectory.txt", written);
  EXPECT_EQ(readTumTrajectory(dir / "trajectory.txt").size(), 3u);
}

TEST(TumFolder, BadFoldersAndImagesAreInputErrors) {
  TempDir dir;
  EXPECT_THROW(TumFolder{dir.path()}, InputError) << "empty folder";
  EXPECT_THROW(TumFolder{dir / "absent"}, InputError);
  makeFolder(dir.path(), 2, {0.0, 0.0});
  std::filesystem::remove(dir / "rgb" / "1.png");
  testing::expectInputError([&] { TumFolder folder(dir.path()); }, dir / "rgb" / "1.png",
                            "listed in depth.txt + rgb.txt (nearest time stamps) but missing");
  cv::imwrite((dir / "rgb" / "1.png").string(), cv::Mat(3, 4, CV_8UC3));
  cv::imwrite((dir / "depth" / "1.png").string(), cv::Mat(3, 4, CV_8UC1, cv::Scalar(5)));
  const TumFolder folder(dir.path());
  const auto depth1 = dir / "depth" / "1.png";
  testing::expectInputError([&] { folder.load(1); }, depth1, "must be a single-channel 16-bit PNG");
  writeBytes(dir / "depth" / "1.png", testing::readBytes(dir / "depth" / "0.png").substr(0, 40));
  testing::expectInputError([&] { folder.load(1); }, depth1,
                            "the PNG file is truncated (it has no IEND end chunk)");
  writeBytes(depth1, "\x89PNG\r\n\x1a\n garbage IEND\xae\x42\x60\x82");
  testing::expectInputError([&] { folder.load(1); }, depth1, "cannot be decoded as a PNG or JPEG");
  cv::imwrite((dir / "depth" / "1.png").string(), cv::Mat(6, 8, CV_16UC1, cv::Scalar(5)));
  testing::expectInputError([&] { folder.load(1); }, depth1,
                            "image is 8x6 but the intrinsics are for 4x3");
}

TEST(TumFolder, UnreachableListedFileIsAnInputError) {
  TempDir dir;
  makeFolder(dir.path(), 1, {0.0});
  const std::string long_name = "depth/" + std::string(300, 'x') + ".png";
  writeBytes(dir / "associations.txt", "100.0 rgb/0.png 100.0 " + long_name + "\n");
  testing::expectInputError([&] { TumFolder folder(dir.path()); }, dir / long_name,
                            "cannot access: File name too long");
}

TEST(TumFolder, ShippedRecordingOpensWithItsCalibrationAndGroundTruth) {
  const TumFolder folder(std::filesystem::path(OBJSCAN_SOURCE_DIR) / "recordings" /
                         "tum_fr2_desk_10");
  ASSERT_EQ(folder.size(), 10u);
  EXPECT_DOUBLE_EQ(folder.intrinsics().fx_px, 520.9);
  EXPECT_DOUBLE_EQ(folder.depthFactor(), 5000.0);
  ASSERT_TRUE(folder.groundTruth().has_value());
  EXPECT_EQ(folder.groundTruth()->size(), 10u);
  const RgbdFrame frame = folder.load(0);
  EXPECT_NO_THROW(frame.validate());
  // A desk scene at 1-3 m: most readings are valid and within the Kinect's range.
  const int valid = cv::countNonZero(frame.depth_m > 0.0f);
  EXPECT_GT(valid, 640 * 480 / 2);
  double lo = 0, hi = 0;
  cv::minMaxLoc(frame.depth_m, &lo, &hi, nullptr, nullptr, frame.depth_m > 0.0f);
  EXPECT_GT(lo, 0.4);
  EXPECT_LT(hi, 12.0);
}

}  // namespace
}  // namespace objscan::capture
