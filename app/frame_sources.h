#pragma once

#include <memory>
#include <optional>
#include <string>

#include "objscan/capture/frame_source.h"
#include "objscan/core/intrinsics.h"

namespace objscan::app {

struct SourceOptions {
  capture::FrameSelection selection;
  std::optional<Intrinsics> intrinsics;  ///< --intrinsics: replaces what the source says
  std::string intrinsics_origin;
};

/// Opens a <source> as the command line names it:
///   X.oni                          an OpenNI2 recording (replayed through OpenNI2)
///   a folder                       TUM RGB-D or 7-Scenes layout (a folder objscan synth wrote too)
///   synth:<seed>[,option=value]    a synthetic scene rendered on the fly
///   live | live:<uri>              the first OpenNI2 sensor, or the one with that URI
///   virtual:<source>[?options]     objscan's virtual OpenNI2 sensor streaming <source>
/// Throws InputError / std::invalid_argument for sources that cannot be opened.
std::unique_ptr<capture::FrameSource> openFrameSource(const std::string& spec,
                                                      const SourceOptions& options);

}  // namespace objscan::app
