#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "objscan/core/intrinsics.h"
#include "objscan/core/pose.h"
#include "objscan/core/triangle_mesh.h"
#include "objscan/fusion/tsdf_volume.h"

namespace objscan::fusion {

/// What the volume's surface looks like from a camera: per pixel (row-major) the first zero
/// crossing along the pixel's ray and the surface normal there, in the world frame W. Pixels
/// without a surface hold NaN.
struct ModelMaps {
  Intrinsics intrinsics;
  Pose T_W_C = Pose::Identity();  ///< the camera the maps were cast from
  std::vector<Eigen::Vector3f> vertices_W;
  std::vector<Eigen::Vector3f> normals_W;  ///< unit, facing the camera (toward free space)
  std::vector<Rgb8> colors;                ///< empty unless asked for
  std::size_t hits = 0;                    ///< pixels with a vertex and a normal
};

/// Casts one ray per pixel through the volume from T_W_C, between the depths (along the optical
/// axis) min_depth_m and max_depth_m. Rays start at the nearest allocated block in front of
/// their 8x8-pixel tile (blocks are projected into a coarse range image first), step through
/// observed free space by a fraction of the stored distance, and stop at the first
/// positive-to-negative crossing, refined by trilinear interpolation. Normals are the
/// normalised gradient of the interpolated distance. A ray that meets the back of a surface
/// (negative first) or leaves the observed volume finds nothing.
///
/// What a ray does at a pixel whose depth hint is 0 (no reading there).
enum class UnhintedRays {
  kMarch,  ///< march the whole depth range, as without a hint
  kSkip,   ///< cast nothing: the pixel stays empty (NaN), as no reading there would match it
};

/// `depth_hint` (CV_32FC1 metres, the image's size, 0 = none): when the maps are cast from the
/// pose a depth image was just integrated at, the surface lies near its readings. A ray with a
/// reading then starts at it and reads the stored distance there: in front of the surface it
/// marches on; behind it, it steps back toward the camera by the stored distance until the sign
/// turns. Where the reading's voxel was never observed, the ray marches the whole range. The
/// crossing found is the one nearest the reading, which is the first along the ray unless the
/// volume holds a surface in front of the reading that the reading itself contradicts. A ray
/// without a reading marches the whole range, or with `unhinted` kSkip is not cast at all (such
/// rays cost a third of the tracking model's raycast on 7-Scenes, and mostly find nothing).
ModelMaps raycast(const TsdfVolume& volume, const Intrinsics& intrinsics, const Pose& T_W_C,
                  float min_depth_m, float max_depth_m, bool with_colors = false,
                  const cv::Mat* depth_hint = nullptr,
                  UnhintedRays unhinted = UnhintedRays::kMarch);

/// The same into `maps`, reusing its memory (two 3.7 MB maps at 640x480, cast every frame).
void raycast(const TsdfVolume& volume, const Intrinsics& intrinsics, const Pose& T_W_C,
             float min_depth_m, float max_depth_m, bool with_colors, const cv::Mat* depth_hint,
             ModelMaps* maps, UnhintedRays unhinted = UnhintedRays::kMarch);

/// Every second pixel of every second row, with the intrinsics of the next pyramid level: the
/// model for a coarser tracking level.
ModelMaps halfResolution(const ModelMaps& maps);

}  // namespace objscan::fusion
