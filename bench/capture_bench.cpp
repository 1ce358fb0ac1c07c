// Capture throughput: recording a dataset folder to .oni through objscan's virtual OpenNI2 sensor,
// and replaying that .oni through OpenNI2's file player, next to the peers a user would otherwise
// reach for on the same frames in the same run:
//   - reading the folder itself: objscan's folder source and Open3D's image reader (what Open3D's
//     reconstruction system does with 7-Scenes or TUM data);
//   - replaying the .oni: PCL's OpenNI2Grabber (what pcl_kinfu_app and PCL's viewers use), at
//     its default real-time speed and at OpenNI2's "fastest" speed. A grabber pushes frames to a
//     callback, so a consumer slower than the player loses frames; each replay is also run with
//     a consumer that takes 20 ms per frame (the cost of a fusion step) to show what it keeps.
// Every replay is checked against the folder: frame count, and depth (and raw colour) equal to
// the dataset's images pixel for pixel.
//
//   capture_bench [--folder DIR] [--runs N] [--json PATH] [--keep DIR] [--no-realtime]
// DIR defaults to <data>/7scenes_300. --keep leaves the recordings in DIR instead of a temporary
// folder. --no-realtime skips PCL's real-time replay (it takes frames / 30 seconds).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include <vector>

#include <open3d/geometry/Image.h>
#include <open3d/io/ImageIO.h>
#include <pcl/io/openni2/openni2_device.h>
#include <pcl/io/openni2_grabber.h>
#include <unistd.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "bench_main.h"
#include "build_paths.h"
#include "objscan/capture/folder_source.h"
#include "objscan/capture/openni.h"
#include "objscan/core/atomic_file.h"

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
using Json = nlohmann::json;

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

void consume(int consumer_ms) {
  if (consumer_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(consumer_ms));
}

/// The folder's frames as objscan's folder source reads them: the reference every replay is
/// compared with.
struct Reference {
  std::vector<cv::Mat> depth_m;
  std::vector<cv::Mat> color_rgb;
};

struct Timed {
  std::size_t frames = 0;
  double seconds = 0.0;
  double fps() const { return seconds > 0 ? static_cast<double>(frames) / seconds : 0.0; }
};

Timed readFolder(const fs::path& folder, Reference* keep) {
  const auto t0 = Clock::now();
  auto source = objscan::capture::openFolderSource(folder);
  Timed t;
  for (auto r = source->next(); r.status != objscan::capture::FrameStatus::kEndOfStream;
       r = source->next()) {
    if (r.status != objscan::capture::FrameStatus::kOk)
      throw std::runtime_error("folder source: " + r.reason);
    ++t.frames;
    if (keep) {
      keep->depth_m.push_back(r.frame.depth_m);
      keep->color_rgb.push_back(r.frame.color_rgb);
    }
  }
  t.seconds = seconds(t0, Clock::now());
  return t;
}

/// Open3D's image reader on the folder's depth PNGs and colour JPEGs (7-Scenes names).
Timed readFolderOpen3d(const fs::path& folder) {
  std::vector<fs::path> depth_files;
  for (const auto& e : fs::directory_iterator(folder)) {
    const std::string name = e.path().filename().string();
    if (name.size() > 10 && name.compare(name.size() - 10, 10, ".depth.png") == 0)
      depth_files.push_back(e.path());
  }
  std::sort(depth_files.begin(), depth_files.end());
  const auto t0 = Clock::now();
  Timed t;
  for (const fs::path& depth_file : depth_files) {
    std::string colour_file = depth_file.string();
    colour_file.replace(colour_file.size() - 10, 10, ".color.jpg");
    const auto depth = open3d::io::CreateImageFromFile(depth_file.string());
    const auto colour = open3d::io::CreateImageFromFile(colour_file);
    if (depth->IsEmpty() || colour->IsEmpty())
      throw std::runtime_error("Open3D could not read " + depth_file.string());
    ++t.frames;
  }
  t.seconds = seconds(t0, Clock::now());
  return t;
}

struct Recording {
  fs::path file;
  objscan::capture::RecordSummary summary;
  double wall_s = 0.0;
  std::uintmax_t bytes = 0;
};

