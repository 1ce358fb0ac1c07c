// `.oni` replay through OpenNI2's file player.
//
// The player runs in its manual mode (speed -1): it reads the next frame of the file only when
// the application waits for one, so replay goes exactly as fast as the consumer pulls, in file
// order, and drops nothing. (At "fastest" speed the player runs free and OpenNI2 keeps only the
// latest frame per stream: a consumer that is briefly slower loses frames.)

#include <OpenNI.h>

#include <chrono>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>

#include "objscan/capture/oni_container.h"
#include "objscan/capture/openni.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/trajectory.h"
#include "openni_path.h"
#include "openni_runtime.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;
using namespace openni_detail;

constexpr int kStallTimeoutMs = 10000;

struct QueuedFrame {
  std::uint64_t timestamp_us = 0;
  cv::Mat image;  ///< depth in metres or RGB
};

/// Marks a file as being replayed in this process.
class FileClaim {
 public:
  explicit FileClaim(fs::path path) : path_(std::move(path)) {
    std::lock_guard<std::mutex> lock(mutex());
    if (!open().insert(path_.string()).second) {
      throw InputError(path_,
                       "is already being replayed in this process (OpenNI2 plays a file "
                       "once at a time)");
    }
  }
  ~FileClaim() {
    std::lock_guard<std::mutex> lock(mutex());
    open().erase(path_.string());
  }
  FileClaim(const FileClaim&) = delete;
  FileClaim& operator=(const FileClaim&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static std::set<std::string>& open() {
    static std::set<std::string> files;
    return files;
  }
  fs::path path_;
};

class OniFileSource final : public FrameSource {
 public:
  OniFileSource(const fs::path& file, const FrameSelection& selection,
                const std::optional<Intrinsics>& intrinsics_override,
                const std::string& intrinsics_origin)
      : file_(file), selection_(selection) {
    selection_.validate();
    std::error_code ec;
    if (!fs::exists(file, ec)) throw InputError(file, "no such file");
    if (fs::is_directory(file, ec)) throw InputError(file, "is a directory, not an .oni recording");
    const OniFileSummary summary = inspectOniFile(file);  // throws on truncated/unfinished files
    bool has_depth = false;
    for (const OniStreamSummary& s : summary.streams) has_depth = has_depth || s.type == "depth";
    if (!has_depth) {
      throw InputError(file, "has no depth stream (objscan needs depth; this recording holds " +
                                 std::to_string(summary.streams.size()) + " other stream(s))");
    }

    ensureOpenNI();
    // OpenNI2 hands out one device per URI: a second replay of the same file in this process
    // would share (and disturb) the first one's player.
    claim_ = std::make_unique<FileClaim>(fs::absolute(file));
    openni_path_ = OpenNIPath(file, "recording.oni");
    if (device_.open(openni_path_.path().c_str()) != openni::STATUS_OK) {
      throw InputError(file, "OpenNI2's file player cannot open it: " + lastError());
    }
    openni::PlaybackControl* playback = device_.getPlaybackControl();
    if (playback == nullptr) throw InputError(file, "OpenNI2 does not treat it as a recording");
    playback->setRepeatEnabled(false);
    playback->setSpeed(-1.0f);  // manual: the player reads a frame when we wait for one

    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      throw InputError(file, "OpenNI2 cannot replay its depth stream: " + lastError());
    }
    depth_total_ = static_cast<std::size_t>(std::max(0, playback->getNumberOfFrames(depth_)));
    if (device_.hasSensor(openni::SENSOR_COLOR) &&
        color_.create(device_, openni::SENSOR_COLOR) == openni::STATUS_OK) {
      has_color_ = true;
      color_total_ = static_cast<std::size_t>(std::max(0, playback->getNumberOfFrames(color_)));
    }

    const RecordingSidecars sidecars = RecordingSidecars::of(file);
    double time_offset_s = 0.0;
    if (fs::exists(sidecars.info, ec)) {
      std::optional<double> unused;
      if (!intrinsics_override) {
        info_.intrinsics = readIntrinsicsJson(sidecars.info, &unused);
        info_.intrinsics_origin = sidecars.info.filename().string();
      }
      try {
        const nlohmann::json j = nlohmann::json::parse(readWholeFile(sidecars.info));
        if (j.contains("time_offset_s") && j["time_offset_s"].is_number()) {
          time_offset_s = j["time_offset_s"].get<double>();
        }
      } catch (const nlohmann::json::exception& e) {
        throw InputError(sidecars.info, std::string("is not valid JSON: ") + e.what());
      }
    } else if (!intrinsics_override) {
      info_.intrinsics = intrinsicsFromStream(depth_, &info_.intrinsics_origin);
    }
    if (intrinsics_override) {
      info_.intrinsics = *intrinsics_override;
      info_.intrinsics_origin = intrinsics_origin.empty() ? "given" : intrinsics_origin;
    }
    // Without its sidecar a recording carries only the sensor's nominal field of view (or not
    // even that): not a calibration.
    info_.intrinsics_assumed = !intrinsics_override && !fs::exists(sidecars.info, ec);
    info_.depth_units = "OpenNI2 depth in millimetres";
    time_offset_s_ = time_offset_s;
    if (fs::exists(sidecars.ground_truth, ec)) {
      info_.ground_truth = readTumTrajectory(sidecars.ground_truth);
    }
    requireIntrinsicsFit(depth_, info_, file.string());
    info_.frame_count = selection_.count(depth_total_);
    info_.description = "OpenNI recording " + file.string() + ", " + std::to_string(depth_total_) +
                        " depth and " + std::to_string(color_total_) + " colour frames";

