// objscan's virtual OpenNI2 sensor driver (see objscan/capture/virtual_sensor.h for the URIs).
//
// Why a driver and not a FrameSource: the point is to run the REAL OpenNI2 runtime (device
// enumeration, stream start/stop, frame sync, openni::Recorder, the file player) with no hardware
// attached, so recording and replay are tested end to end exactly as they run against an Xtion.
//
// Threading: one producer thread per open device. It creates the frame source (synthetic scenes
// render through OSMesa, whose contexts belong to the thread that made them), paces frames at the
// requested rate and hands each depth/colour pair to OpenNI2 through the streams' new-frame
// callbacks. Stream start/stop and property calls come from application threads; a recursive
// mutex orders them with delivery (recursive: application frame listeners run inside delivery and
// may call back into the driver). stop() returns only once no delivery to that stream is running;
// deviceClose() joins the thread (Debian's DummyDevice does neither).

// Debian's OpenNI2 headers use XN_NEW/XN_DELETE in ONI_EXPORT_DRIVER without defining them.
#define XN_NEW(type, ...) new type(__VA_ARGS__)
#define XN_DELETE(p) delete (p)

#include <Driver/OniDriverAPI.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "objscan/capture/frame_source.h"
#include "objscan/capture/freenect.h"
#include "objscan/capture/synthetic/synthetic_source.h"
#include "objscan/capture/virtual_sensor.h"

namespace {

using objscan::capture::FrameSource;
using objscan::capture::FrameStatus;
using objscan::capture::VirtualSensorUri;
namespace vprop = objscan::capture::virtual_property;

// The recorder sizes its lossless depth codec (16z with tables) from the stream's maximum value and
// corrupts larger readings, so announce the whole 16-bit range (TUM data reaches 13 m).
constexpr int kMaxDepthMm = 65535;

void copyString(char* dst, std::size_t capacity, const std::string& src) {
  const std::size_t n = std::min(capacity - 1, src.size());
  std::memcpy(dst, src.data(), n);
  dst[n] = '\0';
}

class VirtualDevice;

class VirtualStream : public oni::driver::StreamBase {
 public:
  VirtualStream(VirtualDevice& device, OniSensorType type) : device_(device), type_(type) {}

  OniSensorType type() const { return type_; }
  bool started() const { return started_; }

  OniStatus start() override;
  void stop() override;
  OniStatus getProperty(int id, void* data, int* size) override;
  OniStatus setProperty(int id, const void* data, int size) override;
  OniBool isPropertySupported(int id) override;

  /// Called by the producer with the device lock held.
  void deliver(const void* pixels, int bytes, int width, int height, int frame_index,
               std::uint64_t timestamp_us);

 private:
  VirtualDevice& device_;
  OniSensorType type_;
  bool started_ = false;
};

class VirtualDevice : public oni::driver::DeviceBase {
 public:
  VirtualDevice(VirtualSensorUri uri, oni::driver::DriverServices& services)
      : uri_(std::move(uri)), services_(services) {}

  ~VirtualDevice() override { close(); }

  /// Starts the producer thread and waits until it has opened the source. Returns the error
  /// message, empty on success.
  std::string open() {
    std::promise<std::string> opened;
    std::future<std::string> result = opened.get_future();
    thread_ = std::thread([this, p = std::move(opened)]() mutable { run(std::move(p)); });
    std::string error = result.get();
    if (!error.empty()) close();
    return error;
  }

