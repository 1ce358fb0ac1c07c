#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "objscan/capture/frame_source.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/trajectory.h"

/// Capture from a Kinect v1 (Xbox 360, Kinect for Windows) through libfreenect, and replay of
/// libfreenect's recorded dumps through its `fakenect` library, which serves a dump through the
/// same API. libfreenect is loaded at run time (dlopen of libfreenect.so.0.5), so objscan runs
/// where it is not installed, and the `fakenect` command (or LD_LIBRARY_PATH naming its folder)
/// swaps in the replay library unchanged. libfreenect types stay out of this header.
namespace objscan::capture {

/// `freenect` or `freenect:<index>` (0-based, as libfreenect counts devices).
bool isFreenectSource(const std::string& spec);
/// The device index of a freenect source. Throws std::invalid_argument naming the bad part.
int freenectIndex(const std::string& spec);

/// A device libfreenect finds.
struct FreenectDevice {
  std::string source;   ///< `freenect:<index>`, as objscan's sources name it
  std::string serial;   ///< the camera's serial number; empty when the library cannot tell
  std::string library;  ///< the file the library was loaded from
  bool replay = false;  ///< fakenect: a dump ($FAKENECT_PATH), not a device
};

/// The devices libfreenect finds now; empty, with `why` saying so, when libfreenect is not
/// installed or finds none.
std::vector<FreenectDevice> listFreenectDevices(std::string* why = nullptr);

/// The Kinect v1's cameras as objscan models them where the library gives no calibration
/// (Debian's fakenect replays raw 11-bit disparity and carries no registration data): the IR
/// (depth) camera, the colour camera 25 mm beside it along the images' x axis, both looking the
/// same way, and the disparity-to-depth relation of Khoshelham and Elberink (2012),
/// z = 8 b f / (d_off - d), with the projector's baseline b = 7.5 cm, the IR camera's focal length
/// f and d_off = 1090. Depth images are CV_32FC1 metres, 0 = no reading.
struct KinectModel {
  Intrinsics ir;     ///< the IR camera at 640x480: fx = fy = 580, centre 319.5, 239.5
  Intrinsics color;  ///< the colour camera (registered depth is in its frame)
  double color_x_m;  ///< the colour camera's x in the IR camera's frame
  double projector_baseline_m;
  double disparity_offset;

  /// The values above, with the colour camera of `color` (default: the PS1080 family's 640x480
  /// camera OpenNI2 reports, fx = fy = 570.3).
  static KinectModel nominal(const Intrinsics& color = Intrinsics::xtionDefault());

  /// The 11-bit raw value's depth; 0 for 2047 (no reading) and values beyond d_off.
  float metresFromRaw(std::uint16_t raw) const;
  /// The nearest raw value for a depth; 2047 (no reading) for 0, NaN, or a depth nearer than
  /// raw 0 measures (about 0.32 m).
  std::uint16_t rawFromMetres(float z_m) const;

  /// Depth seen by the IR camera, moved into the colour camera (registration): every reading is
  /// projected into the colour image (the nearest wins), then one-pixel gaps between readings
  /// that agree within 3 % are filled. Returns a colour-sized image.
  cv::Mat registerToColor(const cv::Mat& ir_depth_m) const;
  /// The other way, for writing dumps: depth in the colour camera seen by the IR camera.
  cv::Mat colorToIr(const cv::Mat& color_depth_m) const;
};

/// Opens a libfreenect device (`freenect` = the first one, `freenect:<index>`): 640x480 depth and
/// RGB at 30 Hz. Depth is registered to colour and in millimetres: by libfreenect's registration,
/// with the device's own calibration, where the library offers it; otherwise (fakenect) from the
/// raw 11-bit disparity with KinectModel::nominal(). Intrinsics: `intrinsics_override`, else the
/// dump's intrinsics.json (fakenect, a dump objscan wrote), else the device's registration data,
/// else the model's colour camera (marked assumed). Time stamps are the device's 60 MHz clock
/// (unwrapped); RgbdFrame::device_frame counts 30 Hz frames on it, so a gap is a dropped frame.
/// next() waits up to 3 s for a frame, then throws std::runtime_error (the sensor is lost); a
/// USB error throws the same way. The source keeps up to 8 frames the reader has not taken yet;
/// beyond that a Kinect's oldest frame goes, as with any sensor, while a dump's replay waits for
/// the reader (a dump replays every frame, whatever the reader's pace).
///
/// Under fakenect ($FAKENECT_PATH names the dump), the dump is checked before fakenect reads it
/// (fakenect itself exits the process on a missing file and reads past short ones): an entry that
/// is missing, unreadable or cut short ends the replay there, with a warning, and the stream ends
/// after the last entry (SourceInfo::frame_count holds the depth frames). The dump's
/// groundtruth.txt (TUM format, on the device clock), when present, is the ground truth.
///
/// Throws NoSensorError when libfreenect finds no device, InputError for a bad source name, an
/// index beyond the devices found, or a dump with no frame to replay, std::runtime_error when
/// libfreenect is not installed or the device cannot be opened (busy in another program, no
/// permission to its USB device).
std::unique_ptr<FrameSource> openFreenect(const std::string& spec,
                                          const std::optional<Intrinsics>& intrinsics_override = {},
                                          const std::string& intrinsics_origin = {});

/// Throws what openFreenect() would before it opens the device (library missing, no Kinect, bad
/// index, a dump it cannot replay), without opening it: for a Kinect that a program reaches
/// another way (the virtual OpenNI2 sensor, for recording), so errors keep their classes.
void checkFreenect(const std::string& spec);

/// The ground truth a freenect source will report, without opening the device: the dump's
/// groundtruth.txt under fakenect, nothing for a device.
std::optional<Trajectory> freenectGroundTruth();

/// Writing fakenect dumps: what libfreenect's `fakenect-record` writes, made from frames with
/// ground truth, so tests and benchmarks replay them through the real fakenect library.
struct FakenectDumpOptions {
  /// The dump's clock runs this many times slower than the source's (fakenect replays at the
  /// recorded pace; device time stamps keep the source's 30 Hz).
  double slow_down = 1.0;
  /// Source frame indices (0-based) left out, as frames a sensor dropped.
  std::vector<std::size_t> drop;
  /// Write at most this many frames.
  std::optional<std::size_t> max_frames;
};

struct FakenectDumpSummary {
  std::size_t frames = 0;  ///< depth frames written
  bool ground_truth = false;
};

/// Writes `source`'s frames into the folder `dir` (created; must be empty or missing) as a
/// fakenect dump: INDEX.txt, `r-<time>-<ticks>-0.ppm` (RGB) and `d-<time>-<ticks>-0.pgm` (raw
/// 11-bit disparity seen by the IR camera, host byte order as fakenect-record writes it), made
/// with KinectModel::nominal(the source's intrinsics). Also intrinsics.json (the colour camera)
/// and, when the source has ground truth, groundtruth.txt re-stamped onto the device clock.
/// Frames must be 640x480. Throws InputError / OutputError.
FakenectDumpSummary writeFakenectDump(FrameSource& source, const std::filesystem::path& dir,
                                      const FakenectDumpOptions& options = {});

}  // namespace objscan::capture
