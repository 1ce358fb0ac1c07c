// openni::Recorder around a sensor's streams.
//
// Guarantees and how they are kept:
// - Every captured frame reaches the file: the recorder is started, and the streams only after
//   the recorder has really begun (its data-begin records are in the file; openni::Recorder
//   starts asynchronously and silently ignores frames that arrive before), and frame limits stop
//   the recorder from inside the new-frame callback, before the next frame is raised.
// - A stop for any reason (limit, Ctrl-C, sensor lost, disk nearly full, an exception, the owner
//   destroyed) detaches the streams and destroys the recorder, which writes the seek tables and
//   the end record: the file always replays. It is written under a temporary name and renamed
//   only once complete.
// - The disk never fills mid-frame: recording stops while free space (and the process's file
//   size limit) still leave room for the frames in flight and the closing records.

#include "oni_recorder.h"

#include <sys/resource.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "objscan/capture/oni_container.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"

namespace objscan::capture::openni_detail {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr auto kRecorderStartTimeout = std::chrono::seconds(5);

/// ".<name>.partial-<pid>" beside `out`; a plain ASCII name when OpenNI2 could not take `out`'s
/// own name (openni_path.h).
fs::path temporaryName(const fs::path& out) {
  const std::string pid = std::to_string(::getpid());
  std::string name = ".";
  name.append(out.filename().string()).append(".partial-").append(pid);
  if (!openNICanTake(name)) name = std::string(".objscan-recording.partial-").append(pid);
  return out.parent_path() / name;
}

/// The folder the recording is written in, as OpenNI2 can take it (with the file's name).
OpenNIPath recorderFolder(const fs::path& temp) {
  const fs::path parent = temp.parent_path().empty() ? fs::path(".") : temp.parent_path();
  return OpenNIPath(parent, "folder", 1 + temp.filename().string().size());
}

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
    std::uint64_t size = fs::file_size(file, ec);
    if (ec) size = 0;  // not created yet
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

/// Calls `on_new_frame` when a stream has a new frame, without reading it (another reader does).
class NewFrameNotice : public openni::VideoStream::NewFrameListener {
 public:
  explicit NewFrameNotice(std::function<void()> on_new_frame)
      : on_new_frame_(std::move(on_new_frame)) {}
  void onNewFrame(openni::VideoStream& /*stream*/) override { on_new_frame_(); }

 private:
  std::function<void()> on_new_frame_;
};

}  // namespace

void checkRecordingTarget(const fs::path& out) {
  std::error_code ec;
  if (out.empty()) throw std::invalid_argument("--out must name the .oni file to write");
  if (fs::is_directory(out, ec)) throw InputError(out, "is a directory; name the .oni file");
  const fs::path parent = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  if (!fs::is_directory(parent, ec)) throw OutputError(out, "its folder does not exist");
  if (const int error = probeWritableFolder(parent); error != 0) {
    throw OutputError(out,
                      "cannot write a file in its folder: " + std::string(std::strerror(error)));
  }
}

std::string sensorLostReason(std::size_t frames, bool disconnected) {
  return "the sensor stopped delivering frames after " + std::to_string(frames) + " frames" +
         (disconnected ? " (it was unplugged)" : " (unplugged?)");
}