  void close() {
    {
      std::lock_guard<std::recursive_mutex> lock(mutex_);
      quit_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  std::recursive_mutex& mutex() { return mutex_; }

  void streamStartedOrStopped() {
    {
      std::lock_guard<std::recursive_mutex> lock(mutex_);
      restart_clock_ = true;
    }
    wake_.notify_all();
  }

  OniVideoMode videoMode(OniSensorType type) const {
    OniVideoMode mode{};
    mode.pixelFormat =
        type == ONI_SENSOR_DEPTH ? ONI_PIXEL_FORMAT_DEPTH_1_MM : ONI_PIXEL_FORMAT_RGB888;
    mode.resolutionX = intrinsics_.width_px;
    mode.resolutionY = intrinsics_.height_px;
    mode.fps = static_cast<int>(std::lround(uri_.fps));
    return mode;
  }
  const objscan::Intrinsics& intrinsics() const { return intrinsics_; }

  OniStatus getSensorInfoList(OniSensorInfo** infos, int* count) override {
    *infos = sensors_.data();
    *count = static_cast<int>(sensors_.size());
    return ONI_STATUS_OK;
  }

  oni::driver::StreamBase* createStream(OniSensorType type) override {
    if ((type == ONI_SENSOR_DEPTH && !uri_.depth) || (type == ONI_SENSOR_COLOR && !uri_.color) ||
        (type != ONI_SENSOR_DEPTH && type != ONI_SENSOR_COLOR)) {
      return nullptr;
    }
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    streams_.push_back(new VirtualStream(*this, type));
    return streams_.back();
  }

  void destroyStream(oni::driver::StreamBase* stream) override {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    streams_.erase(std::remove(streams_.begin(), streams_.end(), stream), streams_.end());
    delete stream;
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    switch (id) {
      case ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION:
        return put(data, size, registration_);
      case ONI_DEVICE_PROPERTY_SERIAL_NUMBER: {
        if (*size < 2) return ONI_STATUS_BAD_PARAMETER;
        copyString(static_cast<char*>(data), static_cast<std::size_t>(*size), "objscan-virtual");
        return ONI_STATUS_OK;
      }
      case vprop::kIntrinsics: {
        const double values[6] = {intrinsics_.fx_px,
                                  intrinsics_.fy_px,
                                  intrinsics_.cx_px,
                                  intrinsics_.cy_px,
                                  static_cast<double>(intrinsics_.width_px),
                                  static_cast<double>(intrinsics_.height_px)};
        if (*size != static_cast<int>(sizeof(values))) return ONI_STATUS_BAD_PARAMETER;
        std::memcpy(data, values, sizeof(values));
        return ONI_STATUS_OK;
      }
      case vprop::kFrameCount:
        return put(data, size, frame_count_);
      case vprop::kTimeOffset:
        return put(data, size, time_offset_s_);
      case vprop::kDescription: {
        if (*size < 2) return ONI_STATUS_BAD_PARAMETER;
        copyString(static_cast<char*>(data), static_cast<std::size_t>(*size), description_);
        return ONI_STATUS_OK;
      }
      default:
        return ONI_STATUS_NOT_SUPPORTED;
    }
  }

  OniStatus setProperty(int id, const void* data, int size) override {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION) return ONI_STATUS_NOT_SUPPORTED;
    if (size != static_cast<int>(sizeof(OniImageRegistrationMode))) {
      return ONI_STATUS_BAD_PARAMETER;
    }
    // The frames are registered already (datasets store depth in the colour camera's frame), so
    // both modes deliver the same pixels.
    std::memcpy(&registration_, data, sizeof(registration_));
    return ONI_STATUS_OK;
  }

  OniBool isPropertySupported(int id) override {
    return id == ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION ||
           id == ONI_DEVICE_PROPERTY_SERIAL_NUMBER || id == vprop::kIntrinsics ||
           id == vprop::kFrameCount || id == vprop::kTimeOffset || id == vprop::kDescription;
  }

  OniBool isImageRegistrationModeSupported(OniImageRegistrationMode) override { return TRUE; }

  /// Set by the driver: called once unplug_after frames went out.
  std::function<void()> on_unplug;

 private:
  template <typename T>
  static OniStatus put(void* data, int* size, const T& value) {
    if (*size != static_cast<int>(sizeof(T))) return ONI_STATUS_BAD_PARAMETER;
    std::memcpy(data, &value, sizeof(T));
    return ONI_STATUS_OK;
  }

  bool allStarted() const {
    return std::all_of(streams_.begin(), streams_.end(),
                       [](const VirtualStream* s) { return s->started(); });
  }

  bool anyStreamStarted() const {
    return std::any_of(streams_.begin(), streams_.end(),
                       [](const VirtualStream* s) { return s->started(); });
  }

  void run(std::promise<std::string> opened) {
    std::unique_ptr<FrameSource> source;
    try {
      // A Kinect (libfreenect) streams through this driver so that OpenNI2's recorder can record
      // it.
      source = objscan::capture::isFreenectSource(uri_.source)
                   ? objscan::capture::openFreenect(uri_.source)
                   : objscan::capture::openSynthOrFolderSource(uri_.source);
      const objscan::capture::SourceInfo& info = source->info();
      live_ = info.live;
      intrinsics_ = info.intrinsics;
      description_ = info.description;
      // unplug_after is not announced: a real sensor gives no warning either.
      frame_count_ = static_cast<int>(info.frame_count.value_or(0));
      // Read ahead to the first good frame: its stamp is the origin of OpenNI2's clock.
      for (;;) {
        pending_ = source->next();
        if (pending_.status != FrameStatus::kBadFrame) break;
        services_.errorLoggerAppend("virtual sensor skipped a frame: %s", pending_.reason.c_str());
      }
      if (pending_.status == FrameStatus::kOk) time_offset_s_ = pending_.frame.stamp_s;
      for (OniSensorType type : {ONI_SENSOR_DEPTH, ONI_SENSOR_COLOR}) {
        if ((type == ONI_SENSOR_DEPTH && !uri_.depth) ||
            (type == ONI_SENSOR_COLOR && !uri_.color)) {
          continue;
        }
        modes_.push_back(videoMode(type));
      }
      for (std::size_t i = 0; i < modes_.size(); ++i) {
        OniSensorInfo sensor{};
        sensor.sensorType = modes_[i].pixelFormat == ONI_PIXEL_FORMAT_DEPTH_1_MM ? ONI_SENSOR_DEPTH
                                                                                 : ONI_SENSOR_COLOR;
        sensor.numSupportedVideoModes = 1;
        sensor.pSupportedVideoModes = &modes_[i];
        sensors_.push_back(sensor);
      }
    } catch (const std::exception& e) {
      opened.set_value(e.what());
      return;
    }
    opened.set_value({});

    std::vector<std::uint16_t> depth_mm;
    int emitted = 0;
    auto clock_start = std::chrono::steady_clock::now();
    std::unique_lock<std::recursive_mutex> lock(mutex_);
    while (!quit_) {
      wake_.wait(lock, [&] { return quit_ || (anyStreamStarted() && !finished_); });
      if (quit_) break;
      if (emitted == 0) {
        // Programs start depth and colour one after the other: give the second time to start, so
        // that the first frame reaches both. 200 ms was too short (under the sanitizers, beside
        // other tests, `record` once started colour later, and its recording lacked the first
        // colour frame), and so was a second (a fresh clone's tests beside its build lost a
        // Kinect's first colour frame; sanitizer runs of the OpenNI2 tests beside the live-page
        // tests a folder's). Only a program that creates a colour stream and never starts it
        // waits the whole 5 s.
        wake_.wait_for(lock, std::chrono::seconds(5), [&] { return quit_ || allStarted(); });
        if (quit_) break;
      }
      if (restart_clock_) {
        clock_start = std::chrono::steady_clock::now() -
                      std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                          std::chrono::duration<double>(emitted / uri_.fps));
        restart_clock_ = false;
      }
      lock.unlock();
      objscan::capture::FrameResult result;
      if (emitted == 0 && pending_.status == FrameStatus::kOk) {
        result = std::move(pending_);
        pending_ = {};
      } else {
        try {
          result = source->next();
        } catch (const std::exception& e) {
          if (live_) {
            // A sensor behind this one was lost: so is this one.
            services_.errorLoggerAppend("%s", e.what());
            lock.lock();
            finished_ = true;
            if (on_unplug) on_unplug();
            continue;
          }
          result = objscan::capture::FrameResult::bad(e.what());
        }
      }
      lock.lock();
      if (quit_) break;
      if (result.status == FrameStatus::kEndOfStream) {
        finished_ = true;
        continue;
      }
      if (result.status == FrameStatus::kBadFrame) {
        services_.errorLoggerAppend("virtual sensor skipped a frame: %s", result.reason.c_str());
        continue;
      }
      const auto deadline =
          clock_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(emitted / uri_.fps));
      // A sensor behind this one keeps its own pace.
      if (!live_) wake_.wait_until(lock, deadline, [&] { return quit_; });
      if (quit_) break;

      const objscan::RgbdFrame& frame = result.frame;
      // The sensor's own frame numbers, where it has them, so that a frame it dropped is a gap.
      const int number =
          frame.device_frame >= 0 ? static_cast<int>(frame.device_frame) + 1 : emitted + 1;
      const auto timestamp_us = static_cast<std::uint64_t>(
          std::max(0.0, std::round((frame.stamp_s - time_offset_s_) * 1e6)));
      const int width = frame.depth_m.cols;
      const int height = frame.depth_m.rows;
      depth_mm.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
      for (int v = 0; v < height; ++v) {
        const float* row = frame.depth_m.ptr<float>(v);
        for (int u = 0; u < width; ++u) {
          const float mm = row[u] * 1000.0f;
          if (std::isfinite(mm) && mm > 0.0f && mm < 65535.5f) {
            depth_mm[static_cast<std::size_t>(v) * static_cast<std::size_t>(width) +
                     static_cast<std::size_t>(u)] = static_cast<std::uint16_t>(std::lround(mm));
          }
        }
      }
      // Iterate over a copy: a listener may destroy a stream during delivery.
      const std::vector<VirtualStream*> streams = streams_;
      for (VirtualStream* stream : streams) {
        if (std::find(streams_.begin(), streams_.end(), stream) == streams_.end()) continue;
        if (!stream->started()) continue;
        if (stream->type() == ONI_SENSOR_DEPTH) {
          stream->deliver(depth_mm.data(), static_cast<int>(depth_mm.size() * 2), width, height,
                          number, timestamp_us);
        } else if (!frame.color_rgb.empty()) {
          const cv::Mat rgb =
              frame.color_rgb.isContinuous() ? frame.color_rgb : frame.color_rgb.clone();
          stream->deliver(rgb.data, static_cast<int>(rgb.total() * rgb.elemSize()), rgb.cols,
                          rgb.rows, number, timestamp_us);
        }
      }
      ++emitted;
      if (uri_.unplug_after && static_cast<std::size_t>(emitted) >= *uri_.unplug_after) {
        finished_ = true;
        if (on_unplug) on_unplug();
      }
    }
  }

