#include "objscan/capture/seven_scenes_folder.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/imgcodecs.hpp>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;
using objscan::testing::expectInputError;
using objscan::testing::sevenScenesFrameName;
using objscan::testing::TempDir;
using objscan::testing::writeBytes;

/// The pose written for the k-th frame: a rotation of 0.1 k rad about (1, 2, 3), translation
/// (k, -2k, 0.5k) metres.
Eigen::Matrix4d poseOf(int k) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() =
      Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = Eigen::Vector3d(k, -2.0 * k, 0.5 * k);
  return T;
}

/// The 7-Scenes text format: one row per line, "%.18e" numbers separated by spaces.
std::string matrixText(const Eigen::MatrixXd& M) {
  std::string text;
  for (int r = 0; r < M.rows(); ++r) {
    for (int c = 0; c < M.cols(); ++c) {
      char number[40];
      std::snprintf(number, sizeof number, "%.18e", M(r, c));
      text.append(number).append(c + 1 < M.cols() ? " " : "\n");
    }
  }
  return text;
}

/// Writes a 4x3 7-Scenes folder with frames numbered `numbers`. The k-th frame's depth pixel
/// (u, v) is 1000 * (k + 1) + 10 * v + u millimetres except (0, 0) = 0 and (1, 0) = 65535 (no
/// reading); its colour is (R, G, B) = (k, u, v) except pure red at (1, 1); its pose is poseOf(k).
void makeFolder(const fs::path& dir, const std::vector<int>& numbers, bool intrinsics = true) {
  fs::create_directories(dir);
  for (std::size_t k = 0; k < numbers.size(); ++k) {
    cv::Mat depth(3, 4, CV_16UC1), bgr(3, 4, CV_8UC3);
    for (int v = 0; v < 3; ++v) {
      for (int u = 0; u < 4; ++u) {
        depth.at<std::uint16_t>(v, u) = static_cast<std::uint16_t>(1000 * (k + 1) + 10 * v + u);
        bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(v, u, k);  // OpenCV stores B, G, R
      }
    }
    depth.at<std::uint16_t>(0, 0) = 0;
    depth.at<std::uint16_t>(0, 1) = 65535;
    bgr.at<cv::Vec3b>(1, 1) = cv::Vec3b(0, 0, 255);  // pure red
    cv::imwrite((dir / sevenScenesFrameName(numbers[k], "depth.png")).string(), depth);
    cv::imwrite((dir / sevenScenesFrameName(numbers[k], "color.png")).string(), bgr);
    writeBytes(dir / sevenScenesFrameName(numbers[k], "pose.txt"),
               matrixText(poseOf(static_cast<int>(k))));
  }
  if (intrinsics) {
    Eigen::Matrix3d K;
    K << 5, 0, 1.5, 0, 6, 1, 0, 0, 1;
    writeBytes(dir / "camera-intrinsics.txt", matrixText(K));
  }
}