Recording record(const fs::path& folder, const fs::path& out, bool compress_color) {
  objscan::capture::RecordOptions options;
  options.out = out;
  // The virtual sensor paces frames at `fps`; 1000 Hz lets the recorder and the folder decoding
  // set the rate. Like a real sensor, it does not wait for a slow recorder: drops are counted.
  options.device_uri = "virtual:" + folder.string() + "?fps=1000";
  options.compress_color = compress_color;
  const std::atomic<bool> stop{false};
  Recording r;
  r.file = out;
  const auto t0 = Clock::now();
  r.summary = objscan::capture::recordSession(options, stop);
  r.wall_s = seconds(t0, Clock::now());
  r.bytes = fs::file_size(out);
  if (r.summary.failed) throw std::runtime_error("recording failed: " + r.summary.stop_reason);
  return r;
}

/// Replays `file` with objscan's .oni source; `consumer_ms` of work per frame. Counts frames whose
/// depth (and colour, when `check_color`) differ from the reference.
struct ObjscanReplay {
  Timed timed;
  std::size_t depth_mismatches = 0;
  std::size_t color_mismatches = 0;
};

bool sameImage(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  cv::Mat diff;
  cv::compare(a, b, diff, cv::CMP_NE);
  return cv::countNonZero(diff.reshape(1)) == 0;
}

ObjscanReplay replayObjscan(const fs::path& file, const Reference& ref, bool check_color,
                            int consumer_ms) {
  ObjscanReplay out;
  const auto t0 = Clock::now();
  auto source = objscan::capture::openOniFile(file);
  for (auto r = source->next(); r.status != objscan::capture::FrameStatus::kEndOfStream;
       r = source->next()) {
    if (r.status != objscan::capture::FrameStatus::kOk)
      throw std::runtime_error("replay: " + r.reason);
    const std::size_t i = out.timed.frames++;
    if (i >= ref.depth_m.size() || !sameImage(r.frame.depth_m, ref.depth_m[i]))
      ++out.depth_mismatches;
    if (check_color &&
        (i >= ref.color_rgb.size() || !sameImage(r.frame.color_rgb, ref.color_rgb[i])))
      ++out.color_mismatches;
    consume(consumer_ms);
  }
  out.timed.seconds = seconds(t0, Clock::now());
  return out;
}

/// One pass of PCL's OpenNI2Grabber over `file`. OpenNI2's player repeats the file, so the pass
/// ends when the frame numbers start again (or nothing arrives for 2 s). `delivered` counts the
/// distinct frames the callback saw in that pass; `timed.seconds` runs from start() to the last
/// of them.
struct PclReplay {
  Timed timed;  ///< frames = delivered
  std::size_t depth_mismatches = 0;
};

PclReplay replayPcl(const fs::path& file, double speed, int consumer_ms, const Reference& ref) {
  pcl::io::OpenNI2Grabber grabber(file.string());
  if (!grabber.getDevice()->setPlaybackSpeed(speed))
    throw std::runtime_error("PCL: cannot set the playback speed");
  std::mutex mutex;
  std::condition_variable done_cv;
  std::set<unsigned> seen;
  unsigned last_id = 0;
  bool done = false;
  std::size_t mismatches = 0;
  Clock::time_point last_frame;
  std::vector<unsigned short> buffer;
  const std::function<void(const pcl::io::DepthImage::Ptr&)> callback =
      [&](const pcl::io::DepthImage::Ptr& depth) {
        const unsigned id = depth->getFrameID();
        {
          std::lock_guard<std::mutex> lock(mutex);
          if (done) return;
          if (!seen.empty() && id <= last_id) {  // the player started the file again
            done = true;
            done_cv.notify_all();
            return;
          }
          last_id = id;
        }
        // What a consumer does first: copy the depth out of the driver's buffer.
        buffer.resize(static_cast<std::size_t>(depth->getWidth()) * depth->getHeight());
        depth->fillDepthImageRaw(depth->getWidth(), depth->getHeight(), buffer.data());
        // OpenNI2 numbers recorded frames from 1.
        const std::size_t index = id >= 1 ? id - 1 : ref.depth_m.size();
        bool same = index < ref.depth_m.size();
        if (same) {
          const cv::Mat mm(ref.depth_m[index].size(), CV_16UC1, buffer.data());
          cv::Mat ref_mm;
          ref.depth_m[index].convertTo(ref_mm, CV_16UC1, 1000.0);  // rounds to the nearest mm
          same = sameImage(mm, ref_mm);
        }
        consume(consumer_ms);
        std::lock_guard<std::mutex> lock(mutex);
        seen.insert(id);
        if (!same) ++mismatches;
        last_frame = Clock::now();
      };
  grabber.registerCallback(callback);
  const auto t0 = Clock::now();
  grabber.start();
  {
    std::unique_lock<std::mutex> lock(mutex);
    while (!done) {
      const std::size_t before = seen.size();
      if (!done_cv.wait_for(lock, std::chrono::seconds(2), [&] { return done; }) &&
          seen.size() == before)
        break;  // nothing new for 2 s
    }
    done = true;
  }
  grabber.stop();
  PclReplay out;
  std::lock_guard<std::mutex> lock(mutex);
  out.timed.frames = seen.size();
  out.timed.seconds = seen.empty() ? 0.0 : seconds(t0, last_frame);
  out.depth_mismatches = mismatches;
  return out;
}

