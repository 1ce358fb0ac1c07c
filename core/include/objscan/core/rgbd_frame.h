#pragma once

#include <cstdint>
#include <opencv2/core/mat.hpp>

#include "objscan/core/intrinsics.h"

namespace objscan {

/// One synchronised depth + colour image pair, as every capture source delivers it.
struct RgbdFrame {
  std::int64_t index = 0;  ///< position in its stream, from 0
  /// The sensor's own number of the depth frame (OpenNI2's frame index), -1 when the source has
  /// none: on a live sensor, gaps between consecutive frames are frames the reader missed.
  std::int64_t device_frame = -1;
  double stamp_s = 0.0;    ///< capture time in seconds (sensor or dataset clock)
  /// CV_32FC1, metres along the optical axis (z, not ray length); 0 or NaN = no reading.
  cv::Mat depth_m;
  /// CV_8UC3 in R, G, B order (not OpenCV's usual BGR), same size as depth; may be empty.
  cv::Mat color_rgb;
  Intrinsics intrinsics;  ///< of the depth image (colour is registered to it)

  /// Throws std::invalid_argument when the images do not match the types and sizes above.
  void validate() const;
};

}  // namespace objscan