TEST(SevenScenesFolder, DepthIsMillimetresOverAThousandAndColourIsRgbOrder) {
  TempDir dir;
  makeFolder(dir.path(), {0, 3, 7});
  const SevenScenesFolder folder(dir.path());
  ASSERT_EQ(folder.size(), 3u);
  EXPECT_EQ(folder.frames()[1].number, 3);
  EXPECT_EQ(folder.frames()[2].depth, "frame-000007.depth.png");
  EXPECT_TRUE(folder.intrinsicsFromFile());
  EXPECT_EQ(folder.intrinsicsFile(), dir / "camera-intrinsics.txt");
  const Intrinsics& k = folder.intrinsics();
  EXPECT_EQ(k.fx_px, 5.0);
  EXPECT_EQ(k.fy_px, 6.0);
  EXPECT_EQ(k.cx_px, 1.5);
  EXPECT_EQ(k.cy_px, 1.0);
  EXPECT_EQ(k.width_px, 4) << "the size comes from the first depth image";
  EXPECT_EQ(k.height_px, 3);

  const RgbdFrame frame = folder.load(2);
  EXPECT_NO_THROW(frame.validate());
  EXPECT_EQ(frame.index, 2);
  EXPECT_DOUBLE_EQ(frame.stamp_s, 7.0 / 30.0) << "frame number / 30 Hz";
  EXPECT_EQ(frame.intrinsics, k);
  EXPECT_EQ(frame.depth_m.at<float>(0, 0), 0.0f);
  EXPECT_EQ(frame.depth_m.at<float>(0, 1), 0.0f) << "65535 means no reading";
  EXPECT_EQ(frame.depth_m.at<float>(2, 3), 3023.0f / 1000.0f);  // (3000 + 20 + 3) mm
  EXPECT_EQ(frame.depth_m.at<float>(1, 2), 3012.0f / 1000.0f);
  EXPECT_EQ(frame.color_rgb.at<cv::Vec3b>(1, 1), cv::Vec3b(255, 0, 0)) << "pure red, RGB order";
  EXPECT_EQ(frame.color_rgb.at<cv::Vec3b>(2, 3), cv::Vec3b(2, 3, 2));
}

TEST(SevenScenesFolder, PoseFilesBecomeTheGroundTruthKeyedByFrameStamps) {
  TempDir dir;
  makeFolder(dir.path(), {2, 5, 6});
  const SevenScenesFolder folder(dir.path());
  ASSERT_TRUE(folder.groundTruth().has_value());
  const Trajectory& gt = *folder.groundTruth();
  ASSERT_EQ(gt.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_DOUBLE_EQ(gt.poses[k].stamp_s, folder.frames()[k].stamp_s);
    // Written with 18 digits, held in float: equal to float precision.
    EXPECT_TRUE(gt.poses[k].T_W_C.matrix().cast<double>().isApprox(poseOf(k), 1e-6))
        << "frame " << k << "\n"
        << gt.poses[k].T_W_C.matrix();
  }
  EXPECT_DOUBLE_EQ(gt.poses[1].stamp_s, 5.0 / 30.0);
}

TEST(SevenScenesFolder, WithoutIntrinsicsFileUsesTheSevenScenesCalibration) {
  TempDir dir;
  makeFolder(dir.path(), {0}, /*intrinsics=*/false);
  const SevenScenesFolder small(dir.path());
  EXPECT_FALSE(small.intrinsicsFromFile());
  EXPECT_EQ(small.intrinsics(), SevenScenesFolder::defaultIntrinsics());
  EXPECT_EQ(small.intrinsics().fx_px, 585.0);
  EXPECT_EQ(small.intrinsics().cx_px, 320.0);
  expectInputError([&] { small.load(0); }, dir / "frame-000000.depth.png",
                   "image is 4x3 but the intrinsics are for 640x480 (add a camera-intrinsics.txt");

  TempDir vga;
  cv::imwrite((vga / "frame-000004.depth.png").string(),
              cv::Mat(480, 640, CV_16UC1, cv::Scalar(1234)));
  const SevenScenesFolder folder(vga.path());
  const RgbdFrame frame = folder.load(0);
  EXPECT_NO_THROW(frame.validate());
  EXPECT_EQ(frame.intrinsics.fy_px, 585.0);
  EXPECT_EQ(frame.depth_m.at<float>(479, 639), 1234.0f / 1000.0f);
  EXPECT_TRUE(frame.color_rgb.empty()) << "no frame has colour";
  EXPECT_FALSE(folder.groundTruth().has_value()) << "no frame has a pose";
}