fs::path defaultFolder() {
  const char* env = std::getenv("OBJSCAN_DATA_DIR");
  return fs::path(env ? env : OBJSCAN_DATA_DIR) / "7scenes_300";
}

void row(const char* name, const Timed& t, double reference_fps, const std::string& note) {
  std::printf("  %-44s %6zu %8.2f %9.1f %8.2f  %s\n", name, t.frames, t.seconds, t.fps(),
              reference_fps > 0 ? t.fps() / reference_fps : 0.0, note.c_str());
}

Json timedJson(const Timed& t) {
  return {{"frames", t.frames}, {"seconds", t.seconds}, {"fps", t.fps()}};
}

std::string mb(std::uintmax_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f MB", static_cast<double>(bytes) / 1e6);
  return text;
}

std::string checkNote(std::size_t frames, std::size_t expected, std::size_t mismatches) {
  std::string note =
      frames == expected ? "all frames" : "LOST " + std::to_string(expected - frames);
  note.append(mismatches == 0 ? ", pixels equal" : ", " + std::to_string(mismatches) + " differ");
  return note;
}

int run(int argc, char** argv) {
  fs::path folder = defaultFolder(), keep;
  std::string json_path;
  int runs = 3;
  bool realtime = true;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    const bool has_value = i + 1 < argc;
    if (flag == "--folder" && has_value)
      folder = argv[++i];
    else if (flag == "--runs" && has_value)
      runs = std::max(1, std::atoi(argv[++i]));
    else if (flag == "--json" && has_value)
      json_path = argv[++i];
    else if (flag == "--keep" && has_value)
      keep = argv[++i];
    else if (flag == "--no-realtime")
      realtime = false;
    else {
      std::fprintf(stderr,
                   "usage: capture_bench [--folder DIR] [--runs N] [--json PATH] [--keep DIR] "
                   "[--no-realtime]\n");
      return 2;
    }
  }
  const fs::path work = keep.empty() ? fs::temp_directory_path() /
                                           ("objscan_capture_bench_" + std::to_string(getpid()))
                                     : keep;
  fs::create_directories(work);

  Reference ref;
  std::vector<double> folder_fps, open3d_fps;
  Timed folder_read, open3d_read;
  for (int r = 0; r < runs; ++r) {
    folder_read = readFolder(folder, r == 0 ? &ref : nullptr);
    open3d_read = readFolderOpen3d(folder);
    folder_fps.push_back(folder_read.fps());
    open3d_fps.push_back(open3d_read.fps());
  }
  const std::size_t n = ref.depth_m.size();
  if (n == 0) throw std::runtime_error(folder.string() + " holds no frames");

  const Recording raw = record(folder, work / "raw_color.oni", false);
  const Recording jpeg = record(folder, work / "jpeg_color.oni", true);

  std::vector<double> replay_fps, replay_jpeg_fps;
  ObjscanReplay replay, replay_jpeg;
  for (int r = 0; r < runs; ++r) {
    replay = replayObjscan(raw.file, ref, true, 0);
    replay_jpeg = replayObjscan(jpeg.file, ref, false, 0);
    replay_fps.push_back(replay.timed.fps());
    replay_jpeg_fps.push_back(replay_jpeg.timed.fps());
  }
  const ObjscanReplay replay_slow = replayObjscan(raw.file, ref, true, 20);
  const PclReplay pcl_fast = replayPcl(raw.file, 0.0, 0, ref);
  const PclReplay pcl_fast_slow = replayPcl(raw.file, 0.0, 20, ref);
  std::optional<PclReplay> pcl_realtime;
  if (realtime) pcl_realtime = replayPcl(raw.file, 1.0, 0, ref);

  // Medians across runs for the repeated measurements; the table shows the median run's rate.
  const auto at = [](Timed t, double fps) {
    t.seconds = fps > 0 ? static_cast<double>(t.frames) / fps : 0.0;
    return t;
  };
  const double replay_median = median(replay_fps);
  std::printf(
      "capture: %s, %zu frames %dx%d; median of %d runs where repeated, one consumer thread\n",
      folder.string().c_str(), n, ref.depth_m[0].cols, ref.depth_m[0].rows, runs);
  std::printf("  %-44s %6s %8s %9s %8s  %s\n", "", "frames", "s", "frames/s", "x replay", "check");
  std::printf(" replay of the recorded .oni (%s, raw colour)\n", mb(raw.bytes).c_str());
  row("objscan openOniFile", at(replay.timed, replay_median), replay_median,
      checkNote(replay.timed.frames, n, replay.depth_mismatches + replay.color_mismatches));
  row("objscan openOniFile, JPEG-colour .oni", at(replay_jpeg.timed, median(replay_jpeg_fps)),
      replay_median,
      checkNote(replay_jpeg.timed.frames, n, replay_jpeg.depth_mismatches) + " (depth)");
  row("PCL OpenNI2Grabber, fastest speed", pcl_fast.timed, replay_median,
      checkNote(pcl_fast.timed.frames, n, pcl_fast.depth_mismatches));
  if (pcl_realtime)
    row("PCL OpenNI2Grabber, default (real time)", pcl_realtime->timed, replay_median,
        checkNote(pcl_realtime->timed.frames, n, pcl_realtime->depth_mismatches));
  std::printf(" replay with a consumer taking 20 ms per frame\n");
  row("objscan openOniFile", replay_slow.timed, replay_median,
      checkNote(replay_slow.timed.frames, n,
                replay_slow.depth_mismatches + replay_slow.color_mismatches));
  row("PCL OpenNI2Grabber, fastest speed", pcl_fast_slow.timed, replay_median,
      checkNote(pcl_fast_slow.timed.frames, n, pcl_fast_slow.depth_mismatches));
  std::printf(" reading the dataset folder (PNG depth + JPEG colour)\n");
  row("objscan folder source", at(folder_read, median(folder_fps)), replay_median, "");
  row("Open3D CreateImageFromFile", at(open3d_read, median(open3d_fps)), replay_median, "");
  std::printf(" recording the folder through the virtual sensor (fps=1000) to .oni\n");
  const auto recordRow = [&](const char* name, const Recording& r) {
    Timed t{r.summary.depth_frames, r.summary.duration_s};
    row(name, t, replay_median,
        std::to_string(r.summary.dropped) + " dropped, " + mb(r.bytes) + ", " +
            std::to_string(r.wall_s).substr(0, 4) + " s with start-up");
  };
  recordRow("objscan record, raw colour", raw);
  recordRow("objscan record --compress-color (JPEG)", jpeg);
  std::printf(
      "replay: %.0f frames/s (target >= 300); %.1fx PCL's fastest grabber, %.1fx reading "
      "the folder with Open3D\n",
      replay_median, replay_median / std::max(pcl_fast.timed.fps(), 1e-9),
      replay_median / std::max(median(open3d_fps), 1e-9));

  if (!json_path.empty()) {
    const auto recordingJson = [](const Recording& r) {
      return Json{{"depth_frames", r.summary.depth_frames},
                  {"color_frames", r.summary.color_frames},
                  {"dropped", r.summary.dropped},
                  {"seconds", r.summary.duration_s},
                  {"fps", r.summary.duration_s > 0
                              ? static_cast<double>(r.summary.depth_frames) / r.summary.duration_s
                              : 0.0},
                  {"wall_seconds", r.wall_s},
                  {"bytes", r.bytes}};
    };
    Json j = {
        {"folder", folder.string()},
        {"frames", n},
        {"runs", runs},
        {"replay",
         {{"objscan_fps_median", replay_median},
          {"objscan_fps_runs", replay_fps},
          {"objscan_jpeg_fps_median", median(replay_jpeg_fps)},
          {"objscan_frames", replay.timed.frames},
          {"objscan_mismatches", replay.depth_mismatches + replay.color_mismatches},
          {"pcl_fastest", timedJson(pcl_fast.timed)},
          {"pcl_realtime", pcl_realtime ? timedJson(pcl_realtime->timed) : Json()}}},
        {"replay_20ms_consumer",
         {{"objscan", timedJson(replay_slow.timed)},
          {"pcl_fastest", timedJson(pcl_fast_slow.timed)}}},
        {"folder_read",
         {{"objscan_fps_median", median(folder_fps)}, {"open3d_fps_median", median(open3d_fps)}}},
        {"record", {{"raw_color", recordingJson(raw)}, {"jpeg_color", recordingJson(jpeg)}}}};
    objscan::writeFileAtomically(json_path, j.dump(2) + "\n");
  }
  if (keep.empty()) fs::remove_all(work);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("capture_bench", run, argc, argv);
}
