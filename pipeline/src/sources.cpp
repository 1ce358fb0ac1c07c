#include "objscan/pipeline/sources.h"

#include <filesystem>

#include "objscan/capture/freenect.h"
#include "objscan/capture/openni.h"
#include "objscan/capture/synthetic/synthetic_source.h"
#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/error.h"

namespace objscan::pipeline {

bool isLiveSource(const std::string& spec) {
  return spec == "live" || spec.rfind("live:", 0) == 0 || capture::isVirtualSensorUri(spec) ||
         capture::isFreenectSource(spec);
}

std::unique_ptr<capture::FrameSource> openFrameSource(const std::string& spec,
                                                      const SourceOptions& options) {
  namespace fs = std::filesystem;
  const fs::path path(spec);
  std::error_code ec;
  const bool live = spec == "live" || spec.rfind("live:", 0) == 0;
  if (options.record && !isLiveSource(spec)) {
    throw InputError(spec, "--record needs a live source (a sensor, freenect or virtual:...)");
  }
  // The sensor names come before the file system: `live` is the sensor even where the working
  // directory holds a folder of that name (./live names the folder).
  if (isLiveSource(spec)) {
    if (!options.selection.selectsAll()) {
      throw std::invalid_argument("--start/--end/--every apply to recordings, not live sensors");
    }
    const bool kinect = capture::isFreenectSource(spec);
    if (kinect && !options.record) {
      return capture::openFreenect(spec, options.intrinsics, options.intrinsics_origin);
    }
    // A Kinect is recorded through OpenNI2's own recorder: objscan's virtual OpenNI2 sensor
    // streams it, so the file is an .oni like an Xtion's.
    const std::string uri = kinect           ? freenectThroughOpenNI(spec)
                            : spec == "live" ? std::string()
                            : live           ? spec.substr(5)
                                             : spec;
    std::optional<capture::LiveRecording> record = options.record;
    if (record && !record->ground_truth && capture::isVirtualSensorUri(uri)) {
      record->ground_truth = virtualSensorGroundTruth(uri);
    }
    return capture::openSensor(uri, options.intrinsics, options.intrinsics_origin, record);
  }
  if (spec.rfind("synth:", 0) == 0 || fs::is_directory(path, ec)) {
    return capture::openSynthOrFolderSource(spec, options.selection, options.intrinsics,
                                            options.intrinsics_origin);
  }
  if (path.extension() == ".oni" || path.extension() == ".ONI") {
    return capture::openOniFile(path, options.selection, options.intrinsics,
                                options.intrinsics_origin);
  }
  if (!fs::exists(path, ec)) throw InputError(path, "no such file or folder");
  throw InputError(path,
                   "is not a source objscan reads: use an .oni recording, a TUM or 7-Scenes "
                   "folder, synth:<seed>, live or virtual:<folder>");
}

std::string freenectThroughOpenNI(const std::string& spec) {
  // The driver can only say that it could not open the device; errors keep their classes (and
  // exit codes) when they are found here first.
  capture::checkFreenect(spec);
  return capture::kVirtualUriPrefix + spec;
}

std::optional<Trajectory> virtualSensorGroundTruth(const std::string& uri) {
  const capture::VirtualSensorUri parsed = capture::parseVirtualSensorUri(uri);
  // A Kinect is opened once, by the sensor (fakenect replays a dump once per process).
  if (capture::isFreenectSource(parsed.source)) return capture::freenectGroundTruth();
  std::optional<Trajectory> ground_truth = openFrameSource(parsed.source, {})->info().ground_truth;
  if (ground_truth && ground_truth->empty()) ground_truth.reset();
  return ground_truth;
}

}  // namespace objscan::pipeline
