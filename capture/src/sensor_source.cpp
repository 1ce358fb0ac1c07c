// Live capture from an OpenNI2 sensor (a real one or objscan's virtual sensor), optionally
// recording the sensor's streams to `.oni` while they are read.

#include <OpenNI.h>

#include <chrono>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>

#include "objscan/capture/openni.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "oni_recorder.h"
#include "openni_path.h"
#include "openni_runtime.h"

namespace objscan::capture {
namespace {

using namespace openni_detail;

constexpr int kStallTimeoutMs = 3000;
constexpr int kWaitSliceMs = 100;
constexpr std::uint64_t kPairToleranceUs = 20000;

/// The sensor, its streams and, when recording, the recorder attached to them. Wrapped by the two
/// FrameSource classes below, so that only a recording source is a RecordingFrameSource.
class Sensor {
 public:
  Sensor(const std::string& uri, const std::optional<Intrinsics>& intrinsics_override,
         const std::string& intrinsics_origin, const std::optional<LiveRecording>& record) {
    if (record) checkRecordingTarget(record->out);  // before the sensor starts anything
    openDevice(device_, uri, &uri_alias_);
    uri_ = device_.getDeviceInfo().getUri();
    createLiveStreams(device_, depth_, color_, &has_color_);
    const LiveSensorFacts facts = liveSensorFacts(device_, depth_);
    info_.intrinsics = facts.intrinsics;
    info_.intrinsics_origin = facts.intrinsics_origin;
    info_.frame_count = facts.frame_count;
    time_offset_s_ = facts.time_offset_s;
    limit_ = facts.frame_count;
    if (intrinsics_override) {
      info_.intrinsics = *intrinsics_override;
      info_.intrinsics_origin = intrinsics_origin.empty() ? "given" : intrinsics_origin;
    }
    info_.intrinsics_assumed = info_.intrinsics_origin.rfind("Xtion defaults", 0) == 0;
    info_.depth_units = "OpenNI2 depth in millimetres";
    requireIntrinsicsFit(depth_, info_, uri_);
    info_.live = true;
    info_.description = std::string("sensor ") + device_.getDeviceInfo().getName() + " (" +
                        (uri_alias_.aliased() ? uri : uri_) + ")";
    if (record) {
      facts_ = {info_.intrinsics, info_.intrinsics_origin, time_offset_s_,
                uri_alias_.aliased() ? uri : uri_, record->ground_truth};
      OniRecorder::Options options;
      options.out = record->out;
      options.compress_color = record->compress_color;
      options.min_free_bytes = record->min_free_bytes;
      options.counting = OniRecorder::Options::Counting::kByReader;  // next() reads the streams
      recorder_ = std::make_unique<OniRecorder>(options, depth_, has_color_ ? &color_ : nullptr);
      recorder_->start();
      info_.description += ", recording to " + record->out.string();
    }
    if (depth_.start() != openni::STATUS_OK ||
        (has_color_ && color_.start() != openni::STATUS_OK)) {
      throw std::runtime_error("cannot start the sensor's streams: " + lastError());
    }
  }

  ~Sensor() {
    if (recorder_ && !summary_ && !finish_error_) {
      try {
        finishRecording("the source was closed without finishing the recording");
      } catch (const std::exception& e) {
        log::warning(recorder_->out().string() + ": " + e.what());
      } catch (...) {
        log::warning(recorder_->out().string() + ": the recording could not be finished");
      }
    }
    recorder_.reset();  // closes the recorder (if finishing failed) before the streams go
    depth_.stop();
    if (has_color_) color_.stop();
    depth_.destroy();
    if (has_color_) color_.destroy();
    device_.close();
  }

  Sensor(const Sensor&) = delete;
  Sensor& operator=(const Sensor&) = delete;

  const SourceInfo& info() const { return info_; }

  FrameResult next() {
    if (stopped_) return FrameResult::end();
    if (limit_ && delivered_ >= *limit_) {
      reached_end_ = true;
      return FrameResult::end();
    }
    if (recorder_ && recorder_->progress().disk_low) {
      // The recording stopped to keep the disk from filling: so does the stream, so that what was
      // fused and what was recorded stay the same scan. finishRecording() reports it.
      stopped_ = true;
      return FrameResult::end();
    }
    openni::VideoStream* streams[2] = {&depth_, &color_};
    const int count = has_color_ ? 2 : 1;
    for (;;) {
      int ready = -1;
      // Waits in slices, so that an unplugged sensor is noticed at once, not after the timeout.
      openni::Status waited = openni::STATUS_TIME_OUT;
      for (int ms = 0; ms < kStallTimeoutMs && waited != openni::STATUS_OK; ms += kWaitSliceMs) {
        waited = openni::OpenNI::waitForAnyStream(streams, count, &ready, kWaitSliceMs);
        if (waited != openni::STATUS_OK && wasDisconnected(uri_)) break;
      }
      if (waited != openni::STATUS_OK) {
        if (limit_ && !wasDisconnected(uri_)) {
          // A virtual sensor whose source has ended. Its frame count is not reached when the
          // reader was slower than the sensor's 30 Hz: OpenNI2 then keeps only the newest frame.
          // An unplugged one is lost like any sensor, recording or not.
          reached_end_ = true;
          return FrameResult::end();
        }
        lost_ = true;
        throw std::runtime_error("sensor " + uri_ + " stopped delivering frames after " +
                                 std::to_string(delivered_) + " frames" +
                                 (wasDisconnected(uri_) ? " (it was unplugged)" : " (unplugged?)"));
      }
      openni::VideoFrameRef ref;
      if (streams[ready]->readFrame(&ref) != openni::STATUS_OK) continue;
      if (recorder_) recorder_->countFrame(ref);
      if (ready == 1) {
        last_color_ = colorToRgb(ref);
        last_color_us_ = ref.getTimestamp();
        if (pending_depth_.empty() || !near(last_color_us_, pending_depth_us_)) continue;
      } else {
        pending_depth_ = depthToMetres(ref);
        pending_depth_us_ = ref.getTimestamp();
        pending_depth_number_ = ref.getFrameIndex();
        if (has_color_ && (last_color_.empty() || !near(last_color_us_, pending_depth_us_))) {
          // Wait a little for the colour frame of this pair; give up at the next depth frame.
          continue;
        }
      }
      return emit();
    }
  }

