// Capture from a Kinect v1 through libfreenect (objscan/capture/freenect.h).
//
// Threading: libfreenect hands frames to callbacks from inside freenect_process_events(), which a
// pump thread of our own calls in a loop (fakenect sleeps in it to keep the dump's pace). The
// callbacks pair each depth frame with the colour frame of the same moment and queue the pair;
// next() takes pairs from the queue on the reader's thread, where the conversion to metres and the
// registration run, so the pump never waits for the reader.

#include <dlfcn.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "freenect_library.h"
#include "objscan/capture/freenect.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"

namespace objscan::capture {
namespace freenect_detail {
namespace {

constexpr char kLibraryName[] = "libfreenect.so.0.5";
constexpr char kPackageHint[] =
    "libfreenect is not installed (Debian: apt-get install libfreenect0.5; fakenect, its replay "
    "library, is in libfreenect-bin)";

template <typename F>
void bind(void* handle, const char* name, F* out, bool required, std::string* missing) {
  *out = reinterpret_cast<F>(dlsym(handle, name));
  if (*out == nullptr && required) *missing += std::string(missing->empty() ? "" : ", ") + name;
}

Library load() {
  Library lib;
  void* handle = dlopen(kLibraryName, RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) throw std::runtime_error(kPackageHint);
  std::string missing;
  bind(handle, "freenect_init", &lib.init, true, &missing);
  bind(handle, "freenect_shutdown", &lib.shutdown, true, &missing);
  bind(handle, "freenect_set_log_callback", &lib.set_log_callback, true, &missing);
  bind(handle, "freenect_set_log_level", &lib.set_log_level, true, &missing);
  bind(handle, "freenect_select_subdevices", &lib.select_subdevices, true, &missing);
  bind(handle, "freenect_num_devices", &lib.num_devices, true, &missing);
  bind(handle, "freenect_open_device", &lib.open_device, true, &missing);
  bind(handle, "freenect_close_device", &lib.close_device, true, &missing);
  bind(handle, "freenect_set_user", &lib.set_user, true, &missing);
  bind(handle, "freenect_get_user", &lib.get_user, true, &missing);
  bind(handle, "freenect_set_depth_callback", &lib.set_depth_callback, true, &missing);
  bind(handle, "freenect_set_video_callback", &lib.set_video_callback, true, &missing);
  bind(handle, "freenect_find_depth_mode", &lib.find_depth_mode, true, &missing);
  bind(handle, "freenect_find_video_mode", &lib.find_video_mode, true, &missing);
  bind(handle, "freenect_set_depth_mode", &lib.set_depth_mode, true, &missing);
  bind(handle, "freenect_set_video_mode", &lib.set_video_mode, true, &missing);
  bind(handle, "freenect_start_depth", &lib.start_depth, true, &missing);
  bind(handle, "freenect_start_video", &lib.start_video, true, &missing);
  bind(handle, "freenect_stop_depth", &lib.stop_depth, true, &missing);
  bind(handle, "freenect_stop_video", &lib.stop_video, true, &missing);
  bind(handle, "freenect_process_events", &lib.process_events, true, &missing);
  bind(handle, "freenect_process_events_timeout", &lib.process_events_timeout, false, &missing);
  bind(handle, "freenect_copy_registration", &lib.copy_registration, false, &missing);
  bind(handle, "freenect_destroy_registration", &lib.destroy_registration, false, &missing);
  bind(handle, "freenect_list_device_attributes", &lib.list_device_attributes, false, &missing);
  bind(handle, "freenect_free_device_attributes", &lib.free_device_attributes, false, &missing);
  Dl_info where{};
  if (dladdr(reinterpret_cast<void*>(lib.init), &where) != 0 && where.dli_fname != nullptr) {
    lib.path = where.dli_fname;
  } else {
    lib.path = kLibraryName;
  }
  if (!missing.empty()) {
    throw std::runtime_error(lib.path + " lacks libfreenect's " + missing +
                             " (not libfreenect 0.5?)");
  }
  lib.replay = dlsym(handle, "sleep_highres") != nullptr ||
               std::filesystem::path(lib.path).parent_path().filename() == "fakenect";
  return lib;
}

/// Bytes of a PGM/PPM file fakenect copies after the header line.
std::size_t payloadBytes(char type) {
  return static_cast<std::size_t>(kWidth) * kHeight * (type == 'd' ? 2 : 3);
}

/// Why fakenect cannot replay this entry, or empty.
std::string checkEntry(const std::filesystem::path& dir, const std::string& line, DumpEntry* e) {
  char type = 0;
  double time_s = 0.0;
  unsigned int ticks = 0;
  int consumed = 0;
  if (std::sscanf(line.c_str(), "%c-%lf-%u-%n", &type, &time_s, &ticks, &consumed) != 3 ||
      consumed == 0 || !std::isfinite(time_s)) {
    return "'" + line + "' is not TYPE-TIME-TIMESTAMP-NAME";
  }
  e->type = type;
  e->time_s = time_s;
  e->ticks = ticks;
  e->file = line;
  std::ifstream in(dir / line, std::ios::binary);
  if (!in) return line + " is missing or unreadable";
  if (type != 'd' && type != 'r') return {};
  std::string header;
  std::getline(in, header);
  if (!in || header.size() < 2 || header[0] != 'P' || header[1] != (type == 'd' ? '5' : '6')) {
    return line + " does not start with a " + (type == 'd' ? "P5 (PGM)" : "P6 (PPM)") +
           " header line";
  }
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::size_t>(in.tellg());
  const std::size_t need = header.size() + 1 + payloadBytes(type);
  if (size < need) {
    return line + " is cut short: " + std::to_string(size) + " of " + std::to_string(need) +
           " bytes";
  }
  return {};
}

}  // namespace

const Library& Library::get() {
  static const Library library = load();  // a failed load throws again at the next call
  return library;
}

DumpIndex readDumpIndex(const std::filesystem::path& dir) {
  const std::filesystem::path index_file = dir / "INDEX.txt";
  std::ifstream in(index_file, std::ios::binary);
  if (!in) throw InputError(index_file, "cannot be read: not a fakenect dump");
  DumpIndex index;
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) {  // fakenect ends the replay at an empty line
      if (in.peek() != std::char_traits<char>::eof()) {
        index.cut_short = "INDEX.txt line " + std::to_string(number) + " is empty";
      }
      break;
    }
    DumpEntry entry;
    const std::string problem = checkEntry(dir, line, &entry);
    if (!problem.empty()) {
      index.cut_short = "INDEX.txt line " + std::to_string(number) + ": " + problem;
      break;
    }
    if (entry.type == 'd') ++index.depth_frames;
    index.entries.push_back(std::move(entry));
  }
  return index;
}

}  // namespace freenect_detail

