#include "objscan/core/intrinsics.h"

#include <gtest/gtest.h>

#include <limits>

#include "objscan/core/error.h"
#include "objscan/core/rgbd_frame.h"
#include "test_support.h"

namespace objscan {
namespace {

TEST(Intrinsics, XtionDefaultsAreValid) {
  const Intrinsics in = Intrinsics::xtionDefault();
  EXPECT_NO_THROW(in.validate());
  EXPECT_DOUBLE_EQ(in.fx_px, 570.3);
  EXPECT_EQ(in.width_px, 640);
}

TEST(Intrinsics, ValidateRejectsBadValues) {
  auto bad = [](auto mutate) {
    Intrinsics in;
    mutate(in);
    return in;
  };
  EXPECT_THROW(bad([](Intrinsics& i) { i.fx_px = 0; }).validate(), std::invalid_argument);
  EXPECT_THROW(
      bad([](Intrinsics& i) { i.fy_px = std::numeric_limits<double>::quiet_NaN(); }).validate(),
      std::invalid_argument);
  EXPECT_THROW(bad([](Intrinsics& i) { i.width_px = 0; }).validate(), std::invalid_argument);
  EXPECT_THROW(bad([](Intrinsics& i) { i.height_px = 100000; }).validate(), std::invalid_argument);
  EXPECT_THROW(bad([](Intrinsics& i) { i.cx_px = 700; }).validate(), std::invalid_argument);
  EXPECT_THROW(bad([](Intrinsics& i) { i.cy_px = -1; }).validate(), std::invalid_argument);
}

TEST(Intrinsics, JsonRoundTripIsExact) {
  testing::TempDir dir;
  Intrinsics in;
  in.fx_px = 520.9;
  in.fy_px = 521.0;
  in.cx_px = 325.1;
  in.cy_px = 249.7;
  writeIntrinsicsJson(dir / "i.json", in);
  EXPECT_EQ(readIntrinsicsJson(dir / "i.json"), in);
}

TEST(Intrinsics, DepthFactorIsReadAndWrittenWhenAsked) {
  testing::TempDir dir;
  const Intrinsics in = Intrinsics::xtionDefault();
  writeIntrinsicsJson(dir / "with.json", in, 5000.0);
  writeIntrinsicsJson(dir / "without.json", in);
  std::optional<double> factor = 1.0;
  EXPECT_EQ(readIntrinsicsJson(dir / "with.json", &factor), in);
  EXPECT_EQ(factor, 5000.0);
  EXPECT_EQ(readIntrinsicsJson(dir / "without.json", &factor), in);
  EXPECT_FALSE(factor.has_value());
  testing::writeBytes(
      dir / "bad.json",
      R"({"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480, "depth_factor": -5})");
  EXPECT_NO_THROW(readIntrinsicsJson(dir / "bad.json"))
      << "not asked for: ignored like any extra key";
  testing::expectInputError([&] { readIntrinsicsJson(dir / "bad.json", &factor); },
                            dir / "bad.json", "\"depth_factor\" must be a positive number");
}

TEST(Intrinsics, BadJsonFilesAreInputErrors) {
  testing::TempDir dir;
  testing::writeBytes(dir / "broken.json", "{\"fx\": 500,");
  testing::expectInputError([&] { readIntrinsicsJson(dir / "broken.json"); }, dir / "broken.json",
                            "not valid JSON");
  testing::writeBytes(
      dir / "overflow.json",
      R"({"fx": 1e400, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480})");
  testing::expectInputError([&] { readIntrinsicsJson(dir / "overflow.json"); },
                            dir / "overflow.json", "not valid JSON");
  testing::writeBytes(dir / "missing.json",
                      R"({"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640})");
  testing::expectInputError([&] { readIntrinsicsJson(dir / "missing.json"); }, dir / "missing.json",
                            "missing number \"height\"");
  testing::writeBytes(
      dir / "outside.json",
      R"({"fx": 500, "fy": 500, "cx": 999, "cy": 240, "width": 640, "height": 480})");
  EXPECT_THROW(readIntrinsicsJson(dir / "outside.json"), InputError);
}

TEST(RgbdFrame, ValidateChecksImageTypesAndSizes) {
  RgbdFrame f;
  f.depth_m = cv::Mat(480, 640, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_NO_THROW(f.validate());
  f.color_rgb = cv::Mat(480, 640, CV_8UC3);
  EXPECT_NO_THROW(f.validate());
  f.color_rgb = cv::Mat(240, 320, CV_8UC3);
  EXPECT_THROW(f.validate(), std::invalid_argument);
  f.color_rgb.release();
  f.depth_m = cv::Mat(480, 640, CV_16UC1);
  EXPECT_THROW(f.validate(), std::invalid_argument);
  f.depth_m = cv::Mat(480, 320, CV_32FC1);
  EXPECT_THROW(f.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace objscan
