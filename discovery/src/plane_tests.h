#pragma once

// Angles and plane membership shared by the supports (supports.cpp), the context (context.cpp)
// and the trimmed feet of small candidates (discover.cpp).

#include <cmath>
#include <numbers>

#include <Eigen/Core>

namespace objscan::discovery {

/// cos(degrees).
inline float cosOfDegrees(float degrees) {
  return std::cos(degrees * std::numbers::pi_v<float> / 180.0f);
}

/// Whether a vertex `height` over a surface whose normal is `normal` (unit length), with normal
/// `n`, lies on it: within `distance`, and with its normal within the angle whose cosine is
/// `min_cos` of the surface's, facing either way. A vertex without a normal (zero) never does.
inline bool onSurface(float height, const Eigen::Vector3f& normal, const Eigen::Vector3f& n,
                      float distance, float min_cos) {
  const float length = n.norm();
  return length > 0.0f && std::abs(height) <= distance &&
         std::abs(normal.dot(n)) >= min_cos * length;
}

/// Whether a vertex at `p` with normal `n` lies on the plane normal . x + offset = 0 (`normal`
/// of unit length): within `distance` of it, and with its normal within the angle whose cosine
/// is `min_cos` of the plane's, facing either way. A vertex without a normal (zero) never does.
inline bool onPlane(const Eigen::Vector3f& normal, float offset, const Eigen::Vector3f& p,
                    const Eigen::Vector3f& n, float distance, float min_cos) {
  return onSurface(normal.dot(p) + offset, normal, n, distance, min_cos);
}

/// The length of `d` along a plane whose unit normal is `up` (its part across the normal).
inline float alongPlane(const Eigen::Vector3f& up, const Eigen::Vector3f& d) {
  return (d - up.dot(d) * up).norm();
}

}  // namespace objscan::discovery
