#pragma once

// Internal to capture/: openni::Recorder writing a sensor's streams to `.oni`, shared by
// `objscan record` (recordSession) and live sources that record while they are read
// (openSensor with a LiveRecording).

#include <OpenNI.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "objscan/capture/openni.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/trajectory.h"
#include "openni_path.h"
#include "openni_runtime.h"

namespace objscan::capture::openni_detail {

/// Checks, before any device is opened, that `out` can be written: named, not a folder, in a
/// folder that exists and takes new files. Throws std::invalid_argument (empty), InputError (a
/// folder), OutputError naming `out` (folder missing, not writable).
void checkRecordingTarget(const std::filesystem::path& out);

/// The stop reason when the disk (or the process's file size limit) left too little room.
inline constexpr char kDiskNearlyFull[] =
    "the disk is nearly full (or the file size limit is near)";

/// "the sensor stopped delivering frames after N frames (it was unplugged)" or "(unplugged?)".
std::string sensorLostReason(std::size_t frames, bool disconnected);

/// What the X.oni.json sidecar says besides the frame counts.
struct RecordingFacts {
  Intrinsics intrinsics;
  std::string intrinsics_origin;
  double time_offset_s = 0.0;  ///< adds back to OpenNI2's stamps to restore the source's clock
  std::string device_uri;
  std::optional<Trajectory> ground_truth;  ///< written as X.oni.groundtruth.txt when not empty
};

/// openni::Recorder attached to a sensor's depth (lossless) and colour streams, writing
/// `.<name>.partial-PID` next to `out`.
///
/// Use: construct (streams created, not started), start() (returns once the recorder really
/// records), start the streams, watch progress(), close() (stops the streams: the file is
/// complete), publish(). The destructor closes the recorder and removes the file unless
/// published. progress() and countFrame() are thread-safe; the rest is for one thread.
///
/// Frames are counted from the sensor's frame numbers. With `Counting::kInCallbacks` (nothing
/// else reads the streams) the recorder reads each new frame on OpenNI2's thread, and stops at
/// `max_frames` there. With `Counting::kByReader` the program reads the streams itself and passes
/// each frame it read to countFrame(): OpenNI2's readFrame() hands a frame to one reader only and
/// blocks the other until the next frame, so a second reader would steal frames. Either way the
/// recorder stops, on OpenNI2's thread at each new frame, when the disk (or the process's file
/// size limit) leaves less than about a second of frames plus the closing records beyond
/// `min_free_bytes`.
class OniRecorder {
 public:
  struct Options {
    std::filesystem::path out;
    bool compress_color = false;
    std::uint64_t min_free_bytes = 64u << 20;
    std::optional<std::size_t> max_frames;  ///< depth (and colour) frames, then stop recording
    enum class Counting { kInCallbacks, kByReader } counting = Counting::kInCallbacks;
  };
  /// `color` may be null (a depth-only sensor). Throws OutputError naming `options.out` when the
  /// file cannot be created, std::runtime_error when OpenNI2 cannot record the streams.
  OniRecorder(const Options& options, openni::VideoStream& depth, openni::VideoStream* color);
  ~OniRecorder();
  OniRecorder(const OniRecorder&) = delete;
  OniRecorder& operator=(const OniRecorder&) = delete;

  /// Starts the recorder and waits (up to 5 s) until it records; call before starting streams.
  void start();

  struct Progress {
    std::size_t depth_frames = 0;  ///< frames the sensor numbered since recording began
    std::size_t color_frames = 0;
    bool limit_reached = false;  ///< max_frames recorded; the recorder has stopped
    bool disk_low = false;       ///< too little room left; the recorder has stopped
    std::chrono::steady_clock::time_point first_frame{}, last_frame{};
  };
  Progress progress() const;

  /// With Counting::kByReader: a frame the program read from one of the streams.
  void countFrame(const openni::VideoFrameRef& ref);

  /// Stops the recorder and the streams, and finishes the file (seek tables, frame counts, end
  /// record): it replays every frame recorded before. Safe to call twice; never throws.
  void close() noexcept;

  /// After close(): trims the padding OpenNI2 leaves, reads the file back, renames it to `out` and
  /// writes X.oni.json (and X.oni.groundtruth.txt). Throws std::runtime_error when the file holds
  /// no frame (it is removed), OutputError when it cannot be put in place.
  /// `complete_at` (a count of frames and a reason): a source with a known end (a virtual
  /// sensor's folder) that stalled. A file holding that many frames of each stream is the end of
  /// the source, said with that reason, not a fault: OpenNI2 coalesces new-frame callbacks, so
  /// when the first ones come together on a busy machine the counts fall short of the end.
  RecordSummary publish(
      const RecordingFacts& facts, const std::string& stop_reason, bool failed,
      const std::optional<std::pair<std::size_t, std::string>>& complete_at = std::nullopt);

  const std::filesystem::path& out() const { return options_.out; }

 private:
  /// On OpenNI2's thread at each new frame: stops the recorder when room runs out.
  void checkRoom();

  Options options_;
  std::filesystem::path temp_;
  OpenNIPath folder_alias_;  ///< temp_'s folder as OpenNI2 can take it, while it writes there
  openni::VideoStream& depth_;
  openni::VideoStream* color_;
  std::uint64_t margin_bytes_ = 0;
  openni::Recorder recorder_;
  std::unique_ptr<openni::VideoStream::NewFrameListener> depth_listener_;
  std::unique_ptr<openni::VideoStream::NewFrameListener> color_listener_;
  bool closed_ = false;
  bool published_ = false;

  mutable std::mutex mutex_;  // guards the counts below, written on OpenNI2's thread
  Progress progress_;
  int first_depth_index_ = 0;
  int first_color_index_ = 0;
};

}  // namespace objscan::capture::openni_detail