  VirtualSensorUri uri_;
  oni::driver::DriverServices& services_;
  std::recursive_mutex mutex_;
  std::condition_variable_any wake_;
  std::thread thread_;
  bool quit_ = false;
  bool finished_ = false;
  bool restart_clock_ = true;
  bool live_ = false;  ///< the source is a sensor (a Kinect): frames go out as they come
  std::vector<VirtualStream*> streams_;
  std::vector<OniVideoMode> modes_;
  std::vector<OniSensorInfo> sensors_;
  objscan::Intrinsics intrinsics_ = objscan::Intrinsics::xtionDefault();
  std::string description_;
  int frame_count_ = 0;
  double time_offset_s_ = 0.0;
  OniImageRegistrationMode registration_ = ONI_IMAGE_REGISTRATION_OFF;
  objscan::capture::FrameResult pending_;  ///< the first frame, read ahead at open
};

OniStatus VirtualStream::start() {
  {
    std::lock_guard<std::recursive_mutex> lock(device_.mutex());
    started_ = true;
  }
  device_.streamStartedOrStopped();
  return ONI_STATUS_OK;
}

void VirtualStream::stop() {
  {
    // Taking the lock waits for a delivery in progress on another thread.
    std::lock_guard<std::recursive_mutex> lock(device_.mutex());
    started_ = false;
  }
  device_.streamStartedOrStopped();
}

