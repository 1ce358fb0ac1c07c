#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/pose.h"

namespace objscan {

/// A camera pose at a moment in time.
struct StampedPose {
  double stamp_s = 0.0;  ///< seconds; TUM uses UNIX time, so double precision is needed
  Pose T_W_C = Pose::Identity();
};

/// Camera poses in time order, the way the TUM RGB-D benchmark stores them: one line per pose,
/// `t tx ty tz qx qy qz qw`, where (tx, ty, tz) and the unit quaternion (qx, qy, qz, qw) give
/// T_W_C.
struct Trajectory {
  std::vector<StampedPose> poses;

  std::size_t size() const { return poses.size(); }
  bool empty() const { return poses.empty(); }
  /// Last minus first time stamp; 0 for fewer than two poses.
  double durationS() const;
  /// Sum of the distances between consecutive camera positions, metres.
  double pathLengthM() const;
};

/// One TUM pose from its 8 numbers `t tx ty tz qx qy qz qw`; the quaternion is normalised.
/// Throws std::invalid_argument naming the problem: NaN or infinity, a quaternion whose norm is
/// off by more than 1 %, or a coordinate too large for float.
StampedPose stampedPoseFromTum(const std::array<double, 8>& values);

/// Reads a TUM trajectory. Lines starting with '#' and blank lines are skipped; a line may also be
/// comma-separated. Quaternions are normalised; one whose norm is off by more than 1 % is an error.
/// Throws InputError naming the file and line for anything else: missing file, a line without
/// exactly 8 numbers, NaN, time stamps that go backwards, or no poses at all.
Trajectory readTumTrajectory(const std::filesystem::path& path);

/// Writes the TUM format (time stamps with microsecond precision, the rest exact), atomically.
/// Throws OutputError, or std::invalid_argument (nothing written) when the time stamps go
/// backwards, which readTumTrajectory would refuse.
void writeTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);

/// Which way was up for the camera along `trajectory`, in its world frame: the mean over its poses
/// of the camera's -y (up in its images), normalised. People hold a camera upright and tilt it
/// down at what they scan, so this lies within the camera's tilt of gravity's up (a hint, not a
/// measurement). Nothing for an empty trajectory or when the poses' ups cancel out.
std::optional<Eigen::Vector3f> viewUp(const Trajectory& trajectory);

/// The pose nearest in time to stamp_s, if one lies within max_dt_s (poses in time order).
std::optional<Pose> nearestPose(const Trajectory& trajectory, double stamp_s, double max_dt_s);

/// Absolute trajectory error, as the TUM benchmark's evaluate_ate.py computes it.
struct TrajectoryError {
  std::size_t matched = 0;  ///< estimated poses paired with a ground-truth pose
  double rmse_m = 0.0;      ///< RMS of the position differences after alignment
  double mean_m = 0.0;
  double max_m = 0.0;
  Pose T_truth_estimate = Pose::Identity();  ///< the aligning rigid motion
};

/// Pairs each estimated pose with the ground-truth pose nearest in time (within max_dt_s, each
/// used once, closest pairs first), aligns the estimated positions to the true ones with the
/// least-squares rigid motion (Horn's method, no scale), and measures what differs. Throws
/// std::invalid_argument when fewer than 3 poses pair up.
TrajectoryError absoluteTrajectoryError(const Trajectory& estimate, const Trajectory& truth,
                                        double max_dt_s = 0.02);

}  // namespace objscan