using namespace freenect_detail;

bool isFreenectSource(const std::string& spec) {
  return spec == "freenect" || spec.rfind("freenect:", 0) == 0;
}

int freenectIndex(const std::string& spec) {
  if (spec == "freenect") return 0;
  if (!isFreenectSource(spec)) throw std::invalid_argument(spec + ": not a freenect source");
  const std::string number = spec.substr(std::strlen("freenect:"));
  char* end = nullptr;
  const long index = number.empty() ? -1 : std::strtol(number.c_str(), &end, 10);
  if (number.empty() || end == nullptr || *end != '\0' || index < 0 || index > 255 ||
      !std::isdigit(static_cast<unsigned char>(number[0]))) {
    throw std::invalid_argument(spec + ": the device index after 'freenect:' must be 0 to 255");
  }
  return static_cast<int>(index);
}

// --- The camera model ---------------------------------------------------------------------------

KinectModel KinectModel::nominal(const Intrinsics& color) {
  KinectModel m;
  m.ir = Intrinsics{580.0, 580.0, 319.5, 239.5, freenect_detail::kWidth, freenect_detail::kHeight};
  m.color = color;
  m.color_x_m = 0.025;
  m.projector_baseline_m = 0.075;
  m.disparity_offset = 1090.0;
  return m;
}

float KinectModel::metresFromRaw(std::uint16_t raw) const {
  if (raw >= 2047 || raw >= disparity_offset) return 0.0f;
  return static_cast<float>(8.0 * projector_baseline_m * ir.fx_px / (disparity_offset - raw));
}

