#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "objscan/core/intrinsics.h"

/// Depth preprocessing for tracking (KinectFusion, Newcombe et al. 2011, section 3.2): range clip,
/// bilateral filter, a pyramid of half resolutions, and per level the vertex and normal maps.
namespace objscan::fusion {

struct PreprocessConfig {
  /// Readings nearer than this are dropped (the Xtion measures from about 0.5 m).
  float min_depth_m = 0.3f;
  /// Readings farther than this are dropped: the sensor's noise grows with the square of the
  /// distance, and the paper's KinectFusion volume was 3 m on a side.
  float max_depth_m = 3.0f;
  /// Bilateral filter on the tracking depth (KinectFusion's values): window radius, spatial and
  /// depth standard deviations. Radius 0 turns the filter off.
  int bilateral_radius_px = 2;
  float bilateral_sigma_space_px = 4.5f;
  float bilateral_sigma_depth_m = 0.03f;
  /// Pyramid levels for coarse-to-fine tracking; level l has 1 / 2^l of the resolution.
  int pyramid_levels = 3;
  /// Throws std::invalid_argument with a sentence naming the bad field.
  void validate() const;
};

/// One pyramid level, in the camera frame C. Pixels are row-major; an invalid pixel has depth 0
/// and NaN vertex and normal.
struct DepthLevel {
  Intrinsics intrinsics;  ///< scaled to this level's size
  cv::Mat depth_m;        ///< CV_32FC1
  /// The vertex and normal maps hold every n-th pixel of every n-th row of depth_m only:
  /// ceil(cols / n) x ceil(rows / n) samples, sample (i, j) being pixel (n i, n j). 1 = all.
  int sample_stride_px = 1;
  std::vector<Eigen::Vector3f> vertices_C;  ///< back-projected depth
  std::vector<Eigen::Vector3f> normals_C;   ///< unit, facing the camera
};

/// Levels 0 (full resolution) to pyramid_levels - 1.
struct DepthPyramid {
  std::vector<DepthLevel> levels;
};

/// `depth_m` (CV_32FC1, metres; 0 or NaN = no reading) with its readings outside
/// [min_depth_m, max_depth_m], NaN and infinities set to 0. This is the depth that is integrated.
cv::Mat clipDepth(const cv::Mat& depth_m, const PreprocessConfig& config);
/// The same into `clipped` (reusing its memory when it has the right size; not depth_m itself).
void clipDepth(const cv::Mat& depth_m, const PreprocessConfig& config, cv::Mat* clipped);

/// The tracking pyramid of a clipped depth image: bilateral filter at level 0, then each level
/// averages the 2x2 pixels of the one below that lie within 3 sigma_depth of the nearest of them.
/// Intrinsics of level l: focal lengths / 2^l, principal point (c + 0.5) / 2^l - 0.5.
/// `finest_sample_stride_px` > 1 computes level 0's vertices and normals only at every n-th pixel
/// of every n-th row (DepthLevel::sample_stride_px), those that tracking's finest level reads
/// (TrackingConfig::finest_level_stride): the same values there, in a quarter of the time at 2.
DepthPyramid buildPyramid(const cv::Mat& clipped_depth_m, const Intrinsics& intrinsics,
                          const PreprocessConfig& config, int finest_sample_stride_px = 1);

/// The same into `pyramid`, reusing its images and maps: at 640x480 a pyramid is 10 MB, and
/// allocating it afresh every frame costs page faults.
void buildPyramid(const cv::Mat& clipped_depth_m, const Intrinsics& intrinsics,
                  const PreprocessConfig& config, DepthPyramid* pyramid,
                  int finest_sample_stride_px = 1);

/// Intrinsics of a pyramid level (see buildPyramid).
Intrinsics levelIntrinsics(const Intrinsics& full, int level);

/// Normals of a camera-frame vertex map from the cross product of its right and lower neighbours'
/// differences, facing the camera (n . v < 0); NaN where a neighbour is missing.
std::vector<Eigen::Vector3f> computeNormals(const std::vector<Eigen::Vector3f>& vertices_C,
                                            int width, int height);

}  // namespace objscan::fusion
