#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/core/intrinsics.h"
#include "objscan/core/rgbd_frame.h"
#include "objscan/core/trajectory.h"

namespace objscan::capture {

/// One depth image and the colour image taken closest to it.
struct TumFrameFiles {
  double depth_stamp_s = 0.0;
  std::filesystem::path depth;  ///< 16-bit PNG, value / depth factor = metres, 0 = no reading
  double rgb_stamp_s = 0.0;
  std::filesystem::path rgb;  ///< 8-bit colour image; empty path when the folder has no colour
};

/// A recording in the TUM RGB-D benchmark's folder layout:
///   rgb/ depth/ rgb.txt depth.txt [associations.txt | associate.txt] [groundtruth.txt]
///   [intrinsics.json]
/// Frames come from associations.txt (or associate.txt; either column order, extra columns
/// `gt_t tx ty tz qx qy qz qw` taken as ground truth), otherwise from depth.txt with each depth
/// image paired to the nearest rgb.txt entry within 20 ms (as TUM's associate.py does).
/// intrinsics.json (core's format, plus an optional "depth_factor") overrides the Xtion defaults;
/// the TUM default depth factor is 5000.
class TumFolder {
 public:
  /// Reads the index files. Throws InputError naming the file and line for a folder that is not
  /// such a recording, an index line that does not parse, or a listed image that does not exist.
  explicit TumFolder(const std::filesystem::path& dir);

  /// True when `dir` has the index files of a TUM-format recording.
  static bool looksLikeTumFolder(const std::filesystem::path& dir);

  const std::filesystem::path& dir() const { return dir_; }
  const std::vector<TumFrameFiles>& frames() const { return frames_; }
  std::size_t size() const { return frames_.size(); }
  const Intrinsics& intrinsics() const { return intrinsics_; }
  bool intrinsicsFromFile() const { return intrinsics_from_file_; }
  double depthFactor() const { return depth_factor_; }
  /// How the frames were paired, for reports: "associations.txt", "depth.txt + rgb.txt (nearest)",
  /// ...
  const std::string& associationSource() const { return association_source_; }
  /// From groundtruth.txt, else from the association file's extra columns.
  const std::optional<Trajectory>& groundTruth() const { return ground_truth_; }
  const std::string& groundTruthSource() const { return ground_truth_source_; }

  /// Decodes frame i. Throws InputError naming the image when it cannot be decoded, is not 16-bit
  /// (depth), or its size differs from the intrinsics or from the other image.
  RgbdFrame load(std::size_t i) const;

 private:
  void readAssociations(const std::filesystem::path& file);
  void associateByTime();

  std::filesystem::path dir_;
  std::vector<TumFrameFiles> frames_;
  Intrinsics intrinsics_ = Intrinsics::xtionDefault();
  bool intrinsics_from_file_ = false;
  double depth_factor_ = 5000.0;
  std::string association_source_;
  std::optional<Trajectory> ground_truth_;
  std::string ground_truth_source_;
};

}  // namespace objscan::capture