OniRecorder::OniRecorder(const Options& options, openni::VideoStream& depth,
                         openni::VideoStream* color)
    : options_(options), temp_(temporaryName(options.out)), depth_(depth), color_(color) {
  const openni::VideoMode mode = depth.getVideoMode();
  const std::uint64_t frame_bytes = static_cast<std::uint64_t>(mode.getResolutionX()) *
                                    static_cast<std::uint64_t>(mode.getResolutionY()) *
                                    (color != nullptr ? 5 : 2);
  // Room for about a second of frames still queued in the recorder plus its closing records.
  margin_bytes_ = 40 * frame_bytes + (1u << 20);
  folder_alias_ = recorderFolder(temp_);
  const std::string openni_temp = folder_alias_.path() + "/" + temp_.filename().string();
  if (recorder_.create(openni_temp.c_str()) != openni::STATUS_OK) {
    std::error_code ec;
    fs::remove(temp_, ec);
    throw OutputError(options_.out, "cannot create the recording: " + lastError());
  }
  // Refused up front when not even the margin fits: OpenNI2's recorder ignores failed writes, so
  // a file that runs out of room before the first check would be left without its frames.
  if (const std::uint64_t room = roomLeft(temp_, options_.min_free_bytes); room < margin_bytes_) {
    recorder_.destroy();
    std::error_code ec;
    fs::remove(temp_, ec);
    throw OutputError(options_.out,
                      "not enough room to record: " + std::to_string(room >> 10) +
                          " kB can be written there (free disk space less the reserve, or the "
                          "file size limit), a recording needs " +
                          std::to_string(margin_bytes_ >> 10) + " kB at least");
  }
  if (recorder_.attach(depth_, /*allowLossyCompression=*/false) != openni::STATUS_OK ||
      (color_ != nullptr &&
       recorder_.attach(*color_, options_.compress_color) != openni::STATUS_OK)) {
    const std::string error = lastError();
    recorder_.destroy();
    std::error_code ec;
    fs::remove(temp_, ec);
    throw std::runtime_error("OpenNI2 cannot record this sensor's streams: " + error);
  }
  auto listener = [this]() -> std::unique_ptr<openni::VideoStream::NewFrameListener> {
    if (options_.counting == Options::Counting::kInCallbacks) {
      return std::make_unique<FrameListener>(
          [this](const openni::VideoFrameRef& f) { countFrame(f); });
    }
    return std::make_unique<NewFrameNotice>([this] { checkRoom(); });
  };
  depth_listener_ = listener();
  depth_.addNewFrameListener(depth_listener_.get());
  if (color_ != nullptr) {
    color_listener_ = listener();
    color_->addNewFrameListener(color_listener_.get());
  }
}

OniRecorder::~OniRecorder() {
  close();
  if (!published_) {
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void OniRecorder::start() {
  recorder_.start();
  if (!waitForRecorderStart(temp_, color_ != nullptr ? 2 : 1)) {
    log::warning("OpenNI2's recorder took over 5 s to start; the first frames may be missing");
  }
}

// OpenNI2 raises new-frame callbacks asynchronously and coalesces them (a callback reads the
// latest frame), so frames are counted from the sensor's frame numbers, not from callbacks.
void OniRecorder::countFrame(const openni::VideoFrameRef& ref) {
  std::lock_guard<std::mutex> lock(mutex_);
  Progress& p = progress_;
  if (p.limit_reached || p.disk_low) return;
  const int index = ref.getFrameIndex();
  if (ref.getSensorType() == openni::SENSOR_DEPTH) {
    if (p.depth_frames == 0) {
      first_depth_index_ = index;
      p.first_frame = Clock::now();
    }
    p.depth_frames = static_cast<std::size_t>(std::max(index - first_depth_index_ + 1, 1));
    p.last_frame = Clock::now();
  } else {
    if (p.color_frames == 0) first_color_index_ = index;
    p.color_frames = static_cast<std::size_t>(std::max(index - first_color_index_ + 1, 1));
  }
  const std::size_t* limit = options_.max_frames ? &*options_.max_frames : nullptr;
  if (limit != nullptr && p.depth_frames >= *limit &&
      (color_ == nullptr || p.color_frames >= *limit)) {
    recorder_.stop();
    p.limit_reached = true;
  } else if (roomLeft(temp_, options_.min_free_bytes) < margin_bytes_) {
    recorder_.stop();
    p.disk_low = true;
  }
}

void OniRecorder::checkRoom() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (progress_.limit_reached || progress_.disk_low) return;
  if (roomLeft(temp_, options_.min_free_bytes) < margin_bytes_) {
    recorder_.stop();
    progress_.disk_low = true;
  }
}

OniRecorder::Progress OniRecorder::progress() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return progress_;
}