    if (depth_.start() != openni::STATUS_OK ||
        (has_color_ && color_.start() != openni::STATUS_OK)) {
      close();
      throw InputError(file, "OpenNI2 cannot start replaying it: " + lastError());
    }
  }

  ~OniFileSource() override { close(); }

  const SourceInfo& info() const override { return info_; }

  FrameResult next() override {
    for (;;) {
      if (selection_.end && depth_taken_ >= *selection_.end) return FrameResult::end();
      while (depth_queue_.empty() && depth_received_ < depth_total_) pull();
      if (depth_queue_.empty()) return FrameResult::end();
      QueuedFrame depth = std::move(depth_queue_.front());
      depth_queue_.pop_front();
      const std::size_t index = depth_taken_++;
      cv::Mat color = has_color_ ? colorFor(depth.timestamp_us) : cv::Mat();
      if (!selection_.selects(index)) continue;
      RgbdFrame frame;
      frame.index = static_cast<std::int64_t>(index);
      frame.stamp_s = time_offset_s_ + static_cast<double>(depth.timestamp_us) * 1e-6;
      frame.depth_m = std::move(depth.image);
      if (!color.empty() && color.size() == frame.depth_m.size())
        frame.color_rgb = std::move(color);
      frame.intrinsics = info_.intrinsics;
      return FrameResult::ok(std::move(frame));
    }
  }

 private:
  /// Lets the player read the next frame of the file, whichever stream it belongs to.
  void pull() {
    openni::VideoStream* streams[2] = {&depth_, &color_};
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(streams, has_color_ ? 2 : 1, &ready, kStallTimeoutMs) !=
        openni::STATUS_OK) {
      throw InputError(file_, "OpenNI2's player stopped after " + std::to_string(depth_received_) +
                                  " of " + std::to_string(depth_total_) + " depth frames and " +
                                  std::to_string(color_received_) + " of " +
                                  std::to_string(color_total_) + " colour frames");
    }
    openni::VideoFrameRef ref;
    if (streams[ready]->readFrame(&ref) != openni::STATUS_OK) return;
    if (ready == 0) {
      depth_queue_.push_back({ref.getTimestamp(), depthToMetres(ref)});
      ++depth_received_;
    } else {
      color_queue_.push_back({ref.getTimestamp(), colorToRgb(ref)});
      ++color_received_;
    }
  }

  /// The colour frame nearest in time to a depth frame, within 20 ms (empty if none). Consumes
  /// colour frames up to the depth frame's time; a later one is taken only if it is the nearest.
  cv::Mat colorFor(std::uint64_t depth_us) {
    constexpr std::uint64_t kToleranceUs = 20000;
    // Read on until a colour frame at or after the depth frame is queued (or colour ends).
    while ((color_queue_.empty() || color_queue_.back().timestamp_us < depth_us) &&
           color_received_ < color_total_) {
      pull();
    }
    cv::Mat best;
    std::uint64_t best_gap = kToleranceUs + 1;
    while (!color_queue_.empty()) {
      const std::uint64_t ts = color_queue_.front().timestamp_us;
      const std::uint64_t gap = ts > depth_us ? ts - depth_us : depth_us - ts;
      if (ts > depth_us && gap >= best_gap) break;  // keep it for the next depth frame
      if (gap < best_gap) {
        best = std::move(color_queue_.front().image);
        best_gap = gap;
      }
      color_queue_.pop_front();
      if (ts >= depth_us) break;
    }
    return best;
  }

  void close() {
    // Debian's file player walks its stream list without its lock at the top of every loop, and
    // with a started stream at the end of the file it loops without pause. Destroying a stream
    // then races that walk and crashed about one replay in five. With every stream stopped the
    // loop walks the list once per 10 ms sleep, so stop all streams, let it reach that sleep,
    // and only then destroy them.
    depth_.stop();
    color_.stop();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    depth_.destroy();
    color_.destroy();
    if (device_.isValid()) device_.close();
  }

  fs::path file_;
  std::unique_ptr<FileClaim> claim_;  ///< released after the device closes (declared first)
  FrameSelection selection_;
  SourceInfo info_;
  double time_offset_s_ = 0.0;
  OpenNIPath openni_path_;  ///< before device_: the alias outlives the device that reads it
  openni::Device device_;
  openni::VideoStream depth_;
  openni::VideoStream color_;
  bool has_color_ = false;
  std::size_t depth_total_ = 0;
  std::size_t color_total_ = 0;
  std::size_t depth_taken_ = 0;

  std::deque<QueuedFrame> depth_queue_;
  std::deque<QueuedFrame> color_queue_;
  std::size_t depth_received_ = 0;
  std::size_t color_received_ = 0;
};

}  // namespace

std::unique_ptr<FrameSource> openOniFile(const fs::path& file, const FrameSelection& selection,
                                         const std::optional<Intrinsics>& intrinsics_override,
                                         const std::string& intrinsics_origin) {
  return std::make_unique<OniFileSource>(file, selection, intrinsics_override, intrinsics_origin);
}

}  // namespace objscan::capture
