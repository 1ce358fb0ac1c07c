#include "objscan/pipeline/frame_scene.h"

#include <memory>
#include <optional>
#include <stdexcept>
#include <utility>

#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/discovery/catalog.h"

namespace objscan::pipeline {

namespace {

/// The bytes a frame's scene is made of (depth, colour, camera), for the catalog's content hash.
std::string frameBytes(const RgbdFrame& frame) {
  std::string bytes;
  for (const cv::Mat* image : {&frame.depth_m, &frame.color_rgb}) {
    const std::size_t row = image->cols * image->elemSize();
    for (int v = 0; v < image->rows; ++v) bytes.append(image->ptr<char>(v), row);
  }
  const Intrinsics& k = frame.intrinsics;
  for (const double x : {k.fx_px, k.fy_px, k.cx_px, k.cy_px}) {
    bytes.append(reinterpret_cast<const char*>(&x), sizeof x);
  }
  return bytes;
}

/// How many frames `source` has, for the message of an index past its end (nothing: unknown).
std::optional<std::size_t> framesOf(const std::string& source, const SourceOptions& options) {
  SourceOptions all = options;
  all.selection = {};
  return openFrameSource(source, all)->info().frame_count;
}

[[noreturn]] void throwPastEnd(const std::string& name, std::size_t index,
                               std::optional<std::size_t> frames) {
  std::string problem = "--frame " + std::to_string(index) + " is past its end";
  if (frames) problem += " (it has " + std::to_string(*frames) + " frames, numbered from 0)";
  throw InputError(name, problem);
}

/// An indexed source (not a sensor) opened at frame `index` alone; `name` is how errors call it.
std::unique_ptr<capture::FrameSource> openAtFrame(const std::string& source,
                                                  const std::string& name, std::size_t index,
                                                  const SourceOptions& options) {
  SourceOptions one = options;
  one.selection = {};
  one.selection.start = index;
  one.selection.end = index + 1;
  std::unique_ptr<capture::FrameSource> opened;
  try {
    opened = openFrameSource(source, one);
  } catch (const std::invalid_argument&) {
    // A folder or synthetic source refuses a start past its end (in --start's words); anything
    // else it refuses, it refuses again without the selection, and that error is the one to see.
    const std::optional<std::size_t> frames = framesOf(source, options);
    if (frames && index >= *frames) throwPastEnd(name, index, frames);
    throw;
  }
  if (opened->info().frame_count == std::optional<std::size_t>(0)) {
    opened.reset();  // OpenNI2 replays a file once at a time
    throwPastEnd(name, index, framesOf(source, options));
  }
  return opened;
}

}  // namespace

discovery::SceneInput sceneOfFrame(const std::string& source, std::size_t index,
                                   const SourceOptions& options, const OrganizedMeshConfig& meshing,
                                   bool hash) {
  const bool sensor = isLiveSource(source) && !capture::isVirtualSensorUri(source);
  // A virtual sensor streams a recording, a folder or a synthetic scene: read that directly.
  const std::string indexed =
      capture::isVirtualSensorUri(source) ? capture::parseVirtualSensorUri(source).source : source;
  std::unique_ptr<capture::FrameSource> frames;
  if (sensor) {
    SourceOptions all = options;
    all.selection = {};
    frames = openFrameSource(source, all);
  } else {
    frames = openAtFrame(indexed, source, index, options);
  }
  if (frames->info().intrinsics_assumed) {
    log::warning("the camera intrinsics of " + source +
                 " are ASSUMED: " + frames->info().intrinsics_origin +
                 "; a different camera makes the scene the wrong size and shape. Add the "
                 "recording's calibration or pass --intrinsics FILE");
  }
  const std::size_t skip = sensor ? index : 0;
  for (std::size_t i = 0;; ++i) {
    capture::FrameResult result = frames->next();
    if (result.status == capture::FrameStatus::kEndOfStream) {
      if (sensor) {
        throw InputError(source, "the sensor's stream ended before frame " + std::to_string(index));
      }
      frames.reset();
      throwPastEnd(source, index, framesOf(indexed, options));
    }
    if (i < skip) continue;
    if (result.status == capture::FrameStatus::kBadFrame) {
      throw InputError(source,
                       "frame " + std::to_string(index) + " cannot be read: " + result.reason);
    }
    OrganizedCloud cloud;
    try {
      cloud = cloudOfFrame(result.frame);
    } catch (const std::invalid_argument& e) {
      throw InputError(source, "frame " + std::to_string(index) + ": " + e.what());
    }
    discovery::SceneInput scene =
        discovery::sceneFromCloud(source + "@frame" + std::to_string(index), cloud, false, meshing);
    if (hash) scene.content_hash = discovery::contentHashOfBytes(frameBytes(result.frame));
    return scene;
  }
}

discovery::SceneInput readScene(const std::filesystem::path& argument,
                                const discovery::SceneReading& reading,
                                std::optional<std::size_t> frame) {
  if (!frame) return discovery::loadScene(argument, reading);
  SourceOptions source;
  source.intrinsics = reading.intrinsics;
  source.intrinsics_origin = reading.intrinsics_origin;
  discovery::SceneInput scene =
      sceneOfFrame(argument.string(), *frame, source, reading.meshing, reading.hash);
  if (reading.view_up) scene.view_up = reading.view_up;
  return scene;
}

}  // namespace objscan::pipeline