TEST(SevenScenesFolder, IntrinsicsFileInTheParentFolderAsIn3DMatch) {
  TempDir dir;
  makeFolder(dir / "seq-01", {0, 1}, /*intrinsics=*/false);
  writeBytes(dir / "camera-intrinsics.txt", "7 0 2\n0 8 1\n0 0 1\n");
  const SevenScenesFolder folder(dir / "seq-01");
  EXPECT_EQ(folder.intrinsicsFile(), dir / "seq-01" / ".." / "camera-intrinsics.txt");
  EXPECT_EQ(folder.intrinsics().fx_px, 7.0);
  EXPECT_EQ(folder.intrinsics().cx_px, 2.0);
}

TEST(SevenScenesFolder, ColourAndPosesAreForEveryFrameOrNone) {
  TempDir dir;
  makeFolder(dir.path(), {0, 3, 7});
  fs::remove(dir / "frame-000003.color.png");
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, dir / "frame-000003.color.png",
                   "missing: 2 of the 3 frames have a colour image, so every frame needs one");
  fs::remove(dir / "frame-000000.color.png");
  fs::remove(dir / "frame-000007.color.png");
  {
    const SevenScenesFolder folder(dir.path());
    EXPECT_TRUE(folder.load(1).color_rgb.empty());
  }

  fs::remove(dir / "frame-000007.pose.txt");
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, dir / "frame-000007.pose.txt",
                   "missing: 2 of the 3 frames have a pose file");
  fs::remove(dir / "frame-000000.pose.txt");
  fs::remove(dir / "frame-000003.pose.txt");
  EXPECT_FALSE(SevenScenesFolder(dir.path()).groundTruth().has_value());

  // A JPEG colour image counts as well; both for one frame is ambiguous.
  cv::imwrite((dir / "frame-000003.color.jpg").string(), cv::Mat(3, 4, CV_8UC3, cv::Scalar(1)));
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, dir / "frame-000000.color.jpg",
                   "missing: 1 of the 3 frames have a colour image");
  cv::imwrite((dir / "frame-000003.color.png").string(), cv::Mat(3, 4, CV_8UC3, cv::Scalar(1)));
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, dir / "frame-000003.color.png",
                   "frame 3 also has frame-000003.color.jpg; remove one of the two");
}

TEST(SevenScenesFolder, SameFrameNumberTwiceIsAnInputError) {
  TempDir dir;
  makeFolder(dir.path(), {0, 3});
  fs::copy_file(dir / "frame-000003.depth.png", dir / "frame-3.depth.png");
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, dir / "frame-3.depth.png",
                   "frame 3 also has frame-000003.depth.png");
}

TEST(SevenScenesFolder, BadPoseFilesAreInputErrorsNamingFileAndLine) {
  TempDir dir;
  makeFolder(dir.path(), {0, 1});
  const fs::path pose = dir / "frame-000001.pose.txt";
  const std::string good = matrixText(poseOf(1));
  const auto expectPoseError = [&](const std::string& text, const std::string& needle) {
    writeBytes(pose, text);
    expectInputError([&] { SevenScenesFolder f(dir.path()); }, pose, needle);
  };
  // As 3DMatch writes poses where tracking was lost.
  expectPoseError("-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n0 0 0 1\n",
                  "line 1: '-inf' is not a finite number");
  expectPoseError("1 0 0 0\n0 1 0 0\n0 0 1 nan\n0 0 0 1\n", "line 3: 'nan' is not a finite number");
  expectPoseError("1 0 0 0\n0 1 0 0x\n0 0 1 0\n0 0 0 1\n", "line 2: '0x' is not a number");
  expectPoseError("1 0 0 0\n\n0 1 0 0 0\n0 0 1 0\n0 0 0 1\n",
                  "line 3: expected 4 numbers, found 5");
  expectPoseError("1 0 0 0\n0 1 0 0\n0 0 1 0\n", "expected 4 lines of 4 numbers");
  expectPoseError("2 0 0 0\n0 2 0 0\n0 0 2 0\n0 0 0 1\n",
                  "lines 1-3: the rotation is not rigid (the largest entry of R^T R - I is 3");
  expectPoseError("1 0 0 0\n0 1 0 0\n0 0 -1 0\n0 0 0 1\n",
                  "lines 1-3: the rotation is a reflection");
  expectPoseError("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n", "line 4: the last row must be 0 0 0 1");
  // Off by 2e-4 (within 1e-3), blank lines and CRLF: accepted.
  writeBytes(pose, "\n1.0002 0 0 0\r\n0 1 0 0\r\n\r\n0 0 1 0\r\n0 0 0 1\r\n\n");
  const SevenScenesFolder folder(dir.path());
  EXPECT_FLOAT_EQ(folder.groundTruth()->poses[1].T_W_C(0, 0), 1.0002f);
}