std::uint16_t KinectModel::rawFromMetres(float z_m) const {
  if (!(z_m > 0.0f) || !std::isfinite(z_m)) return 2047;
  const double raw = disparity_offset - 8.0 * projector_baseline_m * ir.fx_px / z_m;
  if (raw < -0.5) return 2047;
  return static_cast<std::uint16_t>(std::min(2046.0, std::max(0.0, std::round(raw))));
}

namespace {

/// Forward warp of a depth image between two parallel cameras `dx_m` apart along x (a point
/// (x, y, z) in `from` is (x - dx_m, y, z) in `to`), nearest reading per pixel, then one-pixel
/// gaps between agreeing neighbours filled.
cv::Mat warpDepth(const cv::Mat& depth, const Intrinsics& from, const Intrinsics& to, double dx_m) {
  CV_Assert(depth.type() == CV_32FC1);
  cv::Mat out(to.height_px, to.width_px, CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < depth.rows; ++v) {
    const float* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const float z = row[u];
      if (!(z > 0.0f) || !std::isfinite(z)) continue;
      const double x = (u - from.cx_px) / from.fx_px * z - dx_m;
      const double y = (v - from.cy_px) / from.fy_px * z;
      const long ut = std::lround(to.fx_px * x / z + to.cx_px);
      const long vt = std::lround(to.fy_px * y / z + to.cy_px);
      if (ut < 0 || vt < 0 || ut >= to.width_px || vt >= to.height_px) continue;
      float& target = out.at<float>(static_cast<int>(vt), static_cast<int>(ut));
      if (target == 0.0f || z < target) target = z;
    }
  }
  const auto agree = [](float a, float b) {
    return a > 0.0f && b > 0.0f && std::abs(a - b) <= 0.03f * std::min(a, b);
  };
  cv::Mat filled = out.clone();
  for (int v = 1; v + 1 < out.rows; ++v) {
    for (int u = 1; u + 1 < out.cols; ++u) {
      if (out.at<float>(v, u) != 0.0f) continue;
      const float l = out.at<float>(v, u - 1), r = out.at<float>(v, u + 1);
      const float t = out.at<float>(v - 1, u), b = out.at<float>(v + 1, u);
      if (agree(l, r)) {
        filled.at<float>(v, u) = 0.5f * (l + r);
      } else if (agree(t, b)) {
        filled.at<float>(v, u) = 0.5f * (t + b);
      }
    }
  }
  return filled;
}

}  // namespace

cv::Mat KinectModel::registerToColor(const cv::Mat& ir_depth_m) const {
  return warpDepth(ir_depth_m, ir, color, color_x_m);
}

cv::Mat KinectModel::colorToIr(const cv::Mat& color_depth_m) const {
  return warpDepth(color_depth_m, color, ir, -color_x_m);
}

// --- Devices -------------------------------------------------------------------------------------

namespace {

void logFromLibrary(freenect_context*, freenect_loglevel level, const char* message) {
  std::string text = message == nullptr ? "" : message;
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  if (text.empty()) return;
  if (level <= FREENECT_LOG_ERROR) {
    log::warning("libfreenect: " + text);
  } else if (level <= FREENECT_LOG_WARNING) {
    log::debug("libfreenect: " + text);
  }
}

/// A libfreenect context, shut down when it goes.
class Context {
 public:
  explicit Context(const Library& lib) : lib_(lib) {
    if (lib_.init(&ctx_, nullptr) < 0 || ctx_ == nullptr) {
      throw std::runtime_error("libfreenect could not start (libusb failed to initialise)");
    }
    lib_.set_log_callback(ctx_, logFromLibrary);
    lib_.set_log_level(ctx_, FREENECT_LOG_WARNING);
    // The camera only: the motor and audio parts need firmware uploads and are not used.
    lib_.select_subdevices(ctx_, FREENECT_DEVICE_CAMERA);
  }
  ~Context() { lib_.shutdown(ctx_); }
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  freenect_context* get() const { return ctx_; }

