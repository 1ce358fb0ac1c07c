#pragma once

// libfreenect, loaded at run time. Why dlopen and not a link: Debian's fakenect (libfreenect-bin
// 0.5.3), the library tests and dump replays swap in for the real one, exports only the core of
// the API (no freenect_copy_registration, no device attributes), so a program linked against the
// real library would die with an undefined symbol under fakenect; loading it also lets objscan run
// where libfreenect is not installed.

#include <libfreenect.h>
#include <libfreenect_registration.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace objscan::capture::freenect_detail {

struct Library {
  std::string path;  ///< the file loaded (fakenect's lives in .../fakenect/)
  /// fakenect: it replays $FAKENECT_PATH. Told by the file's folder or by the symbols only
  /// fakenect exports (sleep_highres).
  bool replay = false;

  decltype(&freenect_init) init = nullptr;
  decltype(&freenect_shutdown) shutdown = nullptr;
  decltype(&freenect_set_log_callback) set_log_callback = nullptr;
  decltype(&freenect_set_log_level) set_log_level = nullptr;
  decltype(&freenect_select_subdevices) select_subdevices = nullptr;
  decltype(&freenect_num_devices) num_devices = nullptr;
  decltype(&freenect_open_device) open_device = nullptr;
  decltype(&freenect_close_device) close_device = nullptr;
  decltype(&freenect_set_user) set_user = nullptr;
  decltype(&freenect_get_user) get_user = nullptr;
  decltype(&freenect_set_depth_callback) set_depth_callback = nullptr;
  decltype(&freenect_set_video_callback) set_video_callback = nullptr;
  decltype(&freenect_find_depth_mode) find_depth_mode = nullptr;
  decltype(&freenect_find_video_mode) find_video_mode = nullptr;
  decltype(&freenect_set_depth_mode) set_depth_mode = nullptr;
  decltype(&freenect_set_video_mode) set_video_mode = nullptr;
  decltype(&freenect_start_depth) start_depth = nullptr;
  decltype(&freenect_start_video) start_video = nullptr;
  decltype(&freenect_stop_depth) stop_depth = nullptr;
  decltype(&freenect_stop_video) stop_video = nullptr;
  decltype(&freenect_process_events) process_events = nullptr;
  // fakenect's ignores the timeout (it is process_events again, sleeping as the dump pauses).
  decltype(&freenect_process_events_timeout) process_events_timeout = nullptr;
  // Not in fakenect:
  decltype(&freenect_copy_registration) copy_registration = nullptr;
  decltype(&freenect_destroy_registration) destroy_registration = nullptr;
  decltype(&freenect_list_device_attributes) list_device_attributes = nullptr;
  decltype(&freenect_free_device_attributes) free_device_attributes = nullptr;

  /// Loads libfreenect.so.0.5 once per process (never unloaded). Throws std::runtime_error naming
  /// the package when it is missing or lacks the core API.
  static const Library& get();
};

/// One line of a fakenect dump's INDEX.txt that fakenect can read.
struct DumpEntry {
  char type = 0;            ///< 'd' depth, 'r' RGB, 'a' accelerometer, other types are skipped
  double time_s = 0.0;      ///< the recording's wall clock (fakenect paces replay by it)
  std::uint32_t ticks = 0;  ///< the device's 60 MHz time stamp
  std::string file;
};

/// A dump's entries up to the first one fakenect cannot replay safely (a missing, short or
/// malformed file, an empty line: fakenect exits the process on a missing file and reads past a
/// short one), and why the rest was left out (empty when nothing was).
struct DumpIndex {
  std::vector<DumpEntry> entries;
  std::size_t depth_frames = 0;
  std::string cut_short;
};

/// Reads and checks `dir`/INDEX.txt. Throws InputError when INDEX.txt is missing or unreadable.
DumpIndex readDumpIndex(const std::filesystem::path& dir);

inline constexpr int kWidth = 640;
inline constexpr int kHeight = 480;
inline constexpr double kTicksPerSecond = 60e6;  ///< the Kinect's frame clock
inline constexpr double kTicksPerFrame = 2e6;    ///< at 30 Hz

}  // namespace objscan::capture::freenect_detail
