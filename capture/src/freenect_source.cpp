// Capture from a Kinect v1 through libfreenect (objscan/capture/freenect.h).
//
// Threading: libfreenect hands frames to callbacks from inside freenect_process_events(), which a
// pump thread of our own calls in a loop (fakenect sleeps in it to keep the dump's pace). The
// callbacks pair each depth frame with the colour frame of the same moment and queue the pair;
// next() takes pairs from the queue on the reader's thread, where the conversion to metres and the
// registration run. A Kinect's pump never waits for the reader (a full queue loses its oldest
// pair); a dump's does (a dump replays whole). The pump shares the device with the source
// (Session), so a pump asleep in fakenect through a long pause need not be waited for.

#include <dlfcn.h>

#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
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

/// `text` for a message: control characters shown as '?', at most 120 characters.
std::string shown(const std::string& text) {
  std::string out;
  for (const char c : text.substr(0, 120)) {
    out += static_cast<unsigned char>(c) < 0x20 || c == 0x7f ? '?' : c;
  }
  return text.size() > 120 ? out + "..." : out;
}

/// fakenect reads a file's size into an int.
constexpr std::uintmax_t kMaxFileBytes = 0x7fffffff;

/// Why fakenect cannot replay this entry safely, or empty. fakenect exits the process on a file it
/// cannot open, copies a whole image from after the header line however short the file, and
/// prints to stdout on a tilt record of the wrong size, so each file is checked: a regular file
/// (a FIFO would block), under 2 GiB, and for images a header line and a whole image after it.
std::string checkEntry(const std::filesystem::path& dir, const std::string& line, DumpEntry* e) {
  namespace fs = std::filesystem;
  char type = 0;
  double time_s = 0.0;
  unsigned int ticks = 0;
  int consumed = 0;
  if (std::sscanf(line.c_str(), "%c-%lf-%u-%n", &type, &time_s, &ticks, &consumed) != 3 ||
      consumed == 0 || !std::isfinite(time_s)) {
    return "'" + shown(line) + "' is not TYPE-TIME-TIMESTAMP-NAME";
  }
  e->type = type;
  e->time_s = time_s;
  e->ticks = ticks;
  e->file = line;
  std::error_code ec;
  const fs::path file = dir / line;
  if (!fs::is_regular_file(file, ec)) return shown(line) + " is missing or not a regular file";
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec) return shown(line) + " cannot be read: " + ec.message();
  if (size > kMaxFileBytes) return shown(line) + " is over 2 GiB, more than fakenect reads";
  if (type == 'a') {
    if (size != sizeof(freenect_raw_tilt_state)) {
      return shown(line) + " holds a tilt state of " + std::to_string(size) + " bytes, not " +
             std::to_string(sizeof(freenect_raw_tilt_state)) + " (from another libfreenect)";
    }
    return {};
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) return shown(line) + " cannot be read";
  if (type != 'd' && type != 'r') return {};  // fakenect reads it and passes over it
  char head[64] = {};
  in.read(head, sizeof(head));
  const std::string header(head, static_cast<std::size_t>(in.gcount()));
  const std::size_t newline = header.find('\n');
  if (newline == std::string::npos || header.size() < 2 || header[0] != 'P' ||
      header[1] != (type == 'd' ? '5' : '6')) {
    return shown(line) + " does not start with a " + (type == 'd' ? "P5 (PGM)" : "P6 (PPM)") +
           " header line";
  }
  const std::uintmax_t need = newline + 1 + payloadBytes(type);
  if (size < need) {
    return shown(line) + " is cut short: " + std::to_string(size) + " of " + std::to_string(need) +
           " bytes";
  }
  return {};
}

}  // namespace

const Library& Library::get() {
  // Never destroyed: a pump left asleep in fakenect may still use it while the process exits. A
  // failed load throws again at the next call.
  static const Library* const library = new Library(load());
  return *library;
}

