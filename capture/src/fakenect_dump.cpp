// Writing fakenect dumps (objscan/capture/freenect.h), the format libfreenect's fakenect-record
// writes and its fakenect library replays: a folder with INDEX.txt, one line per file in replay
// order, each file named TYPE-TIME-TIMESTAMP-NAME, where TIME is the recording's wall clock in
// seconds (fakenect sleeps to keep its pace) and TIMESTAMP the device's 60 MHz clock (handed to the
// program's callbacks). Depth files are PGMs of 640x480 raw 11-bit values in host byte order after
// a one-line header, RGB files PPMs; fakenect copies the bytes after the header line.

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

#include "freenect_library.h"
#include "objscan/capture/freenect.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan::capture {
namespace {

using freenect_detail::kHeight;
using freenect_detail::kTicksPerSecond;
using freenect_detail::kWidth;

/// The first device time stamp: ten 30 Hz frames before the 32-bit clock wraps, so that every dump
/// of more than ten frames has the wrap a Kinect's clock makes every 71.6 s.
constexpr std::uint64_t kFirstTicks = (std::uint64_t{1} << 32) - 10 * 2'000'000;

void writeFile(const std::filesystem::path& path, const std::string& header, const void* data,
               std::size_t bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
  out.close();
  if (!out) throw OutputError(path, "cannot be written");
}

}  // namespace

FakenectDumpSummary writeFakenectDump(FrameSource& source, const std::filesystem::path& dir,
                                      const FakenectDumpOptions& options) {
  namespace fs = std::filesystem;
  if (!(options.slow_down > 0.0) || !std::isfinite(options.slow_down)) {
    throw std::invalid_argument("slow_down must be a positive number");
  }
  const SourceInfo& info = source.info();
  if (info.intrinsics.width_px != kWidth || info.intrinsics.height_px != kHeight) {
    throw InputError(info.description, "a Kinect dump holds 640x480 frames");
  }
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_empty(dir, ec)) {
    throw OutputError(dir, "exists and is not empty: a dump goes into a new folder");
  }
  fs::create_directories(dir, ec);
  if (ec) throw OutputError(dir, "cannot be created: " + ec.message());
  const KinectModel model = KinectModel::nominal(info.intrinsics);
  writeIntrinsicsJson(dir / "intrinsics.json", info.intrinsics);

  std::string index;
  Trajectory truth;
  FakenectDumpSummary summary;
  std::optional<double> first_stamp;
  std::vector<std::uint16_t> raw(static_cast<std::size_t>(kWidth) * kHeight);
  char name[128];
  for (std::size_t i = 0;; ++i) {
    if (options.max_frames && summary.frames >= *options.max_frames) break;
    FrameResult r = source.next();
    if (r.status == FrameStatus::kEndOfStream) break;
    if (r.status == FrameStatus::kBadFrame) continue;
    const RgbdFrame& frame = r.frame;
    if (!first_stamp) first_stamp = frame.stamp_s;
    if (std::find(options.drop.begin(), options.drop.end(), i) != options.drop.end()) continue;
    if (frame.depth_m.cols != kWidth || frame.depth_m.rows != kHeight) {
      throw InputError(info.description, "frame " + std::to_string(i) + " is not 640x480");
    }
    const double since_s = frame.stamp_s - *first_stamp;
    const std::uint64_t ticks =
        kFirstTicks +
        static_cast<std::uint64_t>(std::llround(std::max(0.0, since_s) * kTicksPerSecond));
    const auto device_ticks = static_cast<std::uint32_t>(ticks);  // wraps as the Kinect's does
    const double time_s = 1000.0 + since_s * options.slow_down;

    if (!frame.color_rgb.empty()) {
      const cv::Mat rgb =
          frame.color_rgb.isContinuous() ? frame.color_rgb : frame.color_rgb.clone();
      std::snprintf(name, sizeof(name), "r-%.6f-%" PRIu32 "-%06zu.ppm", time_s, device_ticks, i);
      writeFile(dir / name, "P6 640 480 255\n", rgb.data, rgb.total() * rgb.elemSize());
      index += name;
      index += '\n';
    }
    const cv::Mat ir = model.colorToIr(frame.depth_m);
    for (int v = 0; v < kHeight; ++v) {
      const float* row = ir.ptr<float>(v);
      for (int u = 0; u < kWidth; ++u) {
        raw[static_cast<std::size_t>(v) * kWidth + static_cast<std::size_t>(u)] =
            model.rawFromMetres(row[u]);
      }
    }
    std::snprintf(name, sizeof(name), "d-%.6f-%" PRIu32 "-%06zu.pgm", time_s, device_ticks, i);
    writeFile(dir / name, "P5 640 480 65535\n", raw.data(), raw.size() * sizeof(raw[0]));
    index += name;
    index += '\n';
    ++summary.frames;

    if (info.ground_truth) {
      if (const std::optional<Pose> pose = nearestPose(*info.ground_truth, frame.stamp_s, 0.02)) {
        truth.poses.push_back({static_cast<double>(ticks) / kTicksPerSecond, *pose});
      }
    }
  }
  if (summary.frames == 0) throw InputError(info.description, "gave no frame to write");
  if (!truth.empty()) {
    writeTumTrajectory(dir / "groundtruth.txt", truth);
    summary.ground_truth = true;
  }
  writeFileAtomically(dir / "INDEX.txt", index);
  return summary;
}

}  // namespace objscan::capture
