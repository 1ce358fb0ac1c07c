#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace objscan::capture {

/// objscan's virtual OpenNI2 sensor: an OpenNI2 driver (libObjscanVirtualSensor.so.0, built with
/// the project and loaded by the real OpenNI2 runtime like any sensor driver) that streams a
/// dataset folder or a synthetic scene as a 640x480 (or the source's size) depth + colour sensor.
///
/// Device URIs:  virtual:<folder>[?option&...]   virtual:synth:<seed>[,...][?option&...]
/// Options:
///   fps=F            frames per second delivered, 1-1000 (default 30, as a real sensor)
///   unplug_after=N   deliver N frames, then behave like an unplugged sensor (no more frames and
///                    a disconnect event); for testing how capture copes with a lost sensor
///   streams=S        "depth,color" (default), "depth" or "color"
/// The driver announces no device by itself: OpenNI2 offers it a "virtual:" URI when a program
/// opens one. With the environment variable OBJSCAN_VIRTUAL_SENSOR=<uri> set, it also announces
/// that device at start-up, so it is listed and found as "the first sensor".
struct VirtualSensorUri {
  std::string source;  ///< the folder or synth:<seed>... spec
  double fps = 30.0;
  std::optional<std::size_t> unplug_after;
  bool depth = true;
  bool color = true;
};

inline constexpr char kVirtualUriPrefix[] = "virtual:";
inline constexpr char kVirtualSensorEnv[] = "OBJSCAN_VIRTUAL_SENSOR";

/// True when `uri` starts with "virtual:".
bool isVirtualSensorUri(const std::string& uri);
/// Throws std::invalid_argument with a one-line message naming the bad part.
VirtualSensorUri parseVirtualSensorUri(const std::string& uri);

/// Device properties the virtual sensor answers beyond OpenNI2's own (ids in the range OpenNI2
/// leaves to vendors). Real sensors answer none of them.
namespace virtual_property {
/// double[6]: fx, fy, cx, cy (pixels), width, height of the depth images.
inline constexpr int kIntrinsics = 0x0B7C0001;
/// int: frames the source holds (unplug_after is not counted), so recording can stop at the end.
inline constexpr int kFrameCount = 0x0B7C0002;
/// double: the source's time stamp of its first frame, in seconds; OpenNI2 time stamps count
/// microseconds from it, so adding it back restores the dataset's own clock.
inline constexpr int kTimeOffset = 0x0B7C0003;
/// char[256]: the source, in words.
inline constexpr int kDescription = 0x0B7C0004;
}  // namespace virtual_property

}  // namespace objscan::capture