 private:
  const Library& lib_;
  freenect_context* ctx_ = nullptr;
};

/// Where fakenect replays from; throws InputError when it is not set.
std::filesystem::path dumpFolder() {
  const char* path = std::getenv("FAKENECT_PATH");
  if (path == nullptr || *path == '\0') {
    throw InputError("FAKENECT_PATH",
                     "is not set: the fakenect library replays the dump that variable names "
                     "(run objscan through `fakenect DUMP objscan ...`)");
  }
  return path;
}

std::vector<std::string> serials(const Library& lib, freenect_context* ctx) {
  std::vector<std::string> out;
  if (lib.list_device_attributes == nullptr) return out;
  freenect_device_attributes* list = nullptr;
  if (lib.list_device_attributes(ctx, &list) < 0) return out;
  for (freenect_device_attributes* a = list; a != nullptr; a = a->next) {
    out.emplace_back(a->camera_serial == nullptr ? "" : a->camera_serial);
  }
  if (lib.free_device_attributes != nullptr) lib.free_device_attributes(list);
  return out;
}

}  // namespace

std::vector<FreenectDevice> listFreenectDevices(std::string* why) {
  std::vector<FreenectDevice> devices;
  const Library* lib = nullptr;
  try {
    lib = &Library::get();
  } catch (const std::exception& e) {
    if (why != nullptr) *why = e.what();
    return devices;
  }
  if (lib->replay) {
    // fakenect always claims one device; it is a dump only when one is named.
    const char* dump = std::getenv("FAKENECT_PATH");
    if (dump == nullptr || *dump == '\0') {
      if (why != nullptr) *why = "fakenect is loaded but FAKENECT_PATH names no dump";
      return devices;
    }
    devices.push_back({"freenect:0", std::string("dump ") + dump, lib->path, true});
    return devices;
  }
  std::unique_ptr<Context> ctx;
  try {
    ctx = std::make_unique<Context>(*lib);
  } catch (const std::exception& e) {
    if (why != nullptr) *why = e.what();
    return devices;
  }
  const int count = lib->num_devices(ctx->get());
  const std::vector<std::string> numbers = serials(*lib, ctx->get());
  for (int i = 0; i < count; ++i) {
    devices.push_back({"freenect:" + std::to_string(i),
                       i < static_cast<int>(numbers.size()) ? numbers[static_cast<std::size_t>(i)]
                                                            : std::string(),
                       lib->path, false});
  }
  if (devices.empty() && why != nullptr) *why = "libfreenect finds no Kinect";
  return devices;
}

std::optional<Trajectory> freenectGroundTruth() {
  try {
    if (!Library::get().replay) return std::nullopt;
    const std::filesystem::path file = dumpFolder() / "groundtruth.txt";
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) return std::nullopt;
    return readTumTrajectory(file);
  } catch (const std::runtime_error&) {
    return std::nullopt;  // not installed, no dump: opening the source says why
  }
}

// --- The source ----------------------------------------------------------------------------------

namespace {

constexpr std::size_t kQueueFrames = 8;
constexpr auto kStallTimeout = std::chrono::seconds(3);
constexpr double kPairToleranceTicks = kTicksPerSecond / 60.0;  // half a frame

/// A 32-bit device clock made monotonic.
class Unwrapped {
 public:
  std::int64_t operator()(std::uint32_t ticks) {
    if (!started_) {
      started_ = true;
      value_ = ticks;
    } else {
      value_ += static_cast<std::int32_t>(ticks - last_);
    }
    last_ = ticks;
    return value_;
  }

