// OpenNI2 on the application side: starting the runtime, opening devices and streams, and the
// pieces replay, live capture and recording share.

#include "openni_runtime.h"

#include <OpenNI.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>

#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"

namespace objscan::capture::openni_detail {
namespace {

/// Remembers devices OpenNI2 reported as disconnected, so a stalled stream can say why.
class DisconnectWatcher : public openni::OpenNI::DeviceDisconnectedListener {
 public:
  void onDeviceDisconnected(const openni::DeviceInfo* info) override {
    std::lock_guard<std::mutex> lock(mutex_);
    uris_.insert(info->getUri());
  }
  bool disconnected(const std::string& uri) {
    std::lock_guard<std::mutex> lock(mutex_);
    return uris_.count(uri) != 0;
  }
  void forget(const std::string& uri) {
    std::lock_guard<std::mutex> lock(mutex_);
    uris_.erase(uri);
  }

 private:
  std::mutex mutex_;
  std::set<std::string> uris_;
};

DisconnectWatcher& watcher() {
  static DisconnectWatcher instance;
  return instance;
}

}  // namespace

std::string lastError() {
  std::string text = openni::OpenNI::getExtendedError();
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text.empty() ? std::string("no details from OpenNI2") : text;
}

void ensureOpenNI() {
  static std::mutex mutex;
  static bool started = false;
  std::lock_guard<std::mutex> lock(mutex);
  if (started) return;
  // OpenNI2 stays up until the process ends: shutting it down unloads drivers whose threads may
  // still be finishing.
  if (openni::OpenNI::initialize() != openni::STATUS_OK) {
    std::string message = "OpenNI2 failed to start: ";
    message.append(lastError());
    throw std::runtime_error(message);
  }
  openni::OpenNI::addDeviceDisconnectedListener(&watcher());
  started = true;
  if (const char* uri = std::getenv(kVirtualSensorEnv); uri != nullptr && !openNICanTake(uri)) {
    // The virtual driver does not announce it (OpenNI2 would crash on it): say so here, where
    // it can be seen.
    log::warning(std::string(kVirtualSensorEnv) +
                 " is ignored: OpenNI2 takes only printable ASCII URIs of at most 200 bytes; give "
                 "the sensor with --device virtual:<path> instead, which objscan aliases");
  }
}

bool wasDisconnected(const std::string& uri) { return watcher().disconnected(uri); }

void forgetDisconnect(const std::string& uri) { watcher().forget(uri); }

std::vector<SensorDescription> listSensorsInternal() {
  ensureOpenNI();
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  std::vector<SensorDescription> result;
  for (int i = 0; i < devices.getSize(); ++i) {
    const openni::DeviceInfo& d = devices[i];
    result.push_back(
        {d.getUri(), d.getVendor(), d.getName(), d.getUsbVendorId(), d.getUsbProductId()});
  }
  return result;
}

void openDevice(openni::Device& device, const std::string& given_uri, OpenNIPath* alias) {
  ensureOpenNI();
  const std::string uri = given_uri.empty() ? given_uri : openNIUri(given_uri, alias);
  if (uri.empty()) {
    if (listSensorsInternal().empty()) {
      throw NoSensorError(
          "no sensor found: connect an OpenNI2 sensor (Asus Xtion, PrimeSense Carmine) or name "
          "one by its URI (objscan devices lists them; virtual:<folder> needs none); a Kinect v1 "
          "is the source freenect");
    }
    if (device.open(openni::ANY_DEVICE) != openni::STATUS_OK) {
      std::string message = "cannot open the first sensor: ";
      message.append(lastError());
      throw std::runtime_error(message);
    }
    return;
  }
  if (device.open(uri.c_str()) != openni::STATUS_OK) {
    throw InputError(given_uri, "cannot open this sensor: " + lastError());
  }
  forgetDisconnect(uri);
}

namespace {

bool pickMode(openni::VideoStream& stream, openni::PixelFormat wanted_format) {
  const openni::SensorInfo& info = stream.getSensorInfo();
  const openni::Array<openni::VideoMode>& modes = info.getSupportedVideoModes();
  int best = -1;
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& m = modes[i];
    if (m.getPixelFormat() != wanted_format) continue;
    if (m.getResolutionX() == 640 && m.getResolutionY() == 480 && m.getFps() == 30) {
      best = i;
      break;
    }
    if (best < 0) best = i;
  }
  if (best < 0) return false;
  return stream.setVideoMode(modes[best]) == openni::STATUS_OK;
}

}  // namespace

void createLiveStreams(openni::Device& device, openni::VideoStream& depth,
                       openni::VideoStream& color, bool* has_color) {
  if (!device.hasSensor(openni::SENSOR_DEPTH) ||
      depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
    std::string message = "the sensor has no depth stream: ";
    message.append(lastError());
    throw std::runtime_error(message);
  }
  if (!pickMode(depth, openni::PIXEL_FORMAT_DEPTH_1_MM)) {
    pickMode(depth, openni::PIXEL_FORMAT_DEPTH_100_UM);
  }
  depth.setMirroringEnabled(false);
  *has_color = device.hasSensor(openni::SENSOR_COLOR) &&
               color.create(device, openni::SENSOR_COLOR) == openni::STATUS_OK;
  if (*has_color) {
    pickMode(color, openni::PIXEL_FORMAT_RGB888);
    color.setMirroringEnabled(false);
    if (device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
      device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
    }
    device.setDepthColorSyncEnabled(true);
  }
}