OniStatus VirtualStream::getProperty(int id, void* data, int* size) {
  const objscan::Intrinsics& in = device_.intrinsics();
  auto putFloat = [&](float value) {
    if (*size != static_cast<int>(sizeof(float))) return ONI_STATUS_BAD_PARAMETER;
    std::memcpy(data, &value, sizeof(float));
    return ONI_STATUS_OK;
  };
  auto putInt = [&](int value) {
    if (*size != static_cast<int>(sizeof(int))) return ONI_STATUS_BAD_PARAMETER;
    std::memcpy(data, &value, sizeof(int));
    return ONI_STATUS_OK;
  };
  switch (id) {
    case ONI_STREAM_PROPERTY_VIDEO_MODE: {
      if (*size != static_cast<int>(sizeof(OniVideoMode))) return ONI_STATUS_BAD_PARAMETER;
      const OniVideoMode mode = device_.videoMode(type_);
      std::memcpy(data, &mode, sizeof(mode));
      return ONI_STATUS_OK;
    }
    case ONI_STREAM_PROPERTY_CROPPING: {
      // The recorder stores a stream's frames as replayable only when it answers this property.
      if (*size != static_cast<int>(sizeof(OniCropping))) return ONI_STATUS_BAD_PARAMETER;
      const OniCropping cropping{0, 0, 0, in.width_px, in.height_px};
      std::memcpy(data, &cropping, sizeof(cropping));
      return ONI_STATUS_OK;
    }
    case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
      return putFloat(static_cast<float>(2.0 * std::atan(in.width_px / (2.0 * in.fx_px))));
    case ONI_STREAM_PROPERTY_VERTICAL_FOV:
      return putFloat(static_cast<float>(2.0 * std::atan(in.height_px / (2.0 * in.fy_px))));
    case ONI_STREAM_PROPERTY_MAX_VALUE:
      return putInt(type_ == ONI_SENSOR_DEPTH ? kMaxDepthMm : 255);
    case ONI_STREAM_PROPERTY_MIN_VALUE:
      return putInt(0);
    case ONI_STREAM_PROPERTY_STRIDE:
      return putInt(in.width_px * (type_ == ONI_SENSOR_DEPTH ? 2 : 3));
    case ONI_STREAM_PROPERTY_MIRRORING:
      return putInt(FALSE);
    default:
      return ONI_STATUS_NOT_SUPPORTED;
  }
}

