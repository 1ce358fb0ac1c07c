#pragma once

#include <array>
#include <cstddef>
#include <string>

#include "objscan/core/pose.h"
#include "objscan/fusion/preprocess.h"
#include "objscan/fusion/raycast.h"

/// Camera tracking: projective point-to-plane ICP of the frame against the raycast model, coarse
/// to fine (KinectFusion, section 3.5).
namespace objscan::fusion {

struct TrackingConfig {
  /// Gauss-Newton iterations per pyramid level, finest level first (KinectFusion's 10, 5, 4).
  /// Levels beyond the pyramid's are ignored; a level with 0 iterations is skipped.
  std::array<int, 3> iterations = {10, 5, 4};
  /// At the finest level, every n-th pixel of every n-th row takes part (1 = all).
  int finest_level_stride = 2;
  /// A frame point and its model point farther apart than this are not a correspondence.
  float max_distance_m = 0.10f;
  /// Nor are they when their normals differ by more than this (20 degrees, KinectFusion's).
  float max_angle_rad = 0.349f;
  /// Huber threshold of the point-to-plane residual: larger residuals get weight huber / |r|.
  float huber_m = 0.01f;
  /// Tracking is lost when fewer than this share of the frame's pixels with a vertex and a
  /// normal that take part at the finest level match the model in the last iteration there...
  float min_inlier_fraction = 0.10f;
  /// ... or when their point-to-plane RMS residual exceeds this ...
  float max_rmse_m = 0.02f;
  /// ... or when the pose moved more than this from the previous one: a hand-held camera at
  /// 30 Hz does not jump 15 cm or 20 degrees between frames.
  float max_translation_m = 0.15f;
  float max_rotation_rad = 0.349f;
  /// Throws std::invalid_argument with a sentence naming the bad field.
  void validate() const;
};

struct TrackingResult {
  Pose T_W_C = Pose::Identity();  ///< the estimate (also when lost: for diagnostics only)
  bool ok = false;
  std::string failure;           ///< why tracking was lost; empty when ok
  std::size_t inliers = 0;       ///< correspondences at the finest level, last iteration
  float inlier_fraction = 0.0f;  ///< inliers / frame pixels taking part at the finest level
  float rmse_m = 0.0f;           ///< point-to-plane RMS residual of the inliers
  int iterations = 0;            ///< Gauss-Newton steps taken, all levels
};

/// Aligns `frame` to `model` (raycast from the previous pose, at the frame's resolution or a
/// pyramid level coarser: each frame level is matched with the model at its own resolution or the
/// model's finest, whichever is coarser) starting from `initial_T_W_C`. Each iteration associates
/// every frame pixel with the model pixel it projects to in the model's camera, keeps pairs within
/// the distance and angle gates, and solves the linearised point-to-plane problem for a small rigid
/// motion.
TrackingResult trackFrame(const DepthPyramid& frame, const ModelMaps& model,
                          const Pose& initial_T_W_C, const TrackingConfig& config);

}  // namespace objscan::fusion