DumpIndex readDumpIndex(const std::filesystem::path& dir) {
  const std::filesystem::path index_file = dir / "INDEX.txt";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(index_file, ec)) {
    throw InputError(index_file, "is missing or not a regular file: not a fakenect dump");
  }
  std::ifstream in(index_file, std::ios::binary);
  if (!in) throw InputError(index_file, "cannot be read");
  DumpIndex index;
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) {  // fakenect ends the replay at an empty line
      if (in.peek() != std::char_traits<char>::eof()) {
        index.cut_short = "line " + std::to_string(number) + " of INDEX.txt is empty";
      }
      break;
    }
    DumpEntry entry;
    const std::string problem = checkEntry(dir, line, &entry);
    if (!problem.empty()) {
      index.cut_short = "line " + std::to_string(number) + " of INDEX.txt: " + problem;
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
      throw NoSensorError("no Kinect found: libfreenect could not start libusb");
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

namespace {

/// The dump's groundtruth.txt, when it has one.
std::optional<Trajectory> dumpGroundTruth(const std::filesystem::path& dump) {
  const std::filesystem::path file = dump / "groundtruth.txt";
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) return std::nullopt;
  return readTumTrajectory(file);
}

}  // namespace

std::optional<Trajectory> freenectGroundTruth() {
  try {
    if (!Library::get().replay) return std::nullopt;
    return dumpGroundTruth(dumpFolder());
  } catch (const std::runtime_error&) {
    return std::nullopt;  // not installed, no dump: opening the source says why
  }
}

// --- The source ----------------------------------------------------------------------------------

namespace {

constexpr std::size_t kQueueFrames = 8;
constexpr auto kStallTimeout = std::chrono::seconds(3);
/// How long closing waits for the pump to leave libfreenect: fakenect may sleep in it for as
/// long as the dump pauses. After that the pump is left to finish on its own.
constexpr auto kPumpJoinTimeout = std::chrono::seconds(1);
constexpr double kPairToleranceTicks = kTicksPerSecond / 60.0;  // half a frame
constexpr int kLibusbInterrupted = -10;                         // LIBUSB_ERROR_INTERRUPTED

/// The Kinect's 32-bit frame clock made monotonic; depth and colour share it.
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

/// Set once a source has replayed through fakenect, whose state is global to the process and
/// never reset (its place in INDEX.txt, the callbacks, the user pointer).
std::atomic<bool>& fakenectReplayed() {
  static std::atomic<bool> replayed{false};
  return replayed;
}

/// What opening a source checks before the device is opened.
struct Preflight {
  const Library* lib = nullptr;
  int index = 0;
  std::filesystem::path dump;  ///< fakenect's dump, empty for a device
  DumpIndex entries;
  std::optional<Intrinsics> dump_intrinsics;
  std::optional<Trajectory> ground_truth;
};

Preflight preflight(const std::string& spec) {
  Preflight p;
  try {
    p.index = freenectIndex(spec);
  } catch (const std::invalid_argument&) {
    throw InputError(spec, "the device index after 'freenect:' must be 0 to 255");
  }
  p.lib = &Library::get();
  if (p.lib->replay) {
    if (fakenectReplayed().load()) {
      throw InputError(spec,
                       "fakenect replays one dump once per process (it keeps its place in the "
                       "dump for the life of the process): run objscan again for another replay");
    }
    p.dump = dumpFolder();
    p.entries = readDumpIndex(p.dump);
    if (p.entries.depth_frames == 0) {
      throw InputError(
          p.dump,
          "holds no depth frame fakenect can replay" +
              (p.entries.cut_short.empty() ? std::string() : " (" + p.entries.cut_short + ")"));
    }
    if (p.index != 0) throw InputError(spec, "fakenect replays one device, freenect:0");
    std::error_code ec;
    if (std::filesystem::exists(p.dump / "intrinsics.json", ec)) {
      p.dump_intrinsics = readIntrinsicsJson(p.dump / "intrinsics.json");
    }
    p.ground_truth = dumpGroundTruth(p.dump);
    return p;
  }
  const Context ctx(*p.lib);
  const int count = p.lib->num_devices(ctx.get());
  if (count <= 0) {
    throw NoSensorError(
        "no Kinect found by libfreenect (is it plugged in, powered by its own adapter, and may "
        "this user open its USB device?)");
  }
  if (p.index >= count) {
    throw InputError(spec,
                     "libfreenect finds " + std::to_string(count) +
                         " Kinect(s): use freenect:0 to freenect:" + std::to_string(count - 1));
  }
  return p;
}

/// The open device and everything its pump thread touches. Shared by the source and the pump, so
/// that a pump still asleep in fakenect when the source closes can finish later on its own.
class Session {
 public:
  Session(const Library& lib, bool replay, std::size_t entries)
      : lib_(lib), replay_(replay), entries_(entries), ctx_(lib) {}

