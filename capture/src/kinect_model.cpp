// The Kinect v1 camera model objscan uses where libfreenect gives no calibration
// (objscan/capture/freenect.h, KinectModel): raw 11-bit disparity to depth, and registration of
// the IR camera's depth to the colour camera.

#include <algorithm>
#include <cmath>

#include "freenect_library.h"
#include "objscan/capture/freenect.h"

namespace objscan::capture {

KinectModel KinectModel::nominal(const Intrinsics& color) {
  KinectModel m;
  m.ir = Intrinsics{580.0, 580.0, 319.5, 239.5, freenect_detail::kWidth, freenect_detail::kHeight};
  m.color = color;
  m.color_x_m = 0.025;
  m.projector_baseline_m = 0.075;
  m.disparity_offset = 1090.0;
  return m;
}

float KinectModel::metresFromRaw(std::uint16_t raw) const {
  if (raw >= 2047 || raw >= disparity_offset) return 0.0f;
  return static_cast<float>(8.0 * projector_baseline_m * ir.fx_px / (disparity_offset - raw));
}

std::uint16_t KinectModel::rawFromMetres(float z_m) const {
  if (!(z_m > 0.0f) || !std::isfinite(z_m)) return 2047;
  const double raw = disparity_offset - 8.0 * projector_baseline_m * ir.fx_px / z_m;
  if (raw < -0.5) return 2047;
  return static_cast<std::uint16_t>(std::min(2046.0, std::max(0.0, std::round(raw))));
}

namespace {

/// Forward warp of a depth image between two parallel cameras `dx_m` apart along x (a point
/// (x, y, z) in `from` is (x - dx_m, y, z) in `to`), nearest reading per pixel, then one-pixel
/// gaps between agreeing neighbours filled.
cv::Mat warpDepth(const cv::Mat& depth, const Intrinsics& from, const Intrinsics& to, double dx_m) {
  CV_Assert(depth.type() == CV_32FC1);
  cv::Mat out(to.height_px, to.width_px, CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < depth.rows; ++v) {
    const float* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const float z = row[u];
      if (!(z > 0.0f) || !std::isfinite(z)) continue;
      const double x = (u - from.cx_px) / from.fx_px * z - dx_m;
      const double y = (v - from.cy_px) / from.fy_px * z;
      const long ut = std::lround(to.fx_px * x / z + to.cx_px);
      const long vt = std::lround(to.fy_px * y / z + to.cy_px);
      if (ut < 0 || vt < 0 || ut >= to.width_px || vt >= to.height_px) continue;
      float& target = out.at<float>(static_cast<int>(vt), static_cast<int>(ut));
      if (target == 0.0f || z < target) target = z;
    }
  }
  const auto agree = [](float a, float b) {
    return a > 0.0f && b > 0.0f && std::abs(a - b) <= 0.03f * std::min(a, b);
  };
  cv::Mat filled = out.clone();
  for (int v = 1; v + 1 < out.rows; ++v) {
    for (int u = 1; u + 1 < out.cols; ++u) {
      if (out.at<float>(v, u) != 0.0f) continue;
      const float l = out.at<float>(v, u - 1), r = out.at<float>(v, u + 1);
      const float t = out.at<float>(v - 1, u), b = out.at<float>(v + 1, u);
      if (agree(l, r)) {
        filled.at<float>(v, u) = 0.5f * (l + r);
      } else if (agree(t, b)) {
        filled.at<float>(v, u) = 0.5f * (t + b);
      }
    }
  }
  return filled;
}

}  // namespace

cv::Mat KinectModel::registerToColor(const cv::Mat& ir_depth_m) const {
  return warpDepth(ir_depth_m, ir, color, color_x_m);
}

cv::Mat KinectModel::colorToIr(const cv::Mat& color_depth_m) const {
  return warpDepth(color_depth_m, color, ir, -color_x_m);
}

}  // namespace objscan::capture
