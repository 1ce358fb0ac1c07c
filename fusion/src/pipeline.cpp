#include "objscan/fusion/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <tbb/parallel_for.h>

#include "objscan/core/clock.h"

namespace objscan::fusion {

namespace {

using Clock = SteadyClock;

/// Where each ray of pyramid level `level` starts its search: the nearest reading of the
/// 2^level x 2^level pixels the ray passes between (0 if none), the rule the frame's pyramid
/// follows at depth edges too.
void nearestPerBlock(const cv::Mat& depth, int level, cv::Mat* out) {
  const int step = 1 << level;
  out->create(depth.rows / step, depth.cols / step, CV_32FC1);
  tbb::parallel_for(0, out->rows, [&](int v) {
    float* o = out->ptr<float>(v);
    for (int u = 0; u < out->cols; ++u) {
      float nearest = 0.0f;
      for (int dv = 0; dv < step; ++dv) {
        const float* in = depth.ptr<float>(v * step + dv) + u * step;
        for (int du = 0; du < step; ++du) {
          if (in[du] > 0.0f && (nearest == 0.0f || in[du] < nearest)) nearest = in[du];
        }
      }
      o[u] = nearest;
    }
  });
}

}  // namespace

void FusionConfig::validate() const {
  preprocess.validate();
  volume.validate();
  tracking.validate();
  if (model_level < 0 || model_level > 2) {
    throw std::invalid_argument("the model's pyramid level must be 0 to 2");
  }
  if (!(min_valid_fraction >= 0.0f && min_valid_fraction < 1.0f)) {
    throw std::invalid_argument("the minimum share of valid depth must be in [0, 1)");
  }
}

Fusion::Fusion(const FusionConfig& config, const Intrinsics& intrinsics, const Pose& initial_T_W_C)
    : config_(config), intrinsics_(intrinsics), volume_(config.volume), last_good_(initial_T_W_C) {
  config_.validate();
  intrinsics_.validate();
  model_level_ = std::min(config_.model_level, config_.preprocess.pyramid_levels - 1);
  const int divisor = 1 << (config_.preprocess.pyramid_levels - 1);
  if (intrinsics_.width_px % divisor != 0 || intrinsics_.height_px % divisor != 0) {
    throw std::invalid_argument(
        "the image size " + std::to_string(intrinsics_.width_px) + "x" +
        std::to_string(intrinsics_.height_px) + " must divide by " + std::to_string(divisor) +
        " for a " + std::to_string(config_.preprocess.pyramid_levels) + "-level pyramid");
  }
}

FrameOutcome Fusion::process(const RgbdFrame& frame, const std::optional<Pose>& given_T_W_C) {
  frame.validate();
  if (frame.depth_m.cols != intrinsics_.width_px || frame.depth_m.rows != intrinsics_.height_px) {
    throw std::invalid_argument(
        "frame " + std::to_string(frame.index) + " is " + std::to_string(frame.depth_m.cols) + "x" +
        std::to_string(frame.depth_m.rows) + ", but the intrinsics are for " +
        std::to_string(intrinsics_.width_px) + "x" + std::to_string(intrinsics_.height_px));
  }
  ++processed_;
  FrameOutcome out;
  out.T_W_C = last_good_;

  auto start = Clock::now();
  clipDepth(frame.depth_m, config_.preprocess, &clipped_);
  const cv::Mat& depth = clipped_;
  const double valid = static_cast<double>(cv::countNonZero(depth));
  if (valid < config_.min_valid_fraction * static_cast<double>(depth.total()) || valid == 0.0) {
    out.status = FrameStatus::kNoDepth;
    out.reason = "no depth readings between " + std::to_string(config_.preprocess.min_depth_m) +
                 " and " + std::to_string(config_.preprocess.max_depth_m) + " m";
    out.timings.preprocess_ms = millisecondsSince(start);
    ++skipped_;
    return out;
  }

  Pose pose = last_good_;
  if (given_T_W_C) {
    pose = *given_T_W_C;
    out.status = FrameStatus::kGivenPose;
    out.timings.preprocess_ms = millisecondsSince(start);
  } else if (volume_.blockCount() == 0) {
    out.status = FrameStatus::kFirst;
    out.timings.preprocess_ms = millisecondsSince(start);
  } else {
    buildPyramid(depth, intrinsics_, config_.preprocess, &pyramid_,
                 config_.tracking.finest_level_stride);
    out.timings.preprocess_ms = millisecondsSince(start);
    start = Clock::now();
    if (!model_current_) {
      raycast(volume_, levelIntrinsics(intrinsics_, model_level_), last_good_,
              config_.preprocess.min_depth_m, config_.preprocess.max_depth_m, false, nullptr,
              &model_);
      model_current_ = true;
    }
    out.tracking = trackFrame(pyramid_, model_, last_good_, config_.tracking);
    out.timings.track_ms = millisecondsSince(start);
    if (!out.tracking.ok) {
      out.status = FrameStatus::kLost;
      out.reason = out.tracking.failure;
      ++lost_;
      return out;
    }
    pose = out.tracking.T_W_C;
    out.status = FrameStatus::kTracked;
  }

  start = Clock::now();
  out.blocks_updated = volume_.integrate(depth, frame.color_rgb, intrinsics_, pose);
  out.timings.integrate_ms = millisecondsSince(start);
  last_good_ = pose;
  out.T_W_C = pose;
  trajectory_.poses.push_back({frame.stamp_s, pose});
  model_current_ = false;
  if (!given_T_W_C) {
    // The model for the next frame; with given poses it is cast only when tracking needs it.
    start = Clock::now();
    if (model_level_ > 0) nearestPerBlock(depth, model_level_, &hint_);
    raycast(volume_, levelIntrinsics(intrinsics_, model_level_), pose,
            config_.preprocess.min_depth_m, config_.preprocess.max_depth_m, false,
            model_level_ > 0 ? &hint_ : &depth, &model_, config_.model_unhinted_rays);
    model_current_ = true;
    out.timings.raycast_ms = millisecondsSince(start);
  }
  return out;
}

}  // namespace objscan::fusion