  ~Session() { close(); }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  const Library& lib() const { return lib_; }
  freenect_context* context() const { return ctx_.get(); }
  freenect_device*& device() { return dev_; }

  void close() {
    if (dev_ == nullptr) return;
    lib_.set_user(dev_, nullptr);  // first: stopping may still hand over a finished transfer
    lib_.stop_depth(dev_);
    lib_.stop_video(dev_);
    lib_.close_device(dev_);
    dev_ = nullptr;
  }

  /// Callbacks on this session from now on; streams started.
  void start() {
    lib_.set_user(dev_, this);
    lib_.set_depth_callback(dev_, &Session::onDepth);
    lib_.set_video_callback(dev_, &Session::onVideo);
    if (lib_.start_depth(dev_) < 0 || lib_.start_video(dev_) < 0) {
      throw std::runtime_error("the Kinect's streams cannot be started");
    }
  }

  /// The pump thread's loop. Ends at quit, a USB error, or the end of a dump.
  void pump() {
    // Ctrl-C and SIGTERM go to the program's own threads, not into libusb's poll.
    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGINT);
    sigaddset(&signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
    std::size_t done = 0;
    for (;;) {
      if (quitting()) break;
      if (replay_ && done >= entries_) {
        // The end of a dump: a depth frame still waiting for its colour goes out without it.
        if (!pending_depth_.empty()) pushPending(false);
        break;
      }
      int status = 0;
      if (lib_.process_events_timeout != nullptr) {
        timeval timeout{0, 100000};
        status = lib_.process_events_timeout(ctx_.get(), &timeout);
      } else {
        status = lib_.process_events(ctx_.get());
      }
      ++done;
      if (status < 0 && status != kLibusbInterrupted && !replay_) {
        std::lock_guard<std::mutex> lock(mutex_);
        error_ = "libfreenect reported a USB error (" + std::to_string(status) + ")";
        break;
      }
    }
    std::lock_guard<std::mutex> lock(mutex_);
    ended_ = true;
    arrived_.notify_all();
  }

  /// The next pair, waiting up to the stall timeout. nullopt at the end of a dump; throws
  /// std::runtime_error with `what` when nothing came, the library's error after a USB error.
  std::optional<RawPair> take(const std::string& stalled) {
    std::unique_lock<std::mutex> lock(mutex_);
    arrived_.wait_for(lock, kStallTimeout,
                      [&] { return !queue_.empty() || ended_ || !error_.empty(); });
    if (queue_.empty()) {
      if (!error_.empty()) throw std::runtime_error(error_);
      if (ended_) return std::nullopt;
      throw std::runtime_error(stalled);
    }
    RawPair pair = std::move(queue_.front());
    queue_.pop_front();
    taken_.notify_all();
    return pair;
  }

