// Recording a sensor to `.oni` with openni::Recorder: `objscan record`. The recorder itself, and
// how it keeps every frame and always leaves a replayable file, is in oni_recorder.cpp.

#include <OpenNI.h>

#include <atomic>
#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "objscan/capture/openni.h"
#include "objscan/core/error.h"
#include "oni_recorder.h"
#include "openni_runtime.h"

namespace objscan::capture {
namespace {

using namespace openni_detail;
using Clock = std::chrono::steady_clock;

constexpr auto kStallTimeout = std::chrono::seconds(3);

}  // namespace

RecordSummary recordSession(const RecordOptions& options, const std::atomic<bool>& stop,
                            const RecordProgress& progress) {
  checkRecordingTarget(options.out);
  if (options.max_seconds && !(*options.max_seconds > 0.0)) {
    throw std::invalid_argument("--seconds must be positive");
  }
  if (options.max_frames && *options.max_frames == 0) {
    throw std::invalid_argument("--frames must be at least 1");
  }

  OpenNIPath alias;  // declared before the device: outlives it
  openni::Device device;
  openDevice(device, options.device_uri, &alias);
  const std::string uri = device.getDeviceInfo().getUri();
  openni::VideoStream depth;
  openni::VideoStream color;
  bool has_color = false;
  createLiveStreams(device, depth, color, &has_color);

  const LiveSensorFacts live = liveSensorFacts(device, depth);
  RecordingFacts facts;
  facts.device_uri = alias.aliased() ? options.device_uri : uri;
  facts.intrinsics = live.intrinsics;
  facts.intrinsics_origin = live.intrinsics_origin;
  facts.time_offset_s = live.time_offset_s;
  facts.ground_truth = options.ground_truth;
  std::optional<std::size_t> limit = options.max_frames;
  std::string stop_at_end;
  if (live.frame_count && *live.frame_count > 0 && (!limit || *limit >= *live.frame_count)) {
    limit = live.frame_count;
    stop_at_end = "end of the virtual sensor's source";
  }

  if (options.intrinsics) {
    const Intrinsics& sensor = facts.intrinsics;
    if (options.intrinsics->width_px != sensor.width_px ||
        options.intrinsics->height_px != sensor.height_px) {
      throw std::invalid_argument(
          "--intrinsics are for " + std::to_string(options.intrinsics->width_px) + "x" +
          std::to_string(options.intrinsics->height_px) + " images but the sensor streams " +
          std::to_string(sensor.width_px) + "x" + std::to_string(sensor.height_px));
    }
    facts.intrinsics = *options.intrinsics;
    facts.intrinsics_origin = "given with --intrinsics";
  }

  OniRecorder recorder({options.out, options.compress_color, options.min_free_bytes, limit,
                        OniRecorder::Options::Counting::kInCallbacks},
                       depth, has_color ? &color : nullptr);
  recorder.start();
  const auto start = Clock::now();
  if (depth.start() != openni::STATUS_OK || (has_color && color.start() != openni::STATUS_OK)) {
    throw std::runtime_error("cannot start the sensor's streams: " + lastError());
  }
  std::string stop_reason;
  bool failed = false;
  bool stalled = false;  // the sensor stopped delivering frames while still attached
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const OniRecorder::Progress s = recorder.progress();
    const auto now = Clock::now();
    const double seconds =
        s.depth_frames > 0 ? std::chrono::duration<double>(now - s.first_frame).count() : 0.0;
    if (progress) progress(s.depth_frames, seconds);
    if (s.limit_reached) {
      stop_reason = stop_at_end.empty() ? "frame limit" : stop_at_end;
      break;
    }
    if (stop.load()) {
      stop_reason = "interrupted";
      break;
    }
    if (options.max_seconds && s.depth_frames > 0 && seconds >= *options.max_seconds) {
      stop_reason = "time limit";
      break;
    }
    const auto last = s.depth_frames > 0 ? s.last_frame : start;
    if (wasDisconnected(uri) || now - last > kStallTimeout) {
      stalled = !wasDisconnected(uri);
      stop_reason = sensorLostReason(s.depth_frames, !stalled);
      failed = true;
      break;
    }
    if (s.disk_low) {
      stop_reason = kDiskNearlyFull;
      failed = true;
      break;
    }
  }
  recorder.close();
  depth.destroy();
  if (has_color) color.destroy();
  device.close();
  // A virtual sensor whose every frame is in the file ended; it was not lost (publish says why
  // the counts can fall short).
  std::optional<std::pair<std::size_t, std::string>> complete_at;
  if (stalled && !stop_at_end.empty()) complete_at.emplace(*limit, stop_at_end);
  return recorder.publish(facts, stop_reason, failed, complete_at);
}

}  // namespace objscan::capture
