#include "objscan/core/rgbd_frame.h"

#include <stdexcept>
#include <string>

namespace objscan {

void RgbdFrame::validate() const {
  intrinsics.validate();
  const std::string where = "frame " + std::to_string(index) + ": ";
  if (depth_m.type() != CV_32FC1)
    throw std::invalid_argument(where + "depth must be a CV_32FC1 image in metres");
  if (depth_m.cols != intrinsics.width_px || depth_m.rows != intrinsics.height_px) {
    throw std::invalid_argument(where + "depth is " + std::to_string(depth_m.cols) + "x" +
                                std::to_string(depth_m.rows) + " but the intrinsics say " +
                                std::to_string(intrinsics.width_px) + "x" +
                                std::to_string(intrinsics.height_px));
  }
  if (!color_rgb.empty()) {
    if (color_rgb.type() != CV_8UC3)
      throw std::invalid_argument(where + "colour must be a CV_8UC3 RGB image");
    if (color_rgb.size() != depth_m.size()) {
      throw std::invalid_argument(where + "colour and depth images differ in size");
    }
  }
}

}  // namespace objscan