  /// Tells the pump to stop; true when it has (within kPumpJoinTimeout).
  bool stop() {
    std::unique_lock<std::mutex> lock(mutex_);
    quit_ = true;
    taken_.notify_all();
    return arrived_.wait_for(lock, kPumpJoinTimeout, [&] { return ended_; });
  }

  std::size_t withoutColor() const { return without_color_.load(); }

 private:
  static Session* of(freenect_device* dev) {
    return static_cast<Session*>(Library::get().get_user(dev));
  }
  static void onDepth(freenect_device* dev, void* data, std::uint32_t ticks) {
    if (Session* self = of(dev)) self->guarded([&] { self->depthArrived(data, ticks); });
  }
  static void onVideo(freenect_device* dev, void* data, std::uint32_t ticks) {
    if (Session* self = of(dev)) self->guarded([&] { self->videoArrived(data, ticks); });
  }

  /// Nothing is thrown back through libfreenect's C frames.
  template <typename F>
  void guarded(F&& f) {
    try {
      f();
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (error_.empty()) error_ = std::string("a frame could not be taken: ") + e.what();
      arrived_.notify_all();
    }
  }

  bool quitting() {
    std::lock_guard<std::mutex> lock(mutex_);
    return quit_;
  }

  // On the pump thread.
  void depthArrived(const void* data, std::uint32_t ticks) {
    // The depth frame before this one found no colour frame: it goes out without one.
    if (!pending_depth_.empty()) pushPending(false);
    pending_depth_ = cv::Mat(kHeight, kWidth, CV_16UC1);
    std::memcpy(pending_depth_.data, data, pending_depth_.total() * pending_depth_.elemSize());
    pending_ticks_ = clock_(ticks);
    if (!last_color_.empty() && near(last_color_ticks_, pending_ticks_)) pushPending(true);
  }

  void videoArrived(const void* data, std::uint32_t ticks) {
    last_color_ = cv::Mat(kHeight, kWidth, CV_8UC3);
    std::memcpy(last_color_.data, data, last_color_.total() * last_color_.elemSize());
    last_color_ticks_ = clock_(ticks);
    if (!pending_depth_.empty() && near(last_color_ticks_, pending_ticks_)) pushPending(true);
  }

  static bool near(std::int64_t a, std::int64_t b) {
    return static_cast<double>(std::abs(a - b)) <= kPairToleranceTicks;
  }

  void pushPending(bool with_color) {
    RawPair pair{std::move(pending_depth_), with_color ? last_color_ : cv::Mat(), pending_ticks_};
    pending_depth_ = cv::Mat();
    if (!with_color) ++without_color_;
    std::unique_lock<std::mutex> lock(mutex_);
    if (replay_) {
      // A dump is replayed whole: fakenect waits for the reader (the replay takes that long more).
      taken_.wait(lock, [&] { return queue_.size() < kQueueFrames || quit_; });
      if (quit_) return;
    }
    queue_.push_back(std::move(pair));
    if (queue_.size() > kQueueFrames) queue_.pop_front();  // a Kinect: the oldest goes
    arrived_.notify_all();
  }

  const Library& lib_;
  const bool replay_;
  const std::size_t entries_;  ///< fakenect: index entries to replay
  Context ctx_;
  freenect_device* dev_ = nullptr;

  // Pump thread only.
  cv::Mat pending_depth_;
  std::int64_t pending_ticks_ = 0;
  cv::Mat last_color_;
  std::int64_t last_color_ticks_ = 0;
  Unwrapped clock_;
  std::atomic<std::size_t> without_color_{0};

