#include "objscan/pipeline/sources.h"

#include <filesystem>

#include "objscan/capture/openni.h"
#include "objscan/capture/synthetic/synthetic_source.h"
#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/error.h"

namespace objscan::pipeline {

bool isLiveSource(const std::string& spec) {
  return spec == "live" || spec.rfind("live:", 0) == 0 || capture::isVirtualSensorUri(spec);
}

std::unique_ptr<capture::FrameSource> openFrameSource(const std::string& spec,
                                                      const SourceOptions& options) {
  namespace fs = std::filesystem;
  const fs::path path(spec);
  std::error_code ec;
  const bool live = spec == "live" || spec.rfind("live:", 0) == 0;
  if (options.record && !isLiveSource(spec)) {
    throw InputError(spec, "--record needs a live source (a sensor or virtual:...)");
  }
  // The sensor names come before the file system: `live` is the sensor even where the working
  // directory holds a folder of that name (./live names the folder).
  if (isLiveSource(spec)) {
    if (!options.selection.selectsAll()) {
      throw std::invalid_argument("--start/--end/--every apply to recordings, not live sensors");
    }
    const std::string uri = spec == "live" ? std::string() : live ? spec.substr(5) : spec;
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

std::optional<Trajectory> virtualSensorGroundTruth(const std::string& uri) {
  const capture::VirtualSensorUri parsed = capture::parseVirtualSensorUri(uri);
  std::optional<Trajectory> ground_truth = openFrameSource(parsed.source, {})->info().ground_truth;
  if (ground_truth && ground_truth->empty()) ground_truth.reset();
  return ground_truth;
}

}  // namespace objscan::pipeline