OniStatus VirtualStream::setProperty(int id, const void* data, int size) {
  switch (id) {
    case ONI_STREAM_PROPERTY_VIDEO_MODE: {
      if (size != static_cast<int>(sizeof(OniVideoMode))) return ONI_STATUS_BAD_PARAMETER;
      OniVideoMode wanted;
      std::memcpy(&wanted, data, sizeof(wanted));
      const OniVideoMode mode = device_.videoMode(type_);
      return std::memcmp(&wanted, &mode, sizeof(mode)) == 0 ? ONI_STATUS_OK
                                                            : ONI_STATUS_NOT_SUPPORTED;
    }
    case ONI_STREAM_PROPERTY_MIRRORING: {
      if (size != static_cast<int>(sizeof(OniBool))) return ONI_STATUS_BAD_PARAMETER;
      OniBool mirror;
      std::memcpy(&mirror, data, sizeof(mirror));
      return mirror ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
    }
    case ONI_STREAM_PROPERTY_CROPPING: {
      if (size != static_cast<int>(sizeof(OniCropping))) return ONI_STATUS_BAD_PARAMETER;
      OniCropping cropping;
      std::memcpy(&cropping, data, sizeof(cropping));
      return cropping.enabled ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
    }
    default:
      return ONI_STATUS_NOT_SUPPORTED;
  }
}

OniBool VirtualStream::isPropertySupported(int id) {
  switch (id) {
    case ONI_STREAM_PROPERTY_VIDEO_MODE:
    case ONI_STREAM_PROPERTY_CROPPING:
    case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
    case ONI_STREAM_PROPERTY_VERTICAL_FOV:
    case ONI_STREAM_PROPERTY_MAX_VALUE:
    case ONI_STREAM_PROPERTY_MIN_VALUE:
    case ONI_STREAM_PROPERTY_STRIDE:
    case ONI_STREAM_PROPERTY_MIRRORING:
      return TRUE;
    default:
      return FALSE;
  }
}

void VirtualStream::deliver(const void* pixels, int bytes, int width, int height, int frame_index,
                            std::uint64_t timestamp_us) {
  OniFrame* frame = getServices().acquireFrame();
  if (frame == nullptr) return;
  if (frame->dataSize < bytes) {  // the buffer is sized from the video mode; never overrun it
    getServices().releaseFrame(frame);
    return;
  }
  std::memcpy(frame->data, pixels, static_cast<std::size_t>(bytes));
  frame->dataSize = bytes;
  frame->sensorType = type_;
  frame->timestamp = timestamp_us;
  frame->frameIndex = frame_index;
  frame->width = width;
  frame->height = height;
  frame->videoMode = device_.videoMode(type_);
  frame->croppingEnabled = FALSE;
  frame->cropOriginX = 0;
  frame->cropOriginY = 0;
  frame->stride = width * (type_ == ONI_SENSOR_DEPTH ? 2 : 3);
  raiseNewFrame(frame);
  getServices().releaseFrame(frame);
}