  // Shared, under mutex_.
  std::mutex mutex_;
  std::condition_variable arrived_;  ///< a pair, the end or an error
  std::condition_variable taken_;    ///< the reader took a pair (a dump's pump waits for room)
  std::deque<RawPair> queue_;
  bool quit_ = false;
  bool ended_ = false;
  std::string error_;
};

class FreenectSource final : public FrameSource {
 public:
  FreenectSource(const std::string& spec, const std::optional<Intrinsics>& intrinsics_override,
                 const std::string& intrinsics_origin)
      : spec_(spec) {
    Preflight p = preflight(spec);
    const Library& lib = *p.lib;
    replay_ = lib.replay;
    info_.live = true;
    info_.ground_truth = std::move(p.ground_truth);
    if (replay_) {
      if (!p.entries.cut_short.empty()) {
        log::warning(p.dump.string() + ": the dump stops early (" + p.entries.cut_short +
                     "): replaying the " + std::to_string(p.entries.depth_frames) +
                     " depth frames before it");
      }
      info_.frame_count = p.entries.depth_frames;
    }
    if (replay_) fakenectReplayed().store(true);
    session_ = std::make_shared<Session>(lib, replay_, p.entries.entries.size());
    freenect_device*& dev = session_->device();
    const int opened = lib.open_device(session_->context(), &dev, p.index);
    if (opened < 0 || dev == nullptr) {
      dev = nullptr;
      throw std::runtime_error(
          spec + ": libfreenect cannot open the Kinect (error " + std::to_string(opened) +
          "): it is busy in another program, or this user may not open its USB device");
    }
    configure(lib, intrinsics_override, intrinsics_origin, p.dump_intrinsics);
    info_.description = replay_ ? "fakenect dump " + p.dump.string() + " (" + spec_ + ", " +
                                      std::to_string(*info_.frame_count) + " frames)"
                                : "Kinect v1 " + spec_ + " (libfreenect)";
    session_->start();
    pump_ = std::thread([session = session_] { session->pump(); });
  }

  ~FreenectSource() override {
    if (session_->stop()) {
      pump_.join();
    } else {
      // fakenect sleeps through a pause in the dump; the pump holds the session and closes it.
      log::debug(spec_ + ": libfreenect is still waiting; its thread ends on its own");
      pump_.detach();
    }
  }

  FreenectSource(const FreenectSource&) = delete;
  FreenectSource& operator=(const FreenectSource&) = delete;

  const SourceInfo& info() const override { return info_; }

  FrameResult next() override {
    const std::string stalled =
        (replay_ ? "the fakenect dump (" + spec_ + ") gave no frame for 3 s after "
                 : "Kinect " + spec_ + " stopped delivering frames after ") +
        std::to_string(delivered_) + " frames" + (replay_ ? "" : " (unplugged?)");
    std::optional<RawPair> pair = session_->take(stalled);
    if (!pair) {
      if (const std::size_t n = session_->withoutColor(); n > 0 && !warned_color_) {
        warned_color_ = true;
        log::warning(spec_ + ": " + std::to_string(n) +
                     " depth frames came without a colour frame within 1/60 s; fused without "
                     "colour");
      }
      return FrameResult::end();
    }
    RgbdFrame frame;
    frame.index = static_cast<std::int64_t>(delivered_++);
    if (first_ticks_ < 0) first_ticks_ = pair->ticks;
    frame.device_frame =
        std::llround(static_cast<double>(pair->ticks - first_ticks_) / kTicksPerFrame);
    frame.stamp_s = static_cast<double>(pair->ticks) / kTicksPerSecond;
    cv::Mat metres(kHeight, kWidth, CV_32FC1);
    for (int v = 0; v < kHeight; ++v) {
      const std::uint16_t* in = pair->depth.ptr<std::uint16_t>(v);
      float* out = metres.ptr<float>(v);
      for (int u = 0; u < kWidth; ++u) {
        out[u] = registered_by_library_ ? static_cast<float>(in[u]) * 1e-3f
                                        : model_.metresFromRaw(in[u]);
      }
    }
    frame.depth_m = registered_by_library_ ? metres : model_.registerToColor(metres);
    frame.color_rgb = std::move(pair->color);
    frame.intrinsics = info_.intrinsics;
    return FrameResult::ok(std::move(frame));
  }