void OniRecorder::close() noexcept {
  if (closed_) return;
  closed_ = true;
  {
    // Not while a frame callback stops it too. The lock is released before the listeners are
    // removed: removing one waits for its callback to return, which may wait for this lock.
    std::lock_guard<std::mutex> lock(mutex_);
    recorder_.stop();
  }
  // The streams stop and forget the listeners before the listeners can go out of scope.
  if (depth_listener_) depth_.removeNewFrameListener(depth_listener_.get());
  if (color_listener_) color_->removeNewFrameListener(color_listener_.get());
  depth_.stop();
  if (color_ != nullptr) color_->stop();
  recorder_.destroy();  // detaches the streams: seek tables, frame counts and the end record
}

RecordSummary OniRecorder::publish(
    const RecordingFacts& facts, const std::string& stop_reason, bool failed,
    const std::optional<std::pair<std::size_t, std::string>>& complete_at) {
  close();
  RecordSummary summary;
  summary.stop_reason = stop_reason;
  summary.failed = failed;
  const Progress s = progress();
  summary.duration_s =
      s.depth_frames > 1 ? std::chrono::duration<double>(s.last_frame - s.first_frame).count() : 0;
  std::error_code ec;
  OniFileSummary written;
  try {
    written = inspectOniFile(temp_);
  } catch (const InputError& e) {
    // OpenNI2's recorder could not write everything (the disk filled from elsewhere).
    throw OutputError(options_.out,
                      std::string("the recording could not be completed (") + e.what() + ")");
  }
  if (written.records_end > 0 && written.records_end < written.bytes) {
    // Drop the zero padding OpenNI2 leaves after the end record: it doubles the file's size.
    fs::resize_file(temp_, written.records_end, ec);
    if (!ec) written = inspectOniFile(temp_);
  }
  for (const OniStreamSummary& stream : written.streams) {
    if (stream.type == "depth") summary.depth_frames = stream.data_records;
    if (stream.type == "color") summary.color_frames = stream.data_records;
  }
  if (failed && complete_at && summary.depth_frames >= complete_at->first &&
      (color_ == nullptr || summary.color_frames >= complete_at->first)) {
    summary.failed = false;
    summary.stop_reason = complete_at->second;
  }
  // Frames the sensor numbered while recording but that are not in the file.
  summary.dropped =
      s.depth_frames > summary.depth_frames ? s.depth_frames - summary.depth_frames : 0;
  if (summary.depth_frames == 0) {
    throw std::runtime_error(stop_reason.empty() ? std::string("no frame was recorded")
                                                 : "no frame was recorded: " + stop_reason);
  }
  const fs::path& out = options_.out;
  fs::rename(temp_, out, ec);
  if (ec) {
    throw OutputError(out, "cannot rename the finished recording into place: " + ec.message());
  }
  published_ = true;

  const Intrinsics& in = facts.intrinsics;
  nlohmann::json info = {{"fx", in.fx_px},
                         {"fy", in.fy_px},
                         {"cx", in.cx_px},
                         {"cy", in.cy_px},
                         {"width", in.width_px},
                         {"height", in.height_px},
                         {"intrinsics_origin", facts.intrinsics_origin},
                         {"time_offset_s", facts.time_offset_s},
                         {"device_uri", facts.device_uri},
                         {"depth_frames", summary.depth_frames},
                         {"color_frames", summary.color_frames},
                         {"dropped_frames", summary.dropped},
                         {"duration_s", summary.duration_s},
                         {"color_codec", options_.compress_color ? "jpeg" : "lossless"},
                         {"stop_reason", summary.stop_reason}};
  const RecordingSidecars sidecars = RecordingSidecars::of(out);
  // A path or reason that is not UTF-8 is written with U+FFFD (JSON is UTF-8).
  std::string text = info.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
  text.push_back('\n');
  writeFileAtomically(sidecars.info, text);
  summary.info_file = sidecars.info;
  if (facts.ground_truth && !facts.ground_truth->empty()) {
    writeTumTrajectory(sidecars.ground_truth, *facts.ground_truth);
    summary.ground_truth_file = sidecars.ground_truth;
  }
  return summary;
}

}  // namespace objscan::capture::openni_detail
