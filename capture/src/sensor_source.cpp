// Live capture from an OpenNI2 sensor (a real one or objscan's virtual sensor).

#include <OpenNI.h>

#include <chrono>
#include <stdexcept>
#include <string>

#include "objscan/capture/openni.h"
#include "objscan/core/error.h"
#include "openni_runtime.h"

namespace objscan::capture {
namespace {

using namespace openni_detail;

constexpr int kStallTimeoutMs = 3000;
constexpr std::uint64_t kPairToleranceUs = 20000;

class SensorSource final : public FrameSource {
 public:
  SensorSource(const std::string& uri, const std::optional<Intrinsics>& intrinsics_override,
               const std::string& intrinsics_origin) {
    openDevice(device_, uri);
    uri_ = device_.getDeviceInfo().getUri();
    createLiveStreams(device_, depth_, color_, &has_color_);
    if (const auto facts = virtualDeviceFacts(device_)) {
      info_.intrinsics = facts->intrinsics;
      info_.intrinsics_origin = "the virtual sensor's source";
      info_.frame_count = facts->frame_count;
      time_offset_s_ = facts->time_offset_s;
      limit_ = facts->frame_count;
    } else {
      info_.intrinsics = intrinsicsFromStream(depth_, &info_.intrinsics_origin);
    }
    if (intrinsics_override) {
      info_.intrinsics = *intrinsics_override;
      info_.intrinsics_origin = intrinsics_origin.empty() ? "given" : intrinsics_origin;
    }
    requireIntrinsicsFit(depth_, info_, uri_);
    info_.live = true;
    info_.description =
        std::string("sensor ") + device_.getDeviceInfo().getName() + " (" + uri_ + ")";
    if (depth_.start() != openni::STATUS_OK ||
        (has_color_ && color_.start() != openni::STATUS_OK)) {
      throw std::runtime_error("cannot start the sensor's streams: " + lastError());
    }
  }

  ~SensorSource() override {
    depth_.stop();
    if (has_color_) color_.stop();
    depth_.destroy();
    if (has_color_) color_.destroy();
    device_.close();
  }

  const SourceInfo& info() const override { return info_; }

  FrameResult next() override {
    if (limit_ && delivered_ >= *limit_) return FrameResult::end();
    openni::VideoStream* streams[2] = {&depth_, &color_};
    const int count = has_color_ ? 2 : 1;
    for (;;) {
      int ready = -1;
      if (openni::OpenNI::waitForAnyStream(streams, count, &ready, kStallTimeoutMs) !=
          openni::STATUS_OK) {
        if (limit_ && wasDisconnected(uri_)) return FrameResult::end();
        throw std::runtime_error("sensor " + uri_ + " stopped delivering frames after " +
                                 std::to_string(delivered_) + " frames" +
                                 (wasDisconnected(uri_) ? " (it was unplugged)" : " (unplugged?)"));
      }
      openni::VideoFrameRef ref;
      if (streams[ready]->readFrame(&ref) != openni::STATUS_OK) continue;
      if (ready == 1) {
        last_color_ = colorToRgb(ref);
        last_color_us_ = ref.getTimestamp();
        if (pending_depth_.empty() || !near(last_color_us_, pending_depth_us_)) continue;
      } else {
        pending_depth_ = depthToMetres(ref);
        pending_depth_us_ = ref.getTimestamp();
        if (has_color_ && (last_color_.empty() || !near(last_color_us_, pending_depth_us_))) {
          // Wait a little for the colour frame of this pair; give up at the next depth frame.
          continue;
        }
      }
      return emit();
    }
  }

 private:
  static bool near(std::uint64_t a, std::uint64_t b) {
    return (a > b ? a - b : b - a) <= kPairToleranceUs;
  }

  FrameResult emit() {
    RgbdFrame frame;
    frame.index = static_cast<std::int64_t>(delivered_++);
    frame.stamp_s = time_offset_s_ + static_cast<double>(pending_depth_us_) * 1e-6;
    frame.depth_m = std::move(pending_depth_);
    pending_depth_ = cv::Mat();
    if (has_color_ && near(last_color_us_, pending_depth_us_) &&
        last_color_.size() == frame.depth_m.size()) {
      frame.color_rgb = last_color_;
    }
    frame.intrinsics = info_.intrinsics;
    return FrameResult::ok(std::move(frame));
  }

  std::string uri_;
  SourceInfo info_;
  openni::Device device_;
  openni::VideoStream depth_;
  openni::VideoStream color_;
  bool has_color_ = false;
  double time_offset_s_ = 0.0;
  std::optional<std::size_t> limit_;
  std::size_t delivered_ = 0;
  cv::Mat pending_depth_;
  std::uint64_t pending_depth_us_ = 0;
  cv::Mat last_color_;
  std::uint64_t last_color_us_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> openSensor(const std::string& uri,
                                        const std::optional<Intrinsics>& intrinsics_override,
                                        const std::string& intrinsics_origin) {
  return std::make_unique<SensorSource>(uri, intrinsics_override, intrinsics_origin);
}

}  // namespace objscan::capture