TEST(SevenScenesFolder, BadIntrinsicsFilesAreInputErrors) {
  TempDir dir;
  makeFolder(dir.path(), {0});
  const fs::path file = dir / "camera-intrinsics.txt";
  writeBytes(file, "5 0.5 1.5\n0 6 1\n0 0 1\n");
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, file,
                   "is not a pinhole camera matrix");
  writeBytes(file, "5 0 1.5\n0 6 1\n");
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, file, "expected 3 lines of 3 numbers");
  writeBytes(file, "5 0 9\n0 6 1\n0 0 1\n");
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, file,
                   "(for the 4x3 images of frame-000000.depth.png)");
}

TEST(SevenScenesFolder, BadImagesAreInputErrorsNamingTheImage) {
  TempDir dir;
  makeFolder(dir.path(), {0, 1});
  const SevenScenesFolder folder(dir.path());
  const fs::path depth1 = dir / "frame-000001.depth.png";
  const fs::path color1 = dir / "frame-000001.color.png";
  const std::string depth_png = testing::readBytes(depth1);
  writeBytes(depth1, depth_png.substr(0, depth_png.size() - 10));
  expectInputError([&] { folder.load(1); }, depth1, "the PNG file is truncated");
  cv::imwrite(depth1.string(), cv::Mat(3, 4, CV_8UC1, cv::Scalar(5)));
  expectInputError([&] { folder.load(1); }, depth1, "must be a single-channel 16-bit PNG");
  cv::imwrite(depth1.string(), cv::Mat(6, 8, CV_16UC1, cv::Scalar(5)));
  expectInputError([&] { folder.load(1); }, depth1, "image is 8x6 but the intrinsics are for 4x3");
  writeBytes(depth1, depth_png);
  EXPECT_NO_THROW(folder.load(1));
  cv::imwrite(color1.string(), cv::Mat(6, 8, CV_8UC3, cv::Scalar(5)));
  expectInputError([&] { folder.load(1); }, color1,
                   "colour image is 8x6 but the depth image frame-000001.depth.png is 4x3");
}

