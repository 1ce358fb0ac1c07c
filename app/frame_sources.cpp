#include "frame_sources.h"

#include <filesystem>

#include "objscan/capture/openni.h"
#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/error.h"
#include "objscan/render/synthetic_source.h"

namespace objscan::app {

std::unique_ptr<capture::FrameSource> openFrameSource(const std::string& spec,
                                                      const SourceOptions& options) {
  namespace fs = std::filesystem;
  const fs::path path(spec);
  std::error_code ec;
  if (spec.rfind("synth:", 0) == 0 || fs::is_directory(path, ec)) {
    return render::openSynthOrFolderSource(spec, options.selection, options.intrinsics,
                                           options.intrinsics_origin);
  }
  const bool live = spec == "live" || spec.rfind("live:", 0) == 0;
  if (live || capture::isVirtualSensorUri(spec)) {
    if (!options.selection.selectsAll()) {
      throw std::invalid_argument("--start/--end/--every apply to recordings, not live sensors");
    }
    const std::string uri = spec == "live" ? std::string() : live ? spec.substr(5) : spec;
    return capture::openSensor(uri, options.intrinsics, options.intrinsics_origin);
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

}  // namespace objscan::app