 private:
  bool started_ = false;
  std::uint32_t last_ = 0;
  std::int64_t value_ = 0;
};

struct RawPair {
  cv::Mat depth;  ///< CV_16UC1: raw 11-bit, or millimetres when registered by the library
  cv::Mat color;  ///< CV_8UC3 RGB, or empty
  std::int64_t ticks = 0;
};

class FreenectSource final : public FrameSource {
 public:
  FreenectSource(const std::string& spec, const std::optional<Intrinsics>& intrinsics_override,
                 const std::string& intrinsics_origin)
      : lib_(Library::get()), spec_(spec), index_(freenectIndex(spec)) {
    info_.live = true;
    std::optional<Intrinsics> dump_intrinsics;
    if (lib_.replay) {
      const std::filesystem::path dump = dumpFolder();
      DumpIndex index = readDumpIndex(dump);
      if (index.depth_frames == 0) {
        throw InputError(
            dump, "holds no depth frame fakenect can replay" +
                      (index.cut_short.empty() ? std::string() : " (" + index.cut_short + ")"));
      }
      if (!index.cut_short.empty()) {
        log::warning(dump.string() + ": the dump is cut short at " + index.cut_short +
                     "; replaying the " + std::to_string(index.depth_frames) +
                     " depth frames before it");
      }
      entries_ = index.entries.size();
      info_.frame_count = index.depth_frames;
      if (index_ != 0) throw InputError(spec, "fakenect replays one device, freenect:0");
      std::error_code ec;
      if (std::filesystem::exists(dump / "intrinsics.json", ec)) {
        dump_intrinsics = readIntrinsicsJson(dump / "intrinsics.json");
      }
      if (std::filesystem::exists(dump / "groundtruth.txt", ec)) {
        info_.ground_truth = readTumTrajectory(dump / "groundtruth.txt");
      }
      dump_ = dump;
    }

    ctx_ = std::make_unique<Context>(lib_);
    if (!lib_.replay) {
      const int count = lib_.num_devices(ctx_->get());
      if (count <= 0) {
        throw NoSensorError(
            "no Kinect found by libfreenect (is it plugged in, powered by its own adapter, and "
            "may this user open its USB device?)");
      }
      if (index_ >= count) {
        throw InputError(spec,
                         "libfreenect finds " + std::to_string(count) +
                             " Kinect(s): use freenect:0 to freenect:" + std::to_string(count - 1));
      }
    }
    const int opened = lib_.open_device(ctx_->get(), &dev_, index_);
    if (opened < 0 || dev_ == nullptr) {
      throw std::runtime_error(
          spec + ": libfreenect cannot open the Kinect (error " + std::to_string(opened) +
          "): it is busy in another program, or this user may not open its USB device");
    }

    try {
      configure(intrinsics_override, intrinsics_origin, dump_intrinsics);
    } catch (...) {
      closeDevice();
      throw;
    }
    pump_ = std::thread([this] { pump(); });
  }

