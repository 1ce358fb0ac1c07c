// PNG and JPEG through libspng and TurboJPEG, checked against OpenCV's imgcodecs (libpng and
// libjpeg-turbo behind another interface) as the independent reader and writer.

#include "objscan/core/image_codec.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace objscan {
namespace {

std::string openCvEncoded(const std::string& extension, const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  EXPECT_TRUE(cv::imencode(extension, image, bytes));
  return {bytes.begin(), bytes.end()};
}

cv::Mat openCvDecoded(const std::string& bytes, int flags) {
  return cv::imdecode(std::vector<unsigned char>(bytes.begin(), bytes.end()), flags);
}

double maxDifference(const cv::Mat& a, const cv::Mat& b) {
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.type(), b.type());
  if (a.size() != b.size() || a.type() != b.type()) return 1e9;
  return cv::norm(a, b, cv::NORM_INF);
}

/// A BGR test card: gradients in each channel, so that an exchange of R and B shows.
cv::Mat testCard(int width, int height) {
  cv::Mat bgr(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      bgr.at<cv::Vec3b>(y, x) =
          cv::Vec3b(static_cast<unsigned char>(4 * x), static_cast<unsigned char>(3 * y),
                    static_cast<unsigned char>(200 - x - y));
    }
  }
  return bgr;
}

cv::Mat rgbOf(const cv::Mat& bgr) {
  std::vector<cv::Mat> c;
  cv::split(bgr, c);
  std::swap(c[0], c[2]);
  cv::Mat rgb;
  cv::merge(c, rgb);
  return rgb;
}

TEST(ImageCodec, SixteenBitDepthPngsKeepEverySampleBothWays) {
  // Values whose two bytes differ catch a swapped byte order.
  cv::Mat depth(3, 5, CV_16UC1);
  const std::uint16_t values[] = {0, 1, 258, 4660, 65535};
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) depth.at<std::uint16_t>(y, x) = values[(x + y) % 5];
  }
  const std::string ours = encodePng(depth);
  EXPECT_EQ(maxDifference(openCvDecoded(ours, cv::IMREAD_UNCHANGED), depth), 0.0);
  EXPECT_EQ(maxDifference(decodeImage(ours, ImageDecoding::kStoredGrey), depth), 0.0);
  EXPECT_EQ(
      maxDifference(decodeImage(openCvEncoded(".png", depth), ImageDecoding::kStoredGrey), depth),
      0.0);
}

TEST(ImageCodec, ColourPngsAreBgrInMemoryAndRgbInTheFile) {
  const cv::Mat bgr = testCard(40, 30);
  const std::string ours = encodePng(bgr);
  EXPECT_EQ(maxDifference(openCvDecoded(ours, cv::IMREAD_COLOR), bgr), 0.0);
  // Decoding gives R, G, B order, what capture's frames hold.
  EXPECT_EQ(
      maxDifference(decodeImage(openCvEncoded(".png", bgr), ImageDecoding::kRgb8), rgbOf(bgr)),
      0.0);
  // A colour PNG asked for as grey samples is not grey: the caller's type check refuses it.
  EXPECT_EQ(decodeImage(ours, ImageDecoding::kStoredGrey).type(), CV_8UC3);

  cv::Mat bgra(2, 3, CV_8UC4, cv::Scalar(10, 20, 30, 128));
  EXPECT_EQ(maxDifference(openCvDecoded(encodePng(bgra), cv::IMREAD_UNCHANGED), bgra), 0.0);
}

TEST(ImageCodec, OtherPngLayoutsBecomeEightBitRgbAsOpenCvReadsThem) {
  // 16-bit colour keeps each sample's high byte; 8-bit grey is repeated into three channels.
  const cv::Mat colour16(2, 2, CV_16UC3, cv::Scalar(0x1234, 0x5678, 0x9abc));
  const cv::Mat rgb = decodeImage(openCvEncoded(".png", colour16), ImageDecoding::kRgb8);
  ASSERT_EQ(rgb.type(), CV_8UC3);
  EXPECT_EQ(rgb.at<cv::Vec3b>(1, 1), cv::Vec3b(0x9a, 0x56, 0x12));

  cv::Mat grey(4, 4, CV_8UC1);
  cv::randu(grey, 0, 256);
  const std::string png = encodePng(grey);
  EXPECT_EQ(maxDifference(decodeImage(png, ImageDecoding::kStoredGrey), grey), 0.0);
  cv::Mat grey3;
  cv::merge(std::vector<cv::Mat>{grey, grey, grey}, grey3);
  EXPECT_EQ(maxDifference(decodeImage(png, ImageDecoding::kRgb8), grey3), 0.0);
}