// A header that declares a huge image is refused on the size it declares, before the decoder
// allocates for it (found by the hostile-input audit: a 90-byte PNG declaring 32768x32768 made OpenCV
// allocate 2 GB). A PNG's IHDR and a JPEG's SOF both say the size.
TEST(SevenScenesFolder, ImagesDeclaringAnotherSizeAreRefusedBeforeDecoding) {
  TempDir dir;
  makeFolder(dir.path(), {0, 1});
  const SevenScenesFolder folder(dir.path());
  const fs::path depth1 = dir / "frame-000001.depth.png";
  std::string png = testing::readBytes(depth1);
  // IHDR's width and height (bytes 16-23, big-endian): 32768 x 32768; the data stays 4x3's, so
  // only a check before decoding can give this message.
  png.replace(16, 8, std::string("\x00\x00\x80\x00\x00\x00\x80\x00", 8));
  writeBytes(depth1, png);
  expectInputError([&] { folder.load(1); }, depth1,
                   "image is 32768x32768 but the intrinsics are for 4x3");
  png.replace(16, 8, std::string("\x7f\x00\x00\x00\x00\x00\x00\x03", 8));
  writeBytes(depth1, png);
  expectInputError([&] { folder.load(1); }, depth1, "image is 2130706432x3");
  // Only PNG and JPEG are decoded: a BMP (whose header objscan does not read) is refused.
  std::vector<std::uint8_t> bmp;
  cv::imencode(".bmp", cv::Mat(3, 4, CV_8UC1, cv::Scalar(5)), bmp);
  writeBytes(depth1, std::string(bmp.begin(), bmp.end()));
  expectInputError([&] { folder.load(1); }, depth1, "not a PNG or JPEG image");
  fs::remove(depth1);
  cv::imwrite(depth1.string(), cv::Mat(3, 4, CV_16UC1, cv::Scalar(5)));

  const fs::path color1 = dir / "frame-000001.color.png";
  fs::remove(color1);
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", cv::Mat(3, 4, CV_8UC3, cv::Scalar(1, 2, 3)), jpeg);
  std::string jpg(jpeg.begin(), jpeg.end());
  const std::size_t sof = jpg.find("\xff\xc0");
  ASSERT_NE(sof, std::string::npos);
  jpg.replace(sof + 5, 4, std::string("\x75\x30\x75\x30", 4));  // 30000 x 30000
  jpg.insert(sof, "\x12\x34");  // stray bytes before the frame header, which libjpeg skips
  writeBytes(dir / "frame-000001.color.jpg", jpg);
  fs::remove(dir / "frame-000000.color.png");
  cv::imwrite((dir / "frame-000000.color.jpg").string(), cv::Mat(3, 4, CV_8UC3));
  const SevenScenesFolder jpg_folder(dir.path());
  expectInputError([&] { jpg_folder.load(1); }, dir / "frame-000001.color.jpg",
                   "colour image is 30000x30000 but the depth image");
  EXPECT_NO_THROW(jpg_folder.load(0));

  // With a camera-intrinsics.txt the image size is frame 0's own: a PNG that declares more
  // pixels than its compressed data can hold (deflate: 1032 bytes out per byte in at most).
  TempDir big;
  makeFolder(big.path(), {0});
  std::string header = testing::readBytes(big / "frame-000000.depth.png");
  header.replace(16, 8, std::string("\x00\x00\x40\x00\x00\x00\x40\x00", 8));  // 16384^2
  writeBytes(big / "frame-000000.depth.png", header);
  const SevenScenesFolder big_folder(big.path());
  EXPECT_EQ(big_folder.intrinsics().width_px, 16384);
  expectInputError([&] { big_folder.load(0); }, big / "frame-000000.depth.png",
                   "declares 16384x16384 pixels, more than its compressed data can hold");
}

TEST(SevenScenesFolder, RecognisesOnlyFoldersWithDepthImages) {
  TempDir dir;
  EXPECT_FALSE(SevenScenesFolder::looksLikeSevenScenesFolder(dir.path()));
  EXPECT_FALSE(SevenScenesFolder::looksLikeSevenScenesFolder(dir / "absent"));
  expectInputError([&] { SevenScenesFolder f(dir.path()); }, dir.path(),
                   "it has no frame-NNNNNN.depth.png images");
  expectInputError([&] { SevenScenesFolder f(dir / "absent"); }, dir / "absent",
                   "no such file or directory");
  cv::imwrite((dir / "frame-000000.color.png").string(), cv::Mat(3, 4, CV_8UC3));
  writeBytes(dir / "frame-x.depth.png", "not a frame number");
  EXPECT_FALSE(SevenScenesFolder::looksLikeSevenScenesFolder(dir.path()));
  cv::imwrite((dir / "frame-000000.depth.png").string(), cv::Mat(3, 4, CV_16UC1));
  EXPECT_TRUE(SevenScenesFolder::looksLikeSevenScenesFolder(dir.path()));
  EXPECT_FALSE(SevenScenesFolder::looksLikeSevenScenesFolder(dir / "frame-000000.depth.png"));
}

}  // namespace
}  // namespace objscan::capture
