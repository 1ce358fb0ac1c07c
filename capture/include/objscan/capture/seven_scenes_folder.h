#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "objscan/core/intrinsics.h"
#include "objscan/core/rgbd_frame.h"
#include "objscan/core/trajectory.h"

namespace objscan::capture {

/// The files of one frame of a 7-Scenes / 3DMatch folder, relative to the folder.
struct SevenScenesFrameFiles {
  std::int64_t number = 0;      ///< NNNNNN of frame-NNNNNN.*
  double stamp_s = 0.0;         ///< number / 30 Hz (the folders carry no time stamps)
  std::filesystem::path depth;  ///< 16-bit PNG, millimetres, 0 or 65535 = no reading
  std::filesystem::path color;  ///< 8-bit colour image; empty path when the folder has no colour
  std::filesystem::path pose;   ///< 4x4 T_W_C text file; empty path when the folder has no poses
};

/// A recording in the Microsoft 7-Scenes layout, which 3DMatch's RGB-D sequences share:
///   frame-NNNNNN.depth.png frame-NNNNNN.color.{png,jpg} [frame-NNNNNN.pose.txt]
///   [camera-intrinsics.txt]
/// Frames are the depth images in frame-number order (gaps in the numbering are fine), each taken
/// at number / 30 Hz. Colour is optional for the whole folder but not per frame: once one frame
/// has a colour image, every frame needs one. The pose files (camera-to-world 4x4 matrices, one
/// row per line) become the ground truth, for every frame or for none.
/// camera-intrinsics.txt holds the 3x3 matrix `fx 0 cx / 0 fy cy / 0 0 1`; it is looked for in
/// the folder and then in its parent (3DMatch keeps one per scene beside its seq-NN folders). It
/// does not give the image size, which is then taken from the first depth image's PNG header.
/// Without it the 7-Scenes calibration applies: fx = fy = 585, centre (320, 240), 640x480.
class SevenScenesFolder {
 public:
  /// The folders have no time stamps; frames are taken to be 1 / 30 s apart (Kinect v1 rate).
  static constexpr double kFrameRate_hz = 30.0;

  /// Lists the frames and reads the intrinsics and all pose files. Throws InputError naming the
  /// file (and line, for text files) for a folder without depth images, a frame without its
  /// colour image or pose file while others have one, two files for the same frame number, an
  /// intrinsics file that does not parse or is not a pinhole matrix, or a pose that does not
  /// parse, is not finite (3DMatch marks lost tracking with -inf) or is not rigid.
  explicit SevenScenesFolder(const std::filesystem::path& dir);

  /// True when `dir` is a folder holding at least one frame-NNNNNN.depth.png.
  static bool looksLikeSevenScenesFolder(const std::filesystem::path& dir);

  /// The 7-Scenes Kinect calibration used when a folder has no camera-intrinsics.txt.
  static Intrinsics defaultIntrinsics();

  const std::filesystem::path& dir() const { return dir_; }
  const std::vector<SevenScenesFrameFiles>& frames() const { return frames_; }
  std::size_t size() const { return frames_.size(); }
  const Intrinsics& intrinsics() const { return intrinsics_; }
  bool intrinsicsFromFile() const { return !intrinsics_file_.empty(); }
  /// The camera-intrinsics.txt that was read (in the folder or its parent); empty for defaults.
  const std::filesystem::path& intrinsicsFile() const { return intrinsics_file_; }
  /// T_W_C per frame keyed by the frames' stamp_s; none when the folder has no pose files.
  const std::optional<Trajectory>& groundTruth() const { return ground_truth_; }

  /// Decodes frame i: depth in metres (millimetres / 1000, 0 and 65535 become 0), colour in RGB
  /// order. Throws InputError naming the image when it cannot be decoded, is not 16-bit (depth),
  /// or its size differs from the intrinsics or from the other image.
  RgbdFrame load(std::size_t i) const { return load(i, intrinsics_); }
  /// The same, checked against and tagged with `intrinsics` instead of the folder's own (for a
  /// calibration the user supplies).
  RgbdFrame load(std::size_t i, const Intrinsics& intrinsics) const;

 private:
  void readIntrinsics();
  void readPoses();

  std::filesystem::path dir_;
  std::vector<SevenScenesFrameFiles> frames_;
  Intrinsics intrinsics_ = defaultIntrinsics();
  std::filesystem::path intrinsics_file_;
  std::optional<Trajectory> ground_truth_;
};

}  // namespace objscan::capture