TEST(ImageCodec, JpegsMatchOpenCvsWithinTheCodecsRounding) {
  const cv::Mat bgr = testCard(64, 48);
  // Ours read by OpenCV: a JPEG at quality 95 of a smooth card is within a few levels of it.
  const cv::Mat back = openCvDecoded(encodeJpeg(bgr, 95), cv::IMREAD_COLOR);
  ASSERT_EQ(back.size(), bgr.size());
  EXPECT_LT(cv::norm(back, bgr, cv::NORM_L1) / static_cast<double>(bgr.total() * 3), 2.0);
  // OpenCV's read by ours: the same libjpeg-turbo decodes it, so within one level.
  const std::string theirs = openCvEncoded(".jpg", bgr);
  EXPECT_LE(maxDifference(decodeImage(theirs, ImageDecoding::kRgb8),
                          rgbOf(openCvDecoded(theirs, cv::IMREAD_COLOR))),
            1.0);
}

TEST(ImageCodec, DamagedOrForeignBytesDecodeToNothing) {
  const std::string png = encodePng(testCard(16, 16));
  EXPECT_TRUE(decodeImage(png.substr(0, png.size() / 2), ImageDecoding::kRgb8).empty());
  std::string bad_crc = png;
  const std::size_t middle = png.size() / 2;  // inside IDAT: its CRC no longer holds
  bad_crc[middle] = static_cast<char>(bad_crc[middle] ^ 0x55);
  EXPECT_TRUE(decodeImage(bad_crc, ImageDecoding::kRgb8).empty());
  EXPECT_TRUE(decodeImage("", ImageDecoding::kRgb8).empty());
  EXPECT_TRUE(decodeImage("GIF89a....", ImageDecoding::kRgb8).empty());
  const std::string jpeg = encodeJpeg(testCard(16, 16), 90);
  EXPECT_FALSE(decodeImage(jpeg, ImageDecoding::kRgb8).empty());
  EXPECT_TRUE(decodeImage(jpeg.substr(0, 20), ImageDecoding::kRgb8).empty());
  // Stray bytes before the start of scan: libjpeg's warning ("extraneous bytes before marker"),
  // after which TurboJPEG would report a later fatal error as a warning too. Refused.
  std::string stray = jpeg;
  const std::size_t scan = stray.find("\xff\xda");
  ASSERT_NE(scan, std::string::npos);
  stray.insert(scan, "\x12\x34");
  EXPECT_TRUE(decodeImage(stray, ImageDecoding::kRgb8).empty());
  // Cut short in its scan and given an end marker, as readImage's end check would pass: libjpeg
  // warns ("premature end of data segment") and fills the rest. Refused as well.
  const std::string big = encodeJpeg(testCard(64, 48), 90);
  const std::size_t big_scan = big.find("\xff\xda");
  ASSERT_NE(big_scan, std::string::npos);
  const std::string cut = big.substr(0, (big_scan + big.size()) / 2) + "\xff\xd9";
  EXPECT_TRUE(decodeImage(cut, ImageDecoding::kRgb8).empty());
}

TEST(ImageCodec, EncodersRefuseWhatTheyCannotWrite) {
  EXPECT_THROW(encodePng(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(encodePng(cv::Mat(2, 2, CV_32FC1, cv::Scalar(1.0f))), std::invalid_argument);
  EXPECT_THROW(encodeJpeg(cv::Mat(2, 2, CV_8UC1, cv::Scalar(1)), 90), std::invalid_argument);
  EXPECT_THROW(encodeJpeg(testCard(4, 4), 0), std::invalid_argument);
  // A view into a larger image (rows not contiguous) is written as the view.
  const cv::Mat card = testCard(20, 20);
  const cv::Mat view = card(cv::Rect(3, 4, 10, 6));
  EXPECT_EQ(maxDifference(openCvDecoded(encodePng(view), cv::IMREAD_COLOR), view.clone()), 0.0);
  const cv::Mat grey_view = cv::Mat(8, 8, CV_16UC1, cv::Scalar(700))(cv::Rect(1, 1, 3, 2));
  EXPECT_EQ(maxDifference(decodeImage(encodePng(grey_view), ImageDecoding::kStoredGrey),
                          grey_view.clone()),
            0.0);
}

}  // namespace
}  // namespace objscan