Intrinsics intrinsicsFromStream(openni::VideoStream& depth, std::string* origin) {
  const openni::VideoMode mode = depth.getVideoMode();
  const float hfov = depth.getHorizontalFieldOfView();
  const float vfov = depth.getVerticalFieldOfView();
  const int w = mode.getResolutionX();
  const int h = mode.getResolutionY();
  if (w > 0 && h > 0 && std::isfinite(hfov) && std::isfinite(vfov) && hfov > 0.1f && hfov < 3.0f &&
      vfov > 0.1f && vfov < 3.0f) {
    Intrinsics in;
    in.width_px = w;
    in.height_px = h;
    in.fx_px = w / (2.0 * std::tan(hfov / 2.0));
    in.fy_px = h / (2.0 * std::tan(vfov / 2.0));
    in.cx_px = (w - 1) / 2.0;
    in.cy_px = (h - 1) / 2.0;
    *origin = "the sensor's field of view";
    return in;
  }
  *origin = "Xtion defaults (the sensor reports no field of view)";
  Intrinsics in = Intrinsics::xtionDefault();
  if (w > 0 && h > 0 && (w != in.width_px || h != in.height_px)) {
    const double s = static_cast<double>(w) / in.width_px;
    in.fx_px *= s;
    in.fy_px *= s;
    in.cx_px = (w - 1) / 2.0;
    in.cy_px = (h - 1) / 2.0;
    in.width_px = w;
    in.height_px = h;
  }
  return in;
}

void requireIntrinsicsFit(openni::VideoStream& depth, const SourceInfo& info,
                          const std::string& subject) {
  const openni::VideoMode mode = depth.getVideoMode();
  const Intrinsics& in = info.intrinsics;
  if (mode.getResolutionX() == in.width_px && mode.getResolutionY() == in.height_px) return;
  throw InputError(subject, "depth images are " + std::to_string(mode.getResolutionX()) + "x" +
                                std::to_string(mode.getResolutionY()) + " but the intrinsics (" +
                                info.intrinsics_origin + ") are for " +
                                std::to_string(in.width_px) + "x" + std::to_string(in.height_px));
}

std::optional<VirtualDeviceFacts> virtualDeviceFacts(openni::Device& device) {
  if (!device.isPropertySupported(virtual_property::kIntrinsics)) return std::nullopt;
  VirtualDeviceFacts facts;
  double values[6] = {};
  int frames = 0;
  char description[256] = {};
  if (device.getProperty(virtual_property::kIntrinsics, &values) != openni::STATUS_OK ||
      device.getProperty(virtual_property::kFrameCount, &frames) != openni::STATUS_OK ||
      device.getProperty(virtual_property::kTimeOffset, &facts.time_offset_s) !=
          openni::STATUS_OK ||
      device.getProperty(virtual_property::kDescription, &description) != openni::STATUS_OK) {
    return std::nullopt;
  }
  facts.intrinsics.fx_px = values[0];
  facts.intrinsics.fy_px = values[1];
  facts.intrinsics.cx_px = values[2];
  facts.intrinsics.cy_px = values[3];
  facts.intrinsics.width_px = static_cast<int>(values[4]);
  facts.intrinsics.height_px = static_cast<int>(values[5]);
  facts.frame_count = static_cast<std::size_t>(std::max(frames, 0));
  facts.description = description;
  return facts;
}

LiveSensorFacts liveSensorFacts(openni::Device& device, openni::VideoStream& depth) {
  LiveSensorFacts live;
  if (const auto facts = virtualDeviceFacts(device)) {
    live.intrinsics = facts->intrinsics;
    live.intrinsics_origin = "the virtual sensor's source";
    live.time_offset_s = facts->time_offset_s;
    live.frame_count = facts->frame_count;
  } else {
    live.intrinsics = intrinsicsFromStream(depth, &live.intrinsics_origin);
  }
  return live;
}

cv::Mat depthToMetres(const openni::VideoFrameRef& frame) {
  const cv::Mat raw(frame.getHeight(), frame.getWidth(), CV_16UC1,
                    const_cast<void*>(frame.getData()),
                    static_cast<std::size_t>(frame.getStrideInBytes()));
  const float units_per_metre =
      frame.getVideoMode().getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM ? 10000.0f
                                                                                 : 1000.0f;
  // Division, as the folder readers do: the float nearest mm / 1000, so that a replayed frame is
  // bit-identical to the dataset frame it was recorded from (convertTo multiplies by a float
  // 0.001, which is one unit in the last place off for most values).
  cv::Mat metres(raw.size(), CV_32FC1);
  for (int v = 0; v < raw.rows; ++v) {
    const std::uint16_t* in = raw.ptr<std::uint16_t>(v);
    float* out = metres.ptr<float>(v);
    for (int u = 0; u < raw.cols; ++u) out[u] = static_cast<float>(in[u]) / units_per_metre;
  }
  return metres;
}

cv::Mat colorToRgb(const openni::VideoFrameRef& frame) {
  if (frame.getVideoMode().getPixelFormat() != openni::PIXEL_FORMAT_RGB888) return {};
  const cv::Mat raw(frame.getHeight(), frame.getWidth(), CV_8UC3,
                    const_cast<void*>(frame.getData()),
                    static_cast<std::size_t>(frame.getStrideInBytes()));
  return raw.clone();
}

}  // namespace objscan::capture::openni_detail

namespace objscan::capture {

std::vector<SensorDescription> listSensors() { return openni_detail::listSensorsInternal(); }

RecordingSidecars RecordingSidecars::of(const std::filesystem::path& oni) {
  RecordingSidecars s;
  s.info = oni;
  s.info += ".json";
  s.ground_truth = oni;
  s.ground_truth += ".groundtruth.txt";
  return s;
}

}  // namespace objscan::capture