 private:
  /// Camera model, intrinsics and modes of the opened device.
  void configure(const Library& lib, const std::optional<Intrinsics>& intrinsics_override,
                 const std::string& intrinsics_origin,
                 const std::optional<Intrinsics>& dump_intrinsics) {
    freenect_device* dev = session_->device();
    std::optional<Intrinsics> device_intrinsics;
    // Registered millimetres from the library where it has the device's calibration.
    if (lib.copy_registration != nullptr && !replay_) {
      freenect_registration reg = lib.copy_registration(dev);
      const double ref_distance = reg.zero_plane_info.reference_distance;
      const double ref_pixel = reg.zero_plane_info.reference_pixel_size;
      if (ref_distance > 0.0 && ref_pixel > 0.0) {
        // The zero plane's pixels are of the 1280x1024 sensor, halved for 640x480.
        const double f = ref_distance / (2.0 * ref_pixel);
        device_intrinsics = Intrinsics{f, f, kWidth / 2.0, kHeight / 2.0, kWidth, kHeight};
        registered_by_library_ = true;
      }
      if (lib.destroy_registration != nullptr) lib.destroy_registration(&reg);
    }
    if (intrinsics_override) {
      info_.intrinsics = *intrinsics_override;
      info_.intrinsics_origin = intrinsics_origin.empty() ? "given" : intrinsics_origin;
    } else if (dump_intrinsics) {
      info_.intrinsics = *dump_intrinsics;
      info_.intrinsics_origin = "the dump's intrinsics.json";
    } else if (device_intrinsics) {
      info_.intrinsics = *device_intrinsics;
      info_.intrinsics_origin = "the Kinect's registration data";
    } else {
      info_.intrinsics = Intrinsics::xtionDefault();
      info_.intrinsics_origin = "Kinect v1 nominal camera (the library gives no calibration)";
      info_.intrinsics_assumed = true;
    }
    info_.intrinsics.validate();
    if (info_.intrinsics.width_px != kWidth || info_.intrinsics.height_px != kHeight) {
      throw InputError(spec_, "the intrinsics are for " +
                                  std::to_string(info_.intrinsics.width_px) + "x" +
                                  std::to_string(info_.intrinsics.height_px) +
                                  " images; the Kinect's are 640x480");
    }
    model_ = KinectModel::nominal(info_.intrinsics);
    info_.depth_units = registered_by_library_
                            ? "libfreenect's registered millimetres"
                            : "11-bit disparity, converted and registered by objscan";
    const freenect_frame_mode depth_mode = lib.find_depth_mode(
        FREENECT_RESOLUTION_MEDIUM,
        registered_by_library_ ? FREENECT_DEPTH_REGISTERED : FREENECT_DEPTH_11BIT);
    const freenect_frame_mode video_mode =
        lib.find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
    if (!depth_mode.is_valid || !video_mode.is_valid || lib.set_depth_mode(dev, depth_mode) < 0 ||
        lib.set_video_mode(dev, video_mode) < 0) {
      throw std::runtime_error(spec_ + ": the Kinect refuses 640x480 depth and RGB");
    }
  }

  std::string spec_;
  bool replay_ = false;
  SourceInfo info_;
  KinectModel model_ = KinectModel::nominal();
  bool registered_by_library_ = false;
  std::shared_ptr<Session> session_;  ///< closed by its last holder (this or the pump)
  std::thread pump_;

  // Reader only.
  std::size_t delivered_ = 0;
  std::int64_t first_ticks_ = -1;
  bool warned_color_ = false;
};

}  // namespace

void checkFreenect(const std::string& spec) { (void)preflight(spec); }

std::unique_ptr<FrameSource> openFreenect(const std::string& spec,
                                          const std::optional<Intrinsics>& intrinsics_override,
                                          const std::string& intrinsics_origin) {
  return std::make_unique<FreenectSource>(spec, intrinsics_override, intrinsics_origin);
}

}  // namespace objscan::capture
