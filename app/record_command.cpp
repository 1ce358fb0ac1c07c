#include "record_command.h"

#include <cstdio>
#include <memory>
#include <string>

#include "exit_codes.h"
#include "objscan/capture/freenect.h"
#include "objscan/capture/openni.h"
#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/log.h"
#include "objscan/core/trajectory.h"
#include "objscan/pipeline/sources.h"
#include "stop_signals.h"

namespace objscan::app {

void runDevices() {
  const std::vector<capture::SensorDescription> sensors = capture::listSensors();
  std::string why_no_kinect;
  const std::vector<capture::FreenectDevice> kinects = capture::listFreenectDevices(&why_no_kinect);
  if (sensors.empty() && kinects.empty()) {
    std::printf(
        "no sensor found (connect an Asus Xtion, PrimeSense Carmine or Kinect v1, which is "
        "freenect; objscan's virtual sensor opens with --device virtual:<folder> or "
        "virtual:synth:<seed>)\n");
    if (!why_no_kinect.empty()) log::info("Kinect v1: " + why_no_kinect);
    return;
  }
  for (const capture::SensorDescription& s : sensors) {
    std::printf("%s\t%s %s\tUSB %04x:%04x\tthrough OpenNI2\n", s.uri.c_str(), s.vendor.c_str(),
                s.name.c_str(), s.usb_vendor_id, s.usb_product_id);
  }
  for (const capture::FreenectDevice& k : kinects) {
    std::printf("%s\tMicrosoft Kinect v1%s%s\tUSB -\tthrough libfreenect%s (%s)\n",
                k.source.c_str(), k.serial.empty() ? "" : ", ", k.serial.c_str(),
                k.replay ? "'s fakenect" : "", k.library.c_str());
  }
}

int runRecord(const RecordCommandOptions& options) {
  capture::RecordOptions record;
  record.out = options.out;
  record.device_uri = capture::isFreenectSource(options.device)
                          ? pipeline::freenectThroughOpenNI(options.device)
                          : options.device;
  record.max_frames = options.frames;
  record.max_seconds = options.seconds;
  record.compress_color = options.compress_color;
  if (!options.intrinsics.empty()) record.intrinsics = readIntrinsicsJson(options.intrinsics);

  // Ground truth travels with recordings of a virtual sensor whose source has it. Opening the
  // source here first also reports a bad folder before any recording starts.
  if (capture::isVirtualSensorUri(record.device_uri)) {
    record.ground_truth = pipeline::virtualSensorGroundTruth(record.device_uri);
  }

  capture::RecordSummary summary;
  {
    StopSignals signals;
    double last_report = 0.0;
    bool announced = false;
    summary = capture::recordSession(
        record, StopSignals::flag(), [&](std::size_t frames, double seconds) {
          if (!announced) {  // the first call comes once the sensor streams
            announced = true;
            log::info("recording " +
                      (options.device.empty() ? std::string("the first sensor") : options.device) +
                      " to " + options.out.string() + " (Ctrl-C stops)");
          }
          if (seconds - last_report >= 5.0) {
            last_report = seconds;
            log::info("recording: " + std::to_string(frames) + " frames, " +
                      std::to_string(static_cast<int>(seconds)) + " s");
          }
        });
  }

  std::printf("recording     %s\n", options.out.string().c_str());
  std::printf("frames        %zu depth, %zu colour\n", summary.depth_frames, summary.color_frames);
  std::printf("dropped       %zu\n", summary.dropped);
  std::printf("duration      %.2f s\n", summary.duration_s);
  std::printf("stopped by    %s\n", summary.stop_reason.c_str());
  std::printf("sidecars      %s%s%s\n", summary.info_file.filename().string().c_str(),
              summary.ground_truth_file.empty() ? "" : ", ",
              summary.ground_truth_file.filename().string().c_str());
  std::fflush(stdout);
  if (summary.failed) {
    std::fprintf(
        stderr, "objscan: error: recording stopped early: %s; the %zu frames before it are in %s\n",
        summary.stop_reason.c_str(), summary.depth_frames, options.out.string().c_str());
    return kExitRuntimeFailure;
  }
  return kExitSuccess;
}

}  // namespace objscan::app
