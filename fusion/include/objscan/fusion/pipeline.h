#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "objscan/core/intrinsics.h"
#include "objscan/core/pose.h"
#include "objscan/core/rgbd_frame.h"
#include "objscan/core/trajectory.h"
#include "objscan/fusion/icp.h"
#include "objscan/fusion/preprocess.h"
#include "objscan/fusion/raycast.h"
#include "objscan/fusion/tsdf_volume.h"

/// KinectFusion on the CPU: per frame, preprocess -> track -> integrate -> raycast.
namespace objscan::fusion {

struct FusionConfig {
  PreprocessConfig preprocess;
  VolumeConfig volume;
  TrackingConfig tracking;
  /// A frame with fewer valid depth readings than this share of its pixels is skipped.
  float min_valid_fraction = 0.01f;
  /// The pyramid level the tracking model is cast at: 0 = the frame's resolution, 1 = half,
  /// 2 = a quarter (a pyramid with fewer levels uses its coarsest). A quarter: the same ATE on
  /// TUM, 7-Scenes and the synthetic desk as half, a raycast 3.4 ms per frame shorter
  /// (docs/fusion.md, "Track").
  int model_level = 2;
  /// Rays of the model cast after integrating, at pixels where the frame has no reading: kSkip
  /// leaves them empty. They were a third of that raycast's time on 7-Scenes at 5.86 mm, and the
  /// ATE moved by at most 0.1 mm on TUM fr2/desk, 7-Scenes and the synthetic desk (2026-11-25).
  UnhintedRays model_unhinted_rays = UnhintedRays::kSkip;
  /// Throws std::invalid_argument naming the bad field.
  void validate() const;
};

/// What happened to one frame.
enum class FrameStatus {
  kTracked,    ///< tracked against the model and integrated
  kGivenPose,  ///< integrated at the pose supplied by the caller
  kFirst,      ///< the first frame: integrated at the initial pose
  kLost,       ///< tracking failed: not integrated; the next frame starts from the last good pose
  kNoDepth,    ///< too few depth readings: skipped
};

struct FrameTimings {
  double preprocess_ms = 0.0;
  double track_ms = 0.0;
  double integrate_ms = 0.0;
  double raycast_ms = 0.0;

  /// Stage by stage, for totals over frames.
  FrameTimings& operator+=(const FrameTimings& o) {
    preprocess_ms += o.preprocess_ms;
    track_ms += o.track_ms;
    integrate_ms += o.integrate_ms;
    raycast_ms += o.raycast_ms;
    return *this;
  }
};

struct FrameOutcome {
  FrameStatus status = FrameStatus::kNoDepth;
  Pose T_W_C = Pose::Identity();  ///< the pose the frame was integrated at (last good if not)
  TrackingResult tracking;        ///< when tracked or lost
  std::string reason;             ///< why lost or skipped
  std::size_t blocks_updated = 0;
  FrameTimings timings;
};

/// Fuses a stream of frames of one camera into a TSDF volume. Owns the volume, the model maps
/// and the trajectory. Not thread-safe; the stages inside run in parallel (oneTBB).
class Fusion {
 public:
  /// `initial_T_W_C` is the pose of the first integrated frame (the identity, or the first
  /// ground-truth pose so that the mesh lands in the dataset's world frame). Throws
  /// std::invalid_argument for a bad config or intrinsics.
  Fusion(const FusionConfig& config, const Intrinsics& intrinsics,
         const Pose& initial_T_W_C = Pose::Identity());

  /// Processes the next frame. With `given_T_W_C` the frame is integrated at that pose and not
  /// tracked. Throws std::invalid_argument when the frame's images or intrinsics do not match
  /// the ones the pipeline was built for.
  FrameOutcome process(const RgbdFrame& frame, const std::optional<Pose>& given_T_W_C = {});

  const TsdfVolume& volume() const { return volume_; }
  /// Poses of the integrated frames, stamped with their frames' stamps.
  const Trajectory& trajectory() const { return trajectory_; }
  std::size_t framesProcessed() const { return processed_; }
  std::size_t framesLost() const { return lost_; }
  std::size_t framesSkipped() const { return skipped_; }
  /// The model maps of the last good pose, at the resolution of config.model_level; empty before
  /// the first frame.
  const ModelMaps& model() const { return model_; }

 private:
  FusionConfig config_;
  Intrinsics intrinsics_;
  TsdfVolume volume_;
  ModelMaps model_;
  cv::Mat clipped_;             ///< this frame's clipped depth (buffer kept across frames)
  cv::Mat hint_;                ///< the nearest reading per pixel of the model's level (> 0)
  int model_level_ = 0;         ///< config_.model_level within the pyramid
  DepthPyramid pyramid_;        ///< this frame's tracking pyramid (buffers kept across frames)
  bool model_current_ = false;  ///< model_ was cast from last_good_
  Pose last_good_;
  Trajectory trajectory_;
  std::size_t processed_ = 0, lost_ = 0, skipped_ = 0;
};

}  // namespace objscan::fusion
