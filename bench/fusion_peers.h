// The peers that bench/fusion runs on the same frames as objscan: Open3D 0.16 (legacy
// ScalableTSDFVolume, ExtractTriangleMesh, RGB-D odometry) and OpenCV 4.6's rgbd module (HashTSDF
// volume, its raycast, ICPOdometry). Debian's OpenCV leaves out the KinFu classes, so the loop is
// composed from those parts. Each function runs one peer over the whole input and returns per-stage
// times; the driver (fusion_bench.cpp) runs each peer in its own process to measure peak memory.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core/mat.hpp>

namespace objscan::bench {

/// The frames every system gets, loaded before any timing starts.
struct FusionBenchInput {
  std::vector<cv::Mat> depth_mm;          ///< CV_16UC1 millimetres, 0 = no reading
  std::vector<cv::Mat> depth_m;           ///< CV_32FC1 metres, 0 = no reading (same frames)
  std::vector<cv::Mat> color_rgb;         ///< CV_8UC3, R G B order, same size as depth
  std::vector<Eigen::Matrix4d> T_W_C;     ///< ground-truth camera-to-world poses, one per frame
  double fx = 0, fy = 0, cx = 0, cy = 0;  ///< depth intrinsics, pixels
  int width = 0, height = 0;
  float voxel_m = 0.01f;       ///< voxel edge for every volume
  float truncation_m = 0.03f;  ///< TSDF truncation for every volume
  float min_depth_m = 0.3f;    ///< readings outside [min, max] are ignored by every system
  float max_depth_m = 3.0f;
  std::vector<int> icp_iterations = {10, 5, 4};  ///< per pyramid level, finest first
};

constexpr double kNotMeasured = std::numeric_limits<double>::quiet_NaN();

/// One system's numbers; a stage it does not offer stays kNotMeasured.
struct FusionBenchResult {
  std::string system;
  double integrate_ms = kNotMeasured;  ///< per frame, integrating with the ground-truth poses
  double raycast_ms = kNotMeasured;    ///< per frame, a 640x480 vertex + normal map of the volume
  double prepare_ms = kNotMeasured;    ///< per frame, what tracking needs first (pyramids, normals)
  double track_ms = kNotMeasured;      ///< per frame, the pose solve alone (frames prepared)
  double mesh_ms = kNotMeasured;       ///< once, meshing the volume integrated over all frames
  std::size_t mesh_vertices = 0;
  std::size_t mesh_triangles = 0;
  double ate_rmse_m = kNotMeasured;   ///< of the trajectory its tracking chained, vs ground truth
  std::size_t tracking_failures = 0;  ///< frames where its odometry reported failure
  nlohmann::json notes = nlohmann::json::object();  ///< settings worth printing
};

/// Every system's raycasts are timed from every raycastPoseStride(n)-th of the n ground-truth
/// poses: about 50 casts spread over the sequence (every pose when there are fewer).
inline std::size_t raycastPoseStride(std::size_t frames) { return frames > 50 ? frames / 50 : 1; }

FusionBenchResult runOpen3dPeer(const FusionBenchInput& input);
FusionBenchResult runOpenCvPeer(const FusionBenchInput& input);

}  // namespace objscan::bench
