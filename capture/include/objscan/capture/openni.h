#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "objscan/capture/frame_source.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/trajectory.h"

/// Capture through the OpenNI2 runtime: live sensors (Asus Xtion, PrimeSense Carmine through their
/// OpenNI2 drivers, and objscan's virtual sensor, which also streams a Kinect v1 from libfreenect
/// for recording: freenect.h), `.oni` replay and `.oni` recording.
/// OpenNI2 types stay out of this header.
namespace objscan::capture {

/// A device OpenNI2 can open.
struct SensorDescription {
  std::string uri;
  std::string vendor;
  std::string name;
  std::uint16_t usb_vendor_id = 0;
  std::uint16_t usb_product_id = 0;
};

/// The sensors OpenNI2 finds now. Throws std::runtime_error when OpenNI2 cannot start.
std::vector<SensorDescription> listSensors();

/// Files written next to a recording `X.oni` by `objscan record` and read back by replay.
struct RecordingSidecars {
  std::filesystem::path info;          ///< X.oni.json: intrinsics (core's format) + time offset
  std::filesystem::path ground_truth;  ///< X.oni.groundtruth.txt: TUM trajectory, when known
  static RecordingSidecars of(const std::filesystem::path& oni);
};

/// Replays an `.oni` file through OpenNI2's file player as fast as the caller reads, dropping no
/// frame, in file order; each depth frame is paired with the colour frame nearest in time. The
/// file's structure is checked first (truncated, unfinished or colour-only recordings are refused
/// with InputError). Intrinsics: `intrinsics_override`, else X.oni.json, else the recorded field
/// of view, else the Xtion defaults. Frame stamps are the recording's clock (+ the time offset of
/// X.oni.json), so they match X.oni.groundtruth.txt.
std::unique_ptr<FrameSource> openOniFile(const std::filesystem::path& file,
                                         const FrameSelection& selection = {},
                                         const std::optional<Intrinsics>& intrinsics_override = {},
                                         const std::string& intrinsics_origin = {});

/// What a finished recording holds and why it stopped.
struct RecordSummary {
  std::size_t depth_frames = 0;  ///< in the finished file (read back)
  std::size_t color_frames = 0;
  std::size_t dropped = 0;  ///< gaps in the sensor's depth frame numbers
  double duration_s = 0.0;  ///< wall time from the first to the last frame
  std::string stop_reason;  ///< "frame limit", "time limit", "interrupted", "end of source"...
  bool failed = false;      ///< stopped by a fault (sensor lost, disk full); file still valid
  std::filesystem::path info_file;          ///< X.oni.json written
  std::filesystem::path ground_truth_file;  ///< empty when none was given
};

/// Recording what a live source delivers while it is read (`objscan scan --record X.oni`).
struct LiveRecording {
  std::filesystem::path out;                 ///< the .oni to write (atomically: temp + rename)
  bool compress_color = false;               ///< JPEG colour (lossy); depth is always lossless
  std::uint64_t min_free_bytes = 64u << 20;  ///< stop recording before the disk has less free
  std::optional<Trajectory> ground_truth;    ///< written as X.oni.groundtruth.txt when set
};

/// A live source that records the sensor's raw streams to `.oni` while next() reads them: the
/// recorder is attached to the very depth and colour streams next() reads, so the file holds
/// every frame the sensor delivered while recording, which includes every frame next() returned
/// (and may hold a frame or two more: frames that arrived while the caller was busy, or after its
/// last next() call). Not thread-safe: call next() and finishRecording() from one thread.
class RecordingFrameSource : public FrameSource {
 public:
  /// Stops the sensor and closes the recording: the file is renamed into place and replays every
  /// frame recorded; X.oni.json (and X.oni.groundtruth.txt) are written next to it. Afterwards
  /// next() returns the end of the stream. `reason` (e.g. "interrupted", "frame limit") becomes
  /// the summary's stop_reason unless the source had stopped by itself first: the end of a
  /// virtual sensor's source, the sensor lost (unplugged, next() threw) or the disk nearly full
  /// (then next() had ended the stream) — those are reported, the last two with `failed` set.
  /// A second call returns the same summary. Throws std::runtime_error when no frame was
  /// recorded (no file is left), OutputError when the file cannot be put in place.
  /// Destroying the source without calling this finishes the recording the same way (errors are
  /// logged as warnings, never thrown).
  virtual RecordSummary finishRecording(const std::string& reason) = 0;
};

/// Opens a live sensor: `uri` or, when empty, the first one found. 640x480 depth (mm) + RGB at
/// 30 Hz where the sensor offers it, depth registered to colour when supported, frame sync on,
/// mirroring off. Intrinsics from the sensor's field of view (Xtion defaults when it reports
/// none), unless overridden. next() waits up to 3 s for a frame; a sensor that stops delivering
/// throws std::runtime_error. Throws NoSensorError when `uri` is empty and no sensor is attached,
/// InputError when `uri` names no device.
///
/// With `record`, the source is a RecordingFrameSource (see finishRecording() below): recording
/// has begun when this returns. `record->out` is checked before the sensor is opened (OutputError
/// naming it: folder missing or not writable).
std::unique_ptr<FrameSource> openSensor(const std::string& uri,
                                        const std::optional<Intrinsics>& intrinsics_override = {},
                                        const std::string& intrinsics_origin = {},
                                        const std::optional<LiveRecording>& record = {});

/// Finishes the recording `source` makes (see RecordingFrameSource::finishRecording); nullopt,
/// doing nothing, when `source` records nothing.
std::optional<RecordSummary> finishRecording(FrameSource& source, const std::string& reason);

struct RecordOptions {
  std::filesystem::path out;                 ///< the .oni to write (atomically: temp + rename)
  std::string device_uri;                    ///< empty: the first sensor
  std::optional<std::size_t> max_frames;     ///< stop after this many depth frames
  std::optional<double> max_seconds;         ///< stop after this long
  bool compress_color = false;               ///< JPEG colour (lossy); depth is always lossless
  std::optional<Intrinsics> intrinsics;      ///< written to X.oni.json instead of the sensor's
  std::uint64_t min_free_bytes = 64u << 20;  ///< stop before the disk has less than this free
  std::optional<Trajectory> ground_truth;    ///< written as X.oni.groundtruth.txt when set
};

/// Progress during recording: depth frames so far and seconds since start.
using RecordProgress = std::function<void(std::size_t frames, double seconds)>;

/// Records depth (lossless) + colour from a sensor to `options.out` with openni::Recorder until a
/// limit, the end of a virtual sensor's source, `stop` becoming true (Ctrl-C), the sensor
/// stopping (unplugged: no frame for 3 s or a disconnect event), or the disk filling. Every stop
/// closes the recorder cleanly, so the file replays every frame captured before it; the file is
/// written under a temporary name and renamed at the end, with X.oni.json (and
/// X.oni.groundtruth.txt) next to it. Throws before recording starts: NoSensorError (no sensor
/// attached), InputError (bad URI), OutputError (output folder missing or not writable); once
/// frames are in the file it returns a summary with `failed` set instead of throwing.
RecordSummary recordSession(const RecordOptions& options, const std::atomic<bool>& stop,
                            const RecordProgress& progress = {});

}  // namespace objscan::capture
