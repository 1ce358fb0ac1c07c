#pragma once

#include <opencv2/core/mat.hpp>
#include <string>
#include <string_view>

/// PNG and JPEG in memory, through libspng and libjpeg-turbo's TurboJPEG.
///
/// Not OpenCV's imgcodecs: that library brings about 140 shared libraries with it (GDAL, GDCM,
/// OpenEXR, libheif, ...), and loading them took 0.14 s at every start of objscan, longer than
/// reading a camera view. These two are small, fuzzed upstream and report errors by return value.
namespace objscan {

/// What decodeImage makes of the stored samples.
enum class ImageDecoding {
  /// A greyscale PNG as stored: CV_8UC1 (depths of 1 to 8 bits widened to 8) or CV_16UC1 in the
  /// host's byte order (a depth image); a greyscale JPEG as CV_8UC1. Anything else as kRgb8
  /// would give it.
  kStoredGrey,
  /// CV_8UC3 in R, G, B order: 16-bit samples keep their high byte, a palette is looked up, grey is
  /// repeated, alpha and gamma are ignored.
  kRgb8,
};

/// Decodes a whole PNG or JPEG held in `bytes`. An empty Mat when `bytes` are neither or cannot
/// be decoded, a JPEG that decodes only with a warning (a damaged stream) included. EXIF
/// orientation is not applied, and CMYK JPEGs are not read. Callers bound the declared size first
/// (a header can ask for any size).
cv::Mat decodeImage(std::string_view bytes, ImageDecoding decoding);

/// A PNG of `image`: CV_8UC1 or CV_16UC1 (grey), CV_8UC3 (B, G, R order, as OpenCV keeps colour)
/// or CV_8UC4 (B, G, R, alpha). Throws std::invalid_argument for another type or an empty image,
/// std::runtime_error when the encoder fails.
std::string encodePng(const cv::Mat& image);

/// A baseline JPEG of `bgr` (CV_8UC3, B, G, R order) at `quality` 1-100, 4:2:0 chroma. Throws as
/// encodePng.
std::string encodeJpeg(const cv::Mat& bgr, int quality);

}  // namespace objscan