  ~FreenectSource() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      quit_ = true;
      taken_.notify_all();
    }
    if (pump_.joinable()) pump_.join();
    closeDevice();
  }

  FreenectSource(const FreenectSource&) = delete;
  FreenectSource& operator=(const FreenectSource&) = delete;

  const SourceInfo& info() const override { return info_; }

 private:
  /// Camera model, intrinsics, modes and callbacks of the opened device; starts its streams.
  void configure(const std::optional<Intrinsics>& intrinsics_override,
                 const std::string& intrinsics_origin,
                 const std::optional<Intrinsics>& dump_intrinsics) {
    // Registered millimetres from the library where it has the device's calibration.
    model_ = KinectModel::nominal(
        intrinsics_override.value_or(dump_intrinsics.value_or(Intrinsics::xtionDefault())));
    if (lib_.copy_registration != nullptr && !lib_.replay) {
      freenect_registration reg = lib_.copy_registration(dev_);
      const double ref_distance = reg.zero_plane_info.reference_distance;
      const double ref_pixel = reg.zero_plane_info.reference_pixel_size;
      if (ref_distance > 0.0 && ref_pixel > 0.0) {
        // The zero plane's pixels are of the 1280x1024 sensor, halved for 640x480.
        const double f = ref_distance / (2.0 * ref_pixel);
        device_intrinsics_ = Intrinsics{f, f, kWidth / 2.0, kHeight / 2.0, kWidth, kHeight};
        registered_by_library_ = true;
      }
      if (lib_.destroy_registration != nullptr) lib_.destroy_registration(&reg);
    }
    if (intrinsics_override) {
      info_.intrinsics = *intrinsics_override;
      info_.intrinsics_origin = intrinsics_origin.empty() ? "given" : intrinsics_origin;
    } else if (dump_intrinsics) {
      info_.intrinsics = *dump_intrinsics;
      info_.intrinsics_origin = "the dump's intrinsics.json";
    } else if (device_intrinsics_) {
      info_.intrinsics = *device_intrinsics_;
      info_.intrinsics_origin = "the Kinect's registration data";
    } else {
      info_.intrinsics = model_.color;
      info_.intrinsics_origin = "Kinect v1 nominal camera (the library gives no calibration)";
      info_.intrinsics_assumed = true;
    }
    model_.color = info_.intrinsics;
    info_.intrinsics.validate();
    if (info_.intrinsics.width_px != kWidth || info_.intrinsics.height_px != kHeight) {
      throw InputError(spec_, "the intrinsics are for " +
                                  std::to_string(info_.intrinsics.width_px) + "x" +
                                  std::to_string(info_.intrinsics.height_px) +
                                  " images; the Kinect's are 640x480");
    }
    info_.depth_units = registered_by_library_
                            ? "libfreenect's registered millimetres"
                            : "11-bit disparity, converted and registered by objscan";
    info_.description = (lib_.replay ? "fakenect dump " + dump_.string() + " (" + spec_ + ", " +
                                           std::to_string(*info_.frame_count) + " frames)"
                                     : "Kinect v1 " + spec_ + " (libfreenect)");

    const freenect_frame_mode depth_mode = lib_.find_depth_mode(
        FREENECT_RESOLUTION_MEDIUM,
        registered_by_library_ ? FREENECT_DEPTH_REGISTERED : FREENECT_DEPTH_11BIT);
    const freenect_frame_mode video_mode =
        lib_.find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
    if (!depth_mode.is_valid || !video_mode.is_valid || lib_.set_depth_mode(dev_, depth_mode) < 0 ||
        lib_.set_video_mode(dev_, video_mode) < 0) {
      throw std::runtime_error(spec_ + ": the Kinect refuses 640x480 depth and RGB");
    }
    lib_.set_user(dev_, this);
    lib_.set_depth_callback(dev_, &FreenectSource::onDepth);
    lib_.set_video_callback(dev_, &FreenectSource::onVideo);
    if (lib_.start_depth(dev_) < 0 || lib_.start_video(dev_) < 0) {
      throw std::runtime_error(spec_ + ": the Kinect's streams cannot be started");
    }
  }

 public:
  FrameResult next() override {
    RawPair pair;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      const bool ready = arrived_.wait_for(
          lock, kStallTimeout, [&] { return !queue_.empty() || ended_ || !error_.empty(); });
      if (queue_.empty()) {
        if (!error_.empty()) throw std::runtime_error(error_);
        if (ended_) return FrameResult::end();
        (void)ready;
        throw std::runtime_error("Kinect " + spec_ + " stopped delivering frames after " +
                                 std::to_string(delivered_.load()) + " frames (unplugged?)");
      }
      pair = std::move(queue_.front());
      queue_.pop_front();
      taken_.notify_all();
    }
    RgbdFrame frame;
    frame.index = static_cast<std::int64_t>(delivered_++);
    if (first_ticks_ < 0) first_ticks_ = pair.ticks;
    frame.device_frame =
        std::llround(static_cast<double>(pair.ticks - first_ticks_) / kTicksPerFrame);
    frame.stamp_s = static_cast<double>(pair.ticks) / kTicksPerSecond;
    cv::Mat metres(kHeight, kWidth, CV_32FC1);
    for (int v = 0; v < kHeight; ++v) {
      const std::uint16_t* in = pair.depth.ptr<std::uint16_t>(v);
      float* out = metres.ptr<float>(v);
      for (int u = 0; u < kWidth; ++u) {
        out[u] = registered_by_library_ ? static_cast<float>(in[u]) * 1e-3f
                                        : model_.metresFromRaw(in[u]);
      }
    }
    frame.depth_m = registered_by_library_ ? metres : model_.registerToColor(metres);
    frame.color_rgb = std::move(pair.color);
    frame.intrinsics = info_.intrinsics;
    return FrameResult::ok(std::move(frame));
  }

 private:
  static void onDepth(freenect_device* dev, void* data, std::uint32_t ticks) {
    auto* self = static_cast<FreenectSource*>(Library::get().get_user(dev));
    if (self != nullptr) self->depthArrived(data, ticks);
  }
  static void onVideo(freenect_device* dev, void* data, std::uint32_t ticks) {
    auto* self = static_cast<FreenectSource*>(Library::get().get_user(dev));
    if (self != nullptr) self->videoArrived(data, ticks);
  }

  // Both run on the pump thread.
  void depthArrived(const void* data, std::uint32_t ticks) {
    pending_depth_ = cv::Mat(kHeight, kWidth, CV_16UC1);
    std::memcpy(pending_depth_.data, data, pending_depth_.total() * pending_depth_.elemSize());
    pending_depth_ticks_ = depth_clock_(ticks);
    if (!last_color_.empty() && near(last_color_ticks_, pending_depth_ticks_)) pushPair();
  }

  void videoArrived(const void* data, std::uint32_t ticks) {
    last_color_ = cv::Mat(kHeight, kWidth, CV_8UC3);
    std::memcpy(last_color_.data, data, last_color_.total() * last_color_.elemSize());
    last_color_ticks_ = color_clock_(ticks);
    if (!pending_depth_.empty() && near(last_color_ticks_, pending_depth_ticks_)) pushPair();
  }

  static bool near(std::int64_t a, std::int64_t b) {
    return static_cast<double>(std::abs(a - b)) <= kPairToleranceTicks;
  }

  void pushPair() {
    RawPair pair{std::move(pending_depth_), last_color_, pending_depth_ticks_};
    pending_depth_ = cv::Mat();
    std::unique_lock<std::mutex> lock(mutex_);
    if (lib_.replay) {
      // A dump is replayed whole: fakenect waits for the reader (and shortens its next pause).
      taken_.wait(lock, [&] { return queue_.size() < kQueueFrames || quit_; });
      if (quit_) return;
    }
    queue_.push_back(std::move(pair));
    if (queue_.size() > kQueueFrames) queue_.pop_front();  // a Kinect: the oldest goes
    arrived_.notify_all();
  }

  void pump() {
    std::size_t done = 0;
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (quit_) return;
      }
      if (lib_.replay && done >= entries_) break;
      int status = 0;
      if (lib_.process_events_timeout != nullptr) {
        timeval timeout{0, 100000};
        status = lib_.process_events_timeout(ctx_->get(), &timeout);
      } else {
        status = lib_.process_events(ctx_->get());
      }
      ++done;
      if (status < 0 && !lib_.replay) {
        std::lock_guard<std::mutex> lock(mutex_);
        error_ = "Kinect " + spec_ + ": libfreenect reported a USB error (" +
                 std::to_string(status) + ") after " + std::to_string(delivered_.load()) +
                 " frames";
        arrived_.notify_all();
        return;
      }
    }
    // The end of a dump: a depth frame still waiting for its colour goes out without it.
    if (!pending_depth_.empty()) {
      last_color_ = cv::Mat();
      pushPair();
    }
    std::lock_guard<std::mutex> lock(mutex_);
    ended_ = true;
    arrived_.notify_all();
  }

  void closeDevice() {
    if (dev_ == nullptr) return;
    lib_.stop_depth(dev_);
    lib_.stop_video(dev_);
    lib_.set_user(dev_, nullptr);
    lib_.close_device(dev_);
    dev_ = nullptr;
  }

  const Library& lib_;
  std::string spec_;
  int index_ = 0;
  SourceInfo info_;
  std::filesystem::path dump_;
  std::size_t entries_ = 0;  ///< fakenect: index entries to replay
  KinectModel model_;
  std::optional<Intrinsics> device_intrinsics_;
  bool registered_by_library_ = false;
  std::unique_ptr<Context> ctx_;
  freenect_device* dev_ = nullptr;

  // Pump thread only.
  cv::Mat pending_depth_;
  std::int64_t pending_depth_ticks_ = 0;
  cv::Mat last_color_;
  std::int64_t last_color_ticks_ = 0;
  Unwrapped depth_clock_, color_clock_;

  // Shared, under mutex_.
  std::mutex mutex_;
  std::condition_variable arrived_;
  std::condition_variable taken_;  ///< the reader took a frame (a dump's pump waits for room)
  std::deque<RawPair> queue_;
  bool quit_ = false;
  bool ended_ = false;
  std::string error_;

  // Reader only.
  std::atomic<std::size_t> delivered_{0};
  std::int64_t first_ticks_ = -1;

  std::thread pump_;  ///< last: started once everything above exists
};

}  // namespace

std::unique_ptr<FrameSource> openFreenect(const std::string& spec,
                                          const std::optional<Intrinsics>& intrinsics_override,
                                          const std::string& intrinsics_origin) {
  try {
    (void)freenectIndex(spec);
  } catch (const std::invalid_argument&) {
    throw InputError(spec, "the device index after 'freenect:' must be 0 to 255");
  }
  return std::make_unique<FreenectSource>(spec, intrinsics_override, intrinsics_origin);
}

}  // namespace objscan::capture
