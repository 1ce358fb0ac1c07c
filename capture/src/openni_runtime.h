#pragma once

// Internal to capture/: OpenNI2 helpers shared by replay, live capture and recording.

#include <OpenNI.h>

#include <functional>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "objscan/capture/openni.h"
#include "objscan/core/intrinsics.h"
#include "openni_path.h"

namespace objscan::capture::openni_detail {

/// Starts OpenNI2 once per process. Throws std::runtime_error.
void ensureOpenNI();
/// OpenNI2's last error message on one line.
std::string lastError();

std::vector<SensorDescription> listSensorsInternal();

/// Opens `uri` (empty: the first sensor), through an alias kept in `*alias` where OpenNI2 cannot
/// take the path a virtual sensor's URI names (openni_path.h); `*alias` must outlive the device.
/// Throws NoSensorError when no sensor is attached, InputError when `uri` cannot be opened,
/// std::runtime_error when the first sensor cannot.
void openDevice(openni::Device& device, const std::string& uri, OpenNIPath* alias);

/// Creates depth (required) and colour (when the device has it) streams at 640x480@30 where
/// offered, mirroring off, registration and frame sync on. Throws std::runtime_error.
void createLiveStreams(openni::Device& device, openni::VideoStream& depth,
                       openni::VideoStream& color, bool* has_color);

/// Pinhole intrinsics from the depth stream's field of view and resolution (principal point at
/// the image centre); the Xtion defaults when the stream reports no usable field of view.
Intrinsics intrinsicsFromStream(openni::VideoStream& depth, std::string* origin);

/// Throws InputError(subject, "depth images are WxH but the intrinsics (<origin>) are for WxH")
/// when the depth stream's resolution differs from `info.intrinsics`.
void requireIntrinsicsFit(openni::VideoStream& depth, const SourceInfo& info,
                          const std::string& subject);

/// What objscan's virtual sensor says about itself; nullopt for any other device.
struct VirtualDeviceFacts {
  Intrinsics intrinsics;
  std::size_t frame_count = 0;
  double time_offset_s = 0.0;
  std::string description;
};
std::optional<VirtualDeviceFacts> virtualDeviceFacts(openni::Device& device);

/// What an opened live sensor says about its depth images: the virtual sensor's own facts, else
/// intrinsicsFromStream().
struct LiveSensorFacts {
  Intrinsics intrinsics;
  std::string intrinsics_origin;
  double time_offset_s = 0.0;              ///< adds back to OpenNI2's stamps: the source's clock
  std::optional<std::size_t> frame_count;  ///< frames a virtual sensor's source holds
};
LiveSensorFacts liveSensorFacts(openni::Device& device, openni::VideoStream& depth);

/// OpenNI2 reported this device as disconnected since it was opened.
bool wasDisconnected(const std::string& uri);
void forgetDisconnect(const std::string& uri);

/// Calls `on_frame` with each new frame of one stream, on the thread that delivers it. OpenNI2's
/// C++ listener passes a temporary VideoStream and keeps one callback handle per listener, so a
/// listener serves exactly one stream and tells streams apart by the frame's sensor type.
class FrameListener : public openni::VideoStream::NewFrameListener {
 public:
  explicit FrameListener(std::function<void(const openni::VideoFrameRef&)> on_frame)
      : on_frame_(std::move(on_frame)) {}
  void onNewFrame(openni::VideoStream& stream) override {
    // readFrame blocks until a frame is there. OpenNI2 may raise a callback whose frame an
    // earlier call already took (callbacks queue, a read takes the newest); at the end of the
    // stream that read would wait forever, and removing the listener waits for the callback: a
    // hang at close. So read only what is ready now.
    openni::VideoStream* streams[1] = {&stream};
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, 0) != openni::STATUS_OK) return;
    openni::VideoFrameRef ref;
    if (stream.readFrame(&ref) == openni::STATUS_OK) on_frame_(ref);
  }

 private:
  std::function<void(const openni::VideoFrameRef&)> on_frame_;
};

/// CV_32FC1 metres from a DEPTH_1_MM or DEPTH_100_UM frame.
cv::Mat depthToMetres(const openni::VideoFrameRef& frame);
/// CV_8UC3 RGB copy of an RGB888 frame; empty for other formats.
cv::Mat colorToRgb(const openni::VideoFrameRef& frame);

}  // namespace objscan::capture::openni_detail
