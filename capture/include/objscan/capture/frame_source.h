#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include "objscan/core/intrinsics.h"
#include "objscan/core/rgbd_frame.h"
#include "objscan/core/trajectory.h"

namespace objscan::capture {

/// What one call of FrameSource::next() gave.
enum class FrameStatus {
  kOk,           ///< `frame` holds the next frame
  kEndOfStream,  ///< no more frames; every later call says the same
  kBadFrame,     ///< this frame could not be read (`reason` says why); the next call moves on
};

struct FrameResult {
  FrameStatus status = FrameStatus::kEndOfStream;
  RgbdFrame frame;     ///< valid only with kOk
  std::string reason;  ///< one line, with kBadFrame: names the file or frame and the problem

  static FrameResult ok(RgbdFrame f) { return {FrameStatus::kOk, std::move(f), {}}; }
  static FrameResult end() { return {}; }
  static FrameResult bad(std::string why) { return {FrameStatus::kBadFrame, {}, std::move(why)}; }
};

/// What a source knows about itself before the first frame.
struct SourceInfo {
  std::string description;  ///< e.g. "TUM folder data/x (50 frames)"
  std::optional<std::size_t>
      frame_count;                ///< frames next() will return (after selection); none for live
  Intrinsics intrinsics;          ///< of the depth images (colour is registered to depth)
  std::string intrinsics_origin;  ///< "intrinsics.json", "sensor field of view", ...
  /// The camera is a default, not the recording's own calibration: a wrong one scales the whole
  /// mesh (the Xtion default's fx 570.3 against TUM fr2's 520.9 is 10 %), so callers warn.
  bool intrinsics_assumed = false;
  std::string depth_units;  ///< how stored depth becomes metres, e.g. "value / 5000 (TUM)"
  std::optional<Trajectory> ground_truth;  ///< camera poses T_W_C, keyed by the frames' stamp_s
  bool live = false;                       ///< frames come from a sensor in real time
};

/// A stream of depth + colour frames: a sensor, a recording, a dataset folder or a synthetic
/// scene. Frames come in capture order; replaying a recording or a folder gives the same frames in
/// the same order every time. Fatal problems (the file vanished, the sensor was unplugged) throw:
/// InputError for bad input, std::runtime_error for a device or system failure.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual const SourceInfo& info() const = 0;
  virtual FrameResult next() = 0;
};

/// Which frames of an indexed source to use: indices start, start + every, ... below end.
struct FrameSelection {
  std::size_t start = 0;
  std::optional<std::size_t> end;  ///< exclusive; none = to the last frame
  std::size_t every = 1;           ///< at least 1

  bool selectsAll() const { return start == 0 && !end && every == 1; }
  /// Throws std::invalid_argument for every == 0 or end <= start.
  void validate() const;
  /// How many of `total` frames are selected.
  std::size_t count(std::size_t total) const;
  /// Whether frame `index` (0-based, in the source's order) is selected.
  bool selects(std::size_t index) const;
};

}  // namespace objscan::capture
