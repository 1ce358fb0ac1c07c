#pragma once

#include <Eigen/Geometry>

namespace objscan {

/// Rigid transforms are Eigen::Isometry3f named by the frames they connect: `T_W_C` maps points
/// from the camera frame C into the world frame W (p_W = T_W_C * p_C), so it is also the camera's
/// pose in the world. Camera frame: x right, y down, z forward (OpenNI/OpenCV convention). Metres.
using Pose = Eigen::Isometry3f;

/// Builds a pose from a translation and a quaternion (normalised here), the TUM convention.
inline Pose poseFromTranslationQuaternion(const Eigen::Vector3f& t, const Eigen::Quaternionf& q) {
  Pose T = Pose::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

}  // namespace objscan
