// Recording a sensor to `.oni` with openni::Recorder.
//
// Guarantees and how they are kept:
// - Every captured frame reaches the file: the recorder is started, and the streams only after
//   the recorder has really begun (its data-begin records are in the file; openni::Recorder
//   starts asynchronously and silently ignores frames that arrive before), and frame limits stop
//   the recorder from inside the new-frame callback, before the next frame is raised.
// - A stop for any reason (limit, Ctrl-C, sensor lost, disk nearly full) detaches the streams
//   and destroys the recorder, which writes the seek tables and the end record: the file always
//   replays. It is written under a temporary name and renamed only once complete.
// - The disk never fills mid-frame: recording stops while free space (and the process's file
//   size limit) still leave room for the frames in flight and the closing records.

#include <OpenNI.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>

#include "objscan/capture/oni_container.h"
#include "objscan/capture/openni.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "openni_runtime.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;
using namespace openni_detail;
using Clock = std::chrono::steady_clock;

constexpr auto kStallTimeout = std::chrono::seconds(3);
constexpr auto kRecorderStartTimeout = std::chrono::seconds(5);

/// Counts frames per stream, notices dropped frame numbers, and stops the recorder at the limit.
class FrameCounter {
 public:
  FrameCounter(openni::Recorder& recorder, bool has_color, std::optional<std::size_t> limit)
      : recorder_(recorder), has_color_(has_color), limit_(limit) {}

  // OpenNI2 raises new-frame callbacks asynchronously and coalesces them (a callback reads the
  // latest frame), so frames are counted from the sensor's frame numbers, not from callbacks.
  void onFrame(const openni::VideoFrameRef& ref) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (limit_reached_) return;
    const int index = ref.getFrameIndex();
    if (ref.getSensorType() == openni::SENSOR_DEPTH) {
      if (depth_frames_ == 0) {
        first_depth_index_ = index;
        first_frame_ = Clock::now();
      }
      depth_frames_ = static_cast<std::size_t>(std::max(index - first_depth_index_ + 1, 1));
      last_frame_ = Clock::now();
    } else {
      if (color_frames_ == 0) first_color_index_ = index;
      color_frames_ = static_cast<std::size_t>(std::max(index - first_color_index_ + 1, 1));
    }
    if (limit_ && depth_frames_ >= *limit_ && (!has_color_ || color_frames_ >= *limit_)) {
      recorder_.stop();
      limit_reached_ = true;
    }
  }

  struct Snapshot {
    std::size_t depth_frames, color_frames;  ///< frames the sensor numbered since recording began
    bool limit_reached;
    Clock::time_point first_frame, last_frame;
  };
  Snapshot snapshot() {
    std::lock_guard<std::mutex> lock(mutex_);
    return {depth_frames_, color_frames_, limit_reached_, first_frame_, last_frame_};
  }

 private:
  openni::Recorder& recorder_;
  bool has_color_;
  std::optional<std::size_t> limit_;
  std::mutex mutex_;
  std::size_t depth_frames_ = 0;
  std::size_t color_frames_ = 0;
  int first_depth_index_ = 0;
  int first_color_index_ = 0;
  bool limit_reached_ = false;
  Clock::time_point first_frame_{};
  Clock::time_point last_frame_{};
};

/// Bytes still writable to `file`: free disk space minus the reserve, and the process's file
/// size limit (RLIMIT_FSIZE) minus the file's size.
std::uint64_t roomLeft(const fs::path& file, std::uint64_t reserve) {
  std::uint64_t room = UINT64_MAX;
  struct statvfs vfs {};
  if (::statvfs(file.parent_path().empty() ? "." : file.parent_path().c_str(), &vfs) == 0) {
    const std::uint64_t free_bytes = static_cast<std::uint64_t>(vfs.f_bavail) * vfs.f_frsize;
    room = free_bytes > reserve ? free_bytes - reserve : 0;
  }
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    std::error_code ec;
    const std::uint64_t size = fs::file_size(file, ec);
    const std::uint64_t cap = static_cast<std::uint64_t>(limit.rlim_cur);
    room = std::min(room, cap > size ? cap - size : 0);
  }
  return room;
}