  RecordSummary finishRecording(const std::string& reason) {
    if (summary_) return *summary_;
    if (finish_error_) std::rethrow_exception(finish_error_);
    if (!recorder_) throw std::logic_error("finishRecording: this sensor source records nothing");
    recorder_->close();  // stops the streams too
    stopped_ = true;
    const OniRecorder::Progress p = recorder_->progress();
    std::string why = reason;
    bool failed = false;
    if (p.disk_low) {
      why = kDiskNearlyFull;
      failed = true;
    } else if (lost_ || wasDisconnected(uri_)) {
      why = sensorLostReason(p.depth_frames, wasDisconnected(uri_));
      failed = true;
    } else if (reached_end_) {
      why = "end of the virtual sensor's source";
    }
    try {
      summary_ = recorder_->publish(facts_, why, failed);
    } catch (...) {
      finish_error_ = std::current_exception();
      throw;
    }
    return *summary_;
  }

 private:
  static bool near(std::uint64_t a, std::uint64_t b) {
    return (a > b ? a - b : b - a) <= kPairToleranceUs;
  }

  FrameResult emit() {
    RgbdFrame frame;
    frame.index = static_cast<std::int64_t>(delivered_++);
    frame.stamp_s = time_offset_s_ + static_cast<double>(pending_depth_us_) * 1e-6;
    frame.device_frame = pending_depth_number_;
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
  OpenNIPath uri_alias_;  ///< before device_: a virtual sensor's source outlives the device
  openni::Device device_;
  openni::VideoStream depth_;
  openni::VideoStream color_;
  bool has_color_ = false;
  double time_offset_s_ = 0.0;
  std::optional<std::size_t> limit_;
  std::size_t delivered_ = 0;
  cv::Mat pending_depth_;
  std::uint64_t pending_depth_us_ = 0;
  std::int64_t pending_depth_number_ = -1;
  cv::Mat last_color_;
  std::uint64_t last_color_us_ = 0;
  bool stopped_ = false;      ///< finished recording, or the recording stopped: next() ends
  bool reached_end_ = false;  ///< next() ended at the end of a virtual sensor's source
  bool lost_ = false;         ///< next() threw: the sensor stopped delivering
  // Declared after the streams: destroyed (and so closed) before them.
  RecordingFacts facts_;
  std::unique_ptr<OniRecorder> recorder_;
  std::optional<RecordSummary> summary_;
  std::exception_ptr finish_error_;
};

class SensorSource final : public FrameSource {
 public:
  explicit SensorSource(std::unique_ptr<Sensor> sensor) : sensor_(std::move(sensor)) {}
  const SourceInfo& info() const override { return sensor_->info(); }
  FrameResult next() override { return sensor_->next(); }

 private:
  std::unique_ptr<Sensor> sensor_;
};

class RecordingSensorSource final : public RecordingFrameSource {
 public:
  explicit RecordingSensorSource(std::unique_ptr<Sensor> sensor) : sensor_(std::move(sensor)) {}
  const SourceInfo& info() const override { return sensor_->info(); }
  FrameResult next() override { return sensor_->next(); }
  RecordSummary finishRecording(const std::string& reason) override {
    return sensor_->finishRecording(reason);
  }

 private:
  std::unique_ptr<Sensor> sensor_;
};

}  // namespace

std::unique_ptr<FrameSource> openSensor(const std::string& uri,
                                        const std::optional<Intrinsics>& intrinsics_override,
                                        const std::string& intrinsics_origin,
                                        const std::optional<LiveRecording>& record) {
  auto sensor = std::make_unique<Sensor>(uri, intrinsics_override, intrinsics_origin, record);
  if (record) return std::make_unique<RecordingSensorSource>(std::move(sensor));
  return std::make_unique<SensorSource>(std::move(sensor));
}

std::optional<RecordSummary> finishRecording(FrameSource& source, const std::string& reason) {
  auto* recording = dynamic_cast<RecordingFrameSource*>(&source);
  if (recording == nullptr) return std::nullopt;
  return recording->finishRecording(reason);
}

}  // namespace objscan::capture
