#pragma once

#include <memory>
#include <optional>
#include <string>

#include "objscan/capture/frame_source.h"
#include "objscan/capture/openni.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/trajectory.h"

namespace objscan::pipeline {

struct SourceOptions {
  capture::FrameSelection selection;
  std::optional<Intrinsics> intrinsics;  ///< --intrinsics: replaces what the source says
  std::string intrinsics_origin;
  /// --record: record a live source's raw streams to .oni while it is read. The source is then a
  /// capture::RecordingFrameSource; capture::finishRecording() closes the file. A virtual sensor's
  /// ground truth (when its source has one and none is set) goes to X.oni.groundtruth.txt.
  std::optional<capture::LiveRecording> record;
};

/// Whether a <source> is a sensor: `live`, `live:<uri>`, a virtual sensor (`virtual:...`) or a
/// Kinect through libfreenect (`freenect[:<index>]`).
bool isLiveSource(const std::string& spec);

/// Opens a <source> as the command line names it:
///   X.oni                          an OpenNI2 recording (replayed through OpenNI2)
///   a folder                       TUM RGB-D or 7-Scenes layout (a folder objscan synth wrote too)
///   synth:<seed>[,option=value]    a synthetic scene rendered on the fly
///   live | live:<uri>              the first OpenNI2 sensor, or the one with that URI
///   virtual:<source>[?options]     objscan's virtual OpenNI2 sensor streaming <source>
///   freenect | freenect:<index>    a Kinect v1 through libfreenect (or a dump through fakenect);
///                                  with --record, read through the virtual OpenNI2 sensor so
///                                  that OpenNI2's recorder writes the .oni
/// The sensor forms are matched first, as text: a folder named `live` is ./live.
/// Throws InputError / std::invalid_argument for sources that cannot be opened (and for --record
/// with a source that is not live), NoSensorError for `live` with no sensor attached.
std::unique_ptr<capture::FrameSource> openFrameSource(const std::string& spec,
                                                      const SourceOptions& options);

/// The virtual OpenNI2 sensor's URI that streams the Kinect `spec` (freenect[:<index>]), once
/// capture::checkFreenect(spec) found nothing wrong (it throws as opening the Kinect would).
std::string freenectThroughOpenNI(const std::string& spec);

/// The ground truth of the source a virtual sensor URI streams (virtual:<folder> or
/// virtual:synth:<seed>), if it has one. Opening the source also reports a bad folder early.
/// Throws as openFrameSource does for that source, std::invalid_argument for a bad URI.
std::optional<Trajectory> virtualSensorGroundTruth(const std::string& uri);

}  // namespace objscan::pipeline