/// OpenNI2 keeps a device URI in 256 bytes and crashes on bytes outside printable ASCII (see
/// capture/src/openni_path.h): such a URI is never announced.
bool uriFitsOpenNI(const char* uri) {
  std::size_t n = 0;
  for (; uri[n] != '\0'; ++n) {
    const auto byte = static_cast<unsigned char>(uri[n]);
    if (byte < 0x20 || byte > 0x7e || n >= ONI_MAX_STR - 1) return false;
  }
  return true;
}

class VirtualDriver : public oni::driver::DriverBase {
 public:
  explicit VirtualDriver(OniDriverServices* services) : DriverBase(services) {}

  OniStatus initialize(oni::driver::DeviceConnectedCallback connected,
                       oni::driver::DeviceDisconnectedCallback disconnected,
                       oni::driver::DeviceStateChangedCallback state_changed,
                       void* cookie) override {
    const OniStatus status = DriverBase::initialize(connected, disconnected, state_changed, cookie);
    if (status != ONI_STATUS_OK) return status;
    if (const char* uri = std::getenv(objscan::capture::kVirtualSensorEnv);
        uri != nullptr && objscan::capture::isVirtualSensorUri(uri)) {
      if (uriFitsOpenNI(uri)) {
        announce(uri);
      } else {
        getServices().errorLoggerAppend(
            "%s is not announced: OpenNI2 takes only printable ASCII URIs under 256 bytes",
            objscan::capture::kVirtualSensorEnv);
      }
    }
    return ONI_STATUS_OK;
  }

  OniStatus tryDevice(const char* uri) override {
    if (uri == nullptr || !objscan::capture::isVirtualSensorUri(uri) || !uriFitsOpenNI(uri)) {
      return ONI_STATUS_ERROR;
    }
    try {
      objscan::capture::parseVirtualSensorUri(uri);
    } catch (const std::exception& e) {
      getServices().errorLoggerAppend("%s", e.what());
      return ONI_STATUS_ERROR;
    }
    announce(uri);
    return ONI_STATUS_OK;
  }

  oni::driver::DeviceBase* deviceOpen(const char* uri, const char* /*mode*/) override {
    VirtualSensorUri parsed;
    try {
      parsed = objscan::capture::parseVirtualSensorUri(uri);
    } catch (const std::exception& e) {
      getServices().errorLoggerAppend("%s", e.what());
      return nullptr;
    }
    const OniDeviceInfo info = makeInfo(uri);
    auto device = std::make_unique<VirtualDevice>(parsed, getServices());
    device->on_unplug = [this, info] { deviceDisconnected(&info); };
    const std::string error = device->open();
    if (!error.empty()) {
      getServices().errorLoggerAppend("%s", error.c_str());
      return nullptr;
    }
    return device.release();
  }

  void deviceClose(oni::driver::DeviceBase* device) override { delete device; }

  // Frame sync: the producer raises each depth frame and its colour frame back to back with the
  // same frame number and time stamp, so the streams are in sync already; OpenNI2 only needs a
  // handle for the group.
  void* enableFrameSync(oni::driver::StreamBase** streams, int count) override {
    return streams != nullptr && count > 0 ? static_cast<void*>(this) : nullptr;
  }
  void disableFrameSync(void*) override {}

  void shutdown() override {}

 private:
  static OniDeviceInfo makeInfo(const std::string& uri) {
    OniDeviceInfo info{};
    copyString(info.uri, sizeof(info.uri), uri);
    const bool kinect = objscan::capture::isFreenectSource(
        uri.substr(std::string_view(objscan::capture::kVirtualUriPrefix).size()));
    copyString(info.vendor, sizeof(info.vendor), kinect ? "Microsoft" : "objscan");
    copyString(info.name, sizeof(info.name),
               kinect ? "Kinect v1 (libfreenect, through the virtual sensor)" : "virtual sensor");
    return info;
  }

  void announce(const std::string& uri) {
    const OniDeviceInfo info = makeInfo(uri);
    deviceConnected(&info);
  }
};

}  // namespace

ONI_EXPORT_DRIVER(VirtualDriver)