/// Waits until openni::Recorder has processed its start: every attached stream's data-begin
/// record is in the file.
bool waitForRecorderStart(const fs::path& file, std::size_t streams) {
  const auto deadline = Clock::now() + kRecorderStartTimeout;
  while (Clock::now() < deadline) {
    try {
      const OniFileSummary summary = inspectOniFile(file, /*tolerate_unfinished=*/true);
      std::size_t begun = 0;
      for (const OniStreamSummary& s : summary.streams) begun += s.data_begun ? 1 : 0;
      if (summary.streams.size() == streams && begun == streams) {
        // The recorder sets its started flag right after writing these records.
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        return true;
      }
    } catch (const InputError&) {
      // not written yet
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

fs::path temporaryName(const fs::path& out) {
  fs::path temp = out.parent_path();
  std::string name = ".";
  name.append(out.filename().string()).append(".partial-").append(std::to_string(::getpid()));
  return temp / name;
}

}  // namespace

RecordSummary recordSession(const RecordOptions& options, const std::atomic<bool>& stop,
                            const RecordProgress& progress) {
  const fs::path& out = options.out;
  std::error_code ec;
  if (out.empty()) throw std::invalid_argument("--out must name the .oni file to write");
  if (fs::is_directory(out, ec)) throw InputError(out, "is a directory; name the .oni file");
  const fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  if (!fs::is_directory(parent, ec)) throw OutputError(out, "its folder does not exist");
  if (options.max_seconds && !(*options.max_seconds > 0.0)) {
    throw std::invalid_argument("--seconds must be positive");
  }
  if (options.max_frames && *options.max_frames == 0) {
    throw std::invalid_argument("--frames must be at least 1");
  }

  openni::Device device;
  openDevice(device, options.device_uri);
  const std::string uri = device.getDeviceInfo().getUri();
  openni::VideoStream depth;
  openni::VideoStream color;
  bool has_color = false;
  createLiveStreams(device, depth, color, &has_color);

  std::string intrinsics_origin;
  Intrinsics intrinsics = intrinsicsFromStream(depth, &intrinsics_origin);
  double time_offset_s = 0.0;
  std::optional<std::size_t> limit = options.max_frames;
  std::string stop_at_end;
  if (const auto facts = virtualDeviceFacts(device)) {
    intrinsics = facts->intrinsics;
    intrinsics_origin = "the virtual sensor's source";
    time_offset_s = facts->time_offset_s;
    if (!limit || *limit >= facts->frame_count) {
      limit = facts->frame_count;
      stop_at_end = "end of the virtual sensor's source";
    }
  }

  if (options.intrinsics) {
    if (options.intrinsics->width_px != intrinsics.width_px ||
        options.intrinsics->height_px != intrinsics.height_px) {
      throw std::invalid_argument(
          "--intrinsics are for " + std::to_string(options.intrinsics->width_px) + "x" +
          std::to_string(options.intrinsics->height_px) + " images but the sensor streams " +
          std::to_string(intrinsics.width_px) + "x" + std::to_string(intrinsics.height_px));
    }
    intrinsics = *options.intrinsics;
    intrinsics_origin = "given with --intrinsics";
  }

  const fs::path temp = temporaryName(out);
  openni::Recorder recorder;
  if (recorder.create(temp.c_str()) != openni::STATUS_OK) {
    throw OutputError(out, "cannot create the recording: " + lastError());
  }
  struct TempCleanup {
    const fs::path& path;
    bool keep = false;
    ~TempCleanup() {
      std::error_code e;
      if (!keep) fs::remove(path, e);
    }
  } cleanup{temp};
  if (recorder.attach(depth, /*allowLossyCompression=*/false) != openni::STATUS_OK ||
      (has_color && recorder.attach(color, options.compress_color) != openni::STATUS_OK)) {
    throw std::runtime_error("OpenNI2 cannot record this sensor's streams: " + lastError());
  }
  FrameCounter counter(recorder, has_color, limit);
  FrameListener depth_listener([&](const openni::VideoFrameRef& f) { counter.onFrame(f); });
  FrameListener color_listener([&](const openni::VideoFrameRef& f) { counter.onFrame(f); });
  depth.addNewFrameListener(&depth_listener);
  if (has_color) color.addNewFrameListener(&color_listener);
  // On every way out (errors included), the streams stop and forget the listeners before the
  // listeners go out of scope. Stopping twice and removing twice are harmless.
  struct StreamCleanup {
    openni::VideoStream& depth;
    openni::VideoStream& color;
    FrameListener& depth_listener;
    FrameListener& color_listener;
    ~StreamCleanup() {
      depth.removeNewFrameListener(&depth_listener);
      color.removeNewFrameListener(&color_listener);
      depth.stop();
      color.stop();
    }
  } stream_cleanup{depth, color, depth_listener, color_listener};
  recorder.start();
  if (!waitForRecorderStart(temp, has_color ? 2 : 1)) {
    log::warning("OpenNI2's recorder took over 5 s to start; the first frames may be missing");
  }

  RecordSummary summary;
  const std::uint64_t frame_bytes =
      static_cast<std::uint64_t>(intrinsics.width_px) * intrinsics.height_px * (has_color ? 5 : 2);
  // Room for about a second of frames still queued in the recorder plus its closing records.
  const std::uint64_t margin = 40 * frame_bytes + (1u << 20);
  const auto start = Clock::now();
  if (depth.start() != openni::STATUS_OK || (has_color && color.start() != openni::STATUS_OK)) {
    throw std::runtime_error("cannot start the sensor's streams: " + lastError());
  }
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const FrameCounter::Snapshot s = counter.snapshot();
    const auto now = Clock::now();
    const double seconds =
        s.depth_frames > 0 ? std::chrono::duration<double>(now - s.first_frame).count() : 0.0;
    if (progress) progress(s.depth_frames, seconds);
    if (s.limit_reached) {
      summary.stop_reason = stop_at_end.empty() ? "frame limit" : stop_at_end;
      break;
    }
    if (stop.load()) {
      summary.stop_reason = "interrupted";
      break;
    }
    if (options.max_seconds && s.depth_frames > 0 && seconds >= *options.max_seconds) {
      summary.stop_reason = "time limit";
      break;
    }
    const auto last = s.depth_frames > 0 ? s.last_frame : start;
    if (wasDisconnected(uri) || now - last > kStallTimeout) {
      summary.stop_reason = "the sensor stopped delivering frames after " +
                            std::to_string(s.depth_frames) + " frames" +
                            (wasDisconnected(uri) ? " (it was unplugged)" : " (unplugged?)");
      summary.failed = true;
      break;
    }
    if (roomLeft(temp, options.min_free_bytes) < margin) {
      summary.stop_reason = "the disk is nearly full (or the file size limit is near)";
      summary.failed = true;
      break;
    }
  }
  recorder.stop();
  depth.removeNewFrameListener(&depth_listener);
  if (has_color) color.removeNewFrameListener(&color_listener);
  depth.stop();
  if (has_color) color.stop();
  recorder.destroy();  // detaches the streams: seek tables, frame counts and the end record
  depth.destroy();
  if (has_color) color.destroy();
  device.close();

  const FrameCounter::Snapshot s = counter.snapshot();
  summary.duration_s =
      s.depth_frames > 1 ? std::chrono::duration<double>(s.last_frame - s.first_frame).count() : 0;
  OniFileSummary written = inspectOniFile(temp);
  if (written.records_end > 0 && written.records_end < written.bytes) {
    // Drop the zero padding OpenNI2 leaves after the end record: it doubles the file's size.
    fs::resize_file(temp, written.records_end, ec);
    if (!ec) written = inspectOniFile(temp);
  }
  for (const OniStreamSummary& stream : written.streams) {
    if (stream.type == "depth") summary.depth_frames = stream.data_records;
    if (stream.type == "color") summary.color_frames = stream.data_records;
  }
  // Frames the sensor numbered while recording but that are not in the file.
  summary.dropped =
      s.depth_frames > summary.depth_frames ? s.depth_frames - summary.depth_frames : 0;
  if (summary.depth_frames == 0) {
    throw std::runtime_error(summary.stop_reason.empty()
                                 ? std::string("no frame was recorded")
                                 : "no frame was recorded: " + summary.stop_reason);
  }
  fs::rename(temp, out, ec);
  if (ec)
    throw OutputError(out, "cannot rename the finished recording into place: " + ec.message());
  cleanup.keep = true;

  nlohmann::json info = {{"fx", intrinsics.fx_px},
                         {"fy", intrinsics.fy_px},
                         {"cx", intrinsics.cx_px},
                         {"cy", intrinsics.cy_px},
                         {"width", intrinsics.width_px},
                         {"height", intrinsics.height_px},
                         {"intrinsics_origin", intrinsics_origin},
                         {"time_offset_s", time_offset_s},
                         {"device_uri", uri},
                         {"depth_frames", summary.depth_frames},
                         {"color_frames", summary.color_frames},
                         {"dropped_frames", summary.dropped},
                         {"duration_s", summary.duration_s},
                         {"color_codec", options.compress_color ? "jpeg" : "lossless"},
                         {"stop_reason", summary.stop_reason}};
  summary.info_file = RecordingSidecars::of(out).info;
  std::string text = info.dump(2);
  text.push_back('\n');
  writeFileAtomically(summary.info_file, text);
  return summary;
}

}  // namespace objscan::capture
