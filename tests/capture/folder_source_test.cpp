#include "objscan/capture/folder_source.h"

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>

#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "objscan/capture/read_ahead.h"
#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;
using objscan::testing::expectInputError;
using objscan::testing::sevenScenesFrameName;
using objscan::testing::TempDir;
using objscan::testing::writeBytes;

/// Depth of frame k at (u, v), millimetres (or TUM raw units with depth factor 1000).
std::uint16_t depthMm(int k, int u, int v) {
  return static_cast<std::uint16_t>(1000 * (k + 1) + 10 * v + u);
}

cv::Mat depthImage(int k) {
  cv::Mat depth(3, 4, CV_16UC1);
  for (int v = 0; v < 3; ++v) {
    for (int u = 0; u < 4; ++u) depth.at<std::uint16_t>(v, u) = depthMm(k, u, v);
  }
  return depth;
}

/// Colour of frame k: pure red (written as OpenCV's B, G, R = 0, 0, 255) with k in green.
cv::Mat colourImage(int k) { return cv::Mat(3, 4, CV_8UC3, cv::Scalar(0, k, 255)); }

/// A 4x3 7-Scenes folder with frames 0 .. n-1, identity-rotation poses at x = frame number.
void makeSevenScenes(const fs::path& dir, int n) {
  fs::create_directories(dir);
  for (int k = 0; k < n; ++k) {
    cv::imwrite((dir / sevenScenesFrameName(k, "depth.png")).string(), depthImage(k));
    cv::imwrite((dir / sevenScenesFrameName(k, "color.png")).string(), colourImage(k));
    writeBytes(dir / sevenScenesFrameName(k, "pose.txt"),
               "1 0 0 " + std::to_string(k) + "\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  }
  writeBytes(dir / "camera-intrinsics.txt", "5 0 1.5\n0 5 1\n0 0 1\n");
}

/// A 4x3 TUM folder with frames 0 .. n-1 at 100 + k / 30 s, paired in associations.txt with a
/// ground-truth pose each; depth factor 1000 so raw values are millimetres.
void makeTum(const fs::path& dir, int n, bool intrinsics_json = true) {
  fs::create_directories(dir / "rgb");
  fs::create_directories(dir / "depth");
  std::string associations;
  for (int k = 0; k < n; ++k) {
    const std::string name = std::to_string(k) + ".png";
    cv::imwrite((dir / "depth" / name).string(), depthImage(k));
    cv::imwrite((dir / "rgb" / name).string(), colourImage(k));
    const std::string t = std::to_string(100.0 + k / 30.0);
    associations.append(t + " rgb/" + name + " " + t + " depth/" + name + " " + t + " " +
                        std::to_string(k) + " 0 0 0 0 0 1\n");
  }
  writeBytes(dir / "associations.txt", associations);
  if (intrinsics_json) {
    writeBytes(
        dir / "intrinsics.json",
        R"({"fx": 5, "fy": 5, "cx": 1.5, "cy": 1, "width": 4, "height": 3, "depth_factor": 1000})");
  }
}

/// Checks that `r` is frame `index` of a folder made above. 7-Scenes depth is the float nearest
/// mm / 1000; TumFolder multiplies by 1 / depth factor, which may be one float step off.
void expectFrame(const FrameResult& r, int index, bool exact_depth = true) {
  ASSERT_EQ(r.status, FrameStatus::kOk) << r.reason;
  EXPECT_EQ(r.frame.index, index);
  EXPECT_NO_THROW(r.frame.validate());
  const float want_m = static_cast<float>(depthMm(index, 3, 2)) / 1000.0f;
  if (exact_depth) {
    EXPECT_EQ(r.frame.depth_m.at<float>(2, 3), want_m);
  } else {
    EXPECT_FLOAT_EQ(r.frame.depth_m.at<float>(2, 3), want_m);
  }
  EXPECT_EQ(r.frame.color_rgb.at<cv::Vec3b>(1, 1), cv::Vec3b(255, index, 0)) << "RGB order";
}

TEST(FolderSource, SevenScenesFramesInOrderThenEndForever) {
  TempDir dir;
  makeSevenScenes(dir.path(), 3);
  const auto source = openFolderSource(dir.path());
  const SourceInfo& info = source->info();
  EXPECT_EQ(info.description, "7-Scenes folder " + dir.path().string() + ", 3 frames");
  EXPECT_EQ(info.frame_count, 3u);
  EXPECT_FALSE(info.live);
  EXPECT_EQ(info.intrinsics.fx_px, 5.0);
  EXPECT_EQ(info.intrinsics.width_px, 4);
  EXPECT_EQ(info.intrinsics_origin, (dir / "camera-intrinsics.txt").string());
  ASSERT_TRUE(info.ground_truth.has_value());
  ASSERT_EQ(info.ground_truth->size(), 3u);
  EXPECT_EQ(info.ground_truth->poses[2].T_W_C.translation(), Eigen::Vector3f(2, 0, 0));
  for (int k = 0; k < 3; ++k) {
    const FrameResult r = source->next();
    expectFrame(r, k);
    EXPECT_DOUBLE_EQ(r.frame.stamp_s, info.ground_truth->poses[k].stamp_s);
  }
  EXPECT_EQ(source->next().status, FrameStatus::kEndOfStream);
  EXPECT_EQ(source->next().status, FrameStatus::kEndOfStream);
}

TEST(FolderSource, TumFolderThroughTheSameInterface) {
  TempDir dir;
  makeTum(dir.path(), 3);
  const auto source = openFolderSource(dir.path());
  const SourceInfo& info = source->info();
  EXPECT_EQ(info.description, "TUM folder " + dir.path().string() + ", 3 frames");
  EXPECT_EQ(info.frame_count, 3u);
  EXPECT_EQ(info.intrinsics.fx_px, 5.0);
  EXPECT_EQ(info.intrinsics_origin, (dir / "intrinsics.json").string());
  ASSERT_TRUE(info.ground_truth.has_value());
  EXPECT_EQ(info.ground_truth->size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const FrameResult r = source->next();
    expectFrame(r, k, /*exact_depth=*/false);
    EXPECT_NEAR(r.frame.stamp_s, 100.0 + k / 30.0, 1e-6);
  }
  EXPECT_EQ(source->next().status, FrameStatus::kEndOfStream);
}

TEST(FolderSource, SelectionKeepsFolderIndices) {
  TempDir dir;
  makeSevenScenes(dir.path(), 10);
  FrameSelection selection;
  selection.start = 1;
  selection.end = 7;
  selection.every = 3;
  const auto source = openFolderSource(dir.path(), selection);
  EXPECT_EQ(source->info().frame_count, 2u);
  EXPECT_NE(source->info().description.find("10 frames, 2 selected"), std::string::npos)
      << source->info().description;
  expectFrame(source->next(), 1);
  const FrameResult second = source->next();
  expectFrame(second, 4);
  EXPECT_DOUBLE_EQ(second.frame.stamp_s, 4.0 / 30.0);
  EXPECT_EQ(source->next().status, FrameStatus::kEndOfStream);
  EXPECT_EQ(source->next().status, FrameStatus::kEndOfStream);

  // An end past the last frame stops at the last frame.
  selection = {8, 1000, 1};
  const auto tail = openFolderSource(dir.path(), selection);
  EXPECT_EQ(tail->info().frame_count, 2u);
  expectFrame(tail->next(), 8);
  expectFrame(tail->next(), 9);
  EXPECT_EQ(tail->next().status, FrameStatus::kEndOfStream);
}

TEST(FolderSource, BadFramesAreReportedAndSkipped) {
  TempDir dir;
  makeSevenScenes(dir.path(), 5);
  const fs::path depth1 = dir / sevenScenesFrameName(1, "depth.png");
  const fs::path colour2 = dir / sevenScenesFrameName(2, "color.png");
  const fs::path depth3 = dir / sevenScenesFrameName(3, "depth.png");
  const std::string png = testing::readBytes(depth1);
  writeBytes(depth1, png.substr(0, png.size() / 2));  // truncated
  cv::imwrite(colour2.string(), cv::Mat(6, 8, CV_8UC3, cv::Scalar(0, 0, 255)));
  cv::imwrite(depth3.string(), cv::Mat(6, 8, CV_16UC1, cv::Scalar(1000)));
  const auto source = openFolderSource(dir.path());
  expectFrame(source->next(), 0);
  const auto expectBad = [&](const std::string& needle) {
    const FrameResult r = source->next();
    ASSERT_EQ(r.status, FrameStatus::kBadFrame);
    EXPECT_NE(r.reason.find(needle), std::string::npos) << r.reason;
  };
  expectBad("frame 1: " + depth1.string() + ": the PNG file is truncated");
  expectBad("frame 2: " + colour2.string() + ": colour image is 8x6 but the depth image");
  expectBad("frame 3: " + depth3.string() + ": image is 8x6 but the intrinsics are for 4x3");
  expectFrame(source->next(), 4);
  EXPECT_EQ(source->next().status, FrameStatus::kEndOfStream);
}

TEST(FolderSource, ImageThatVanishedAfterOpeningThrows) {
  TempDir dir;
  makeTum(dir.path(), 2);
  const auto source = openFolderSource(dir.path());
  fs::remove(dir / "rgb" / "1.png");
  expectFrame(source->next(), 0, /*exact_depth=*/false);
  EXPECT_THROW(source->next(), InputError);
}

// --- Read-ahead over a real folder source
// ---------------------------------------------------------

TEST(ReadAhead, SameFramesBadFramesAndEndInTheInnerSourcesOrder) {
  TempDir dir;
  makeSevenScenes(dir.path(), 6);
  const fs::path depth2 = dir / sevenScenesFrameName(2, "depth.png");
  const std::string png = testing::readBytes(depth2);
  writeBytes(depth2, png.substr(0, png.size() / 2));  // truncated
  ReadAheadSource source(openFolderSource(dir.path()), 2);
  EXPECT_EQ(source.info().frame_count, 6u);
  for (int k = 0; k < 6; ++k) {
    const FrameResult r = source.next();
    if (k == 2) {
      ASSERT_EQ(r.status, FrameStatus::kBadFrame);
      EXPECT_NE(r.reason.find("frame 2: " + depth2.string()), std::string::npos) << r.reason;
    } else {
      expectFrame(r, k);
    }
  }
  EXPECT_EQ(source.next().status, FrameStatus::kEndOfStream);
  EXPECT_EQ(source.next().status, FrameStatus::kEndOfStream);
}

/// A real folder source that counts how often it is asked for a frame.
class CountingSource : public FrameSource {
 public:
  CountingSource(std::unique_ptr<FrameSource> inner, std::atomic<int>* calls)
      : inner_(std::move(inner)), calls_(calls) {}
  const SourceInfo& info() const override { return inner_->info(); }
  FrameResult next() override {
    ++*calls_;
    return inner_->next();
  }

 private:
  std::unique_ptr<FrameSource> inner_;
  std::atomic<int>* calls_;
};

/// Waits up to 5 s for `calls` to reach `n`.
bool reaches(const std::atomic<int>& calls, int n) {
  for (int i = 0; i < 500 && calls.load() < n; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return calls.load() >= n;
}

TEST(ReadAhead, ReadsAheadOnItsOwnButNoFurtherThanItsDepth) {
  TempDir dir;
  makeSevenScenes(dir.path(), 8);
  std::atomic<int> calls{0};
  ReadAheadSource source(std::make_unique<CountingSource>(openFolderSource(dir.path()), &calls), 3);
  // Without a single next(), three frames are decoded, and no more.
  ASSERT_TRUE(reaches(calls, 3));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(calls.load(), 3);
  // Taking one makes room for one more.
  expectFrame(source.next(), 0);
  ASSERT_TRUE(reaches(calls, 4));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(calls.load(), 4);
}

TEST(ReadAhead, WhatTheInnerSourceThrowsArrivesAfterTheFramesBeforeIt) {
  TempDir dir;
  makeTum(dir.path(), 3);
  auto inner = openFolderSource(dir.path());
  fs::remove(dir / "rgb" / "2.png");  // frame 2 vanished after opening: the folder source throws
  ReadAheadSource source(std::move(inner));
  expectFrame(source.next(), 0, /*exact_depth=*/false);
  expectFrame(source.next(), 1, /*exact_depth=*/false);
  expectInputError([&] { source.next(); }, dir / "rgb" / "2.png", "");
  EXPECT_EQ(source.next().status, FrameStatus::kEndOfStream);
}

TEST(ReadAhead, StopsItsReaderWhenDestroyedMidStream) {
  TempDir dir;
  makeSevenScenes(dir.path(), 8);
  auto source = std::make_unique<ReadAheadSource>(openFolderSource(dir.path()), 1);
  expectFrame(source->next(), 0);
  source.reset();  // joins a reader that is waiting for room in its queue
  EXPECT_THROW(ReadAheadSource(nullptr), std::invalid_argument);
  EXPECT_THROW(ReadAheadSource(openFolderSource(dir.path()), 0), std::invalid_argument);
}

TEST(FolderSource, NotADatasetFolderIsAnInputError) {
  TempDir dir;
  expectInputError([&] { openFolderSource(dir.path()); }, dir.path(),
                   "is neither a TUM RGB-D folder (rgb.txt/depth.txt or an associations file) "
                   "nor a 7-Scenes folder (frame-NNNNNN.depth.png)");
  expectInputError([&] { openFolderSource(dir / "absent"); }, dir / "absent",
                   "no such file or directory");
  writeBytes(dir / "scan.ply", "ply\n");
  expectInputError([&] { openFolderSource(dir / "scan.ply"); }, dir / "scan.ply", "is a file");
}

TEST(FolderSource, BadSelectionIsAnInvalidArgument) {
  TempDir dir;
  makeSevenScenes(dir.path(), 3);
  EXPECT_THROW(openFolderSource(dir.path(), {0, std::nullopt, 0}), std::invalid_argument);
  EXPECT_THROW(openFolderSource(dir.path(), {2, 2, 1}), std::invalid_argument);
  try {
    openFolderSource(dir.path(), {3, std::nullopt, 1});
    ADD_FAILURE() << "a start past the last frame must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--start (3) is past the last frame"), std::string::npos)
        << e.what();
  }
}

TEST(FolderSource, IntrinsicsOverrideReplacesTheFolders) {
  TempDir dir;
  makeSevenScenes(dir.path(), 3);
  Intrinsics k{7.0, 8.0, 2.0, 1.0, 4, 3};
  {
    const auto source = openFolderSource(dir.path(), {}, k, "calib.json");
    EXPECT_EQ(source->info().intrinsics, k);
    EXPECT_EQ(source->info().intrinsics_origin, "calib.json");
    const FrameResult r = source->next();
    ASSERT_EQ(r.status, FrameStatus::kOk) << r.reason;
    EXPECT_EQ(r.frame.intrinsics, k);
  }
  // Checked against the first selected frame at open; a later frame of another size is bad.
  Intrinsics wrong = k;
  wrong.width_px = 8;
  wrong.height_px = 6;
  expectInputError([&] { openFolderSource(dir.path(), {}, wrong, "calib.json"); },
                   dir / sevenScenesFrameName(0, "depth.png"),
                   "image is 4x3 but the intrinsics from calib.json are for 8x6");
  cv::imwrite((dir / sevenScenesFrameName(1, "depth.png")).string(), cv::Mat(6, 8, CV_16UC1));
  cv::imwrite((dir / sevenScenesFrameName(1, "color.png")).string(), cv::Mat(6, 8, CV_8UC3));
  {
    const auto source = openFolderSource(dir.path(), {1, std::nullopt, 1}, wrong, "calib.json");
    const FrameResult r1 = source->next();
    ASSERT_EQ(r1.status, FrameStatus::kOk) << r1.reason;
    EXPECT_EQ(r1.frame.intrinsics, wrong);
    const FrameResult r2 = source->next();
    ASSERT_EQ(r2.status, FrameStatus::kBadFrame);
    EXPECT_NE(r2.reason.find("frame 2: " + (dir / sevenScenesFrameName(2, "depth.png")).string() +
                             ": image is 4x3 but the intrinsics are for 8x6"),
              std::string::npos)
        << r2.reason;
  }
  Intrinsics invalid = k;
  invalid.fx_px = -1.0;
  EXPECT_THROW(openFolderSource(dir.path(), {}, invalid, "calib.json"), std::invalid_argument);
}

TEST(FolderSource, IntrinsicsOverrideOfATumFolder) {
  TempDir dir;
  makeTum(dir.path(), 2, /*intrinsics_json=*/false);
  const Intrinsics k{7.0, 8.0, 2.0, 1.0, 4, 3};
  // The folder's own intrinsics are the 640x480 defaults, which TumFolder checks images against.
  expectInputError([&] { openFolderSource(dir.path(), {}, k, "calib.json"); }, dir.path(),
                   "put the calibration in " + (dir / "intrinsics.json").string());
  writeBytes(dir / "intrinsics.json",
             R"({"fx": 5, "fy": 5, "cx": 1.5, "cy": 1, "width": 4, "height": 3})");
  const auto source = openFolderSource(dir.path(), {}, k, "calib.json");
  EXPECT_EQ(source->info().intrinsics, k);
  const FrameResult r = source->next();
  ASSERT_EQ(r.status, FrameStatus::kOk) << r.reason;
  EXPECT_EQ(r.frame.intrinsics, k);
}

}  // namespace
}  // namespace objscan::capture
