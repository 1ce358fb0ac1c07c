// The two peers of bench/fusion (see fusion_peers.h). Each runs the same four stages as objscan
// where the peer offers them: integrate every frame at its ground-truth pose, raycast or mesh the
// result, and track frame to frame. Only the library call that does a stage's work is inside a
// timed region; copying our cv::Mat frames into the peer's own image types is not, since a user of
// that library would load the frames into those types directly.

#include "fusion_peers.h"

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <open3d/Open3DConfig.h>
#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/pipelines/integration/ScalableTSDFVolume.h>
#include <open3d/pipelines/odometry/Odometry.h>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/core/ocl.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/rgbd/depth.hpp>
#include <opencv2/rgbd/volume.hpp>

#include "objscan/core/trajectory.h"

namespace objscan::bench {
namespace {

using Clock = std::chrono::steady_clock;

/// Ground truth and estimate are paired by index: frame i gets the stamp i seconds, so any
/// tolerance below 1 s pairs exactly the same frames.
constexpr double kAteMaxDtS = 0.5;

/// Runs `work` once and returns how long it took, milliseconds.
template <typename Work>
double timeMs(Work&& work) {
  const Clock::time_point start = Clock::now();
  work();
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// A float setting as a JSON number without the float-to-double noise (0.07f prints as 0.07).
double forNotes(double setting) { return std::round(setting * 1e6) / 1e6; }

double meanMs(const std::vector<double>& times_ms) {
  if (times_ms.empty()) return kNotMeasured;
  double sum = 0.0;
  for (double t : times_ms) sum += t;
  return sum / static_cast<double>(times_ms.size());
}

/// Both peers need matching frames and poses, and the trajectory error needs three poses.
void checkInput(const FusionBenchInput& input) {
  const std::size_t n = input.T_W_C.size();
  if (n < 3 || input.depth_mm.size() != n || input.depth_m.size() != n ||
      input.color_rgb.size() != n) {
    throw std::invalid_argument(
        "fusion peers: need at least 3 frames, each with a millimetre depth image, a metre depth "
        "image, a colour image and a ground-truth pose; got " +
        std::to_string(n) + " poses, " + std::to_string(input.depth_mm.size()) + "/" +
        std::to_string(input.depth_m.size()) + "/" + std::to_string(input.color_rgb.size()) +
        " images");
  }
  if (input.icp_iterations.empty()) {
    throw std::invalid_argument("fusion peers: icp_iterations needs at least one pyramid level");
  }
  const cv::Size size(input.width, input.height);
  for (std::size_t i = 0; i < n; ++i) {
    if (input.depth_mm[i].type() != CV_16UC1 || input.depth_m[i].type() != CV_32FC1 ||
        input.color_rgb[i].type() != CV_8UC3 || input.depth_mm[i].size() != size ||
        input.depth_m[i].size() != size || input.color_rgb[i].size() != size) {
      throw std::invalid_argument("fusion peers: frame " + std::to_string(i) +
                                  " does not have the image types and the size the input declares");
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Trajectories

/// Frame-to-frame tracking of one peer: per-frame times and the chained camera poses.
struct OdometryRun {
  std::vector<double> prepare_ms;      ///< one per frame
  std::vector<double> track_ms;        ///< one per frame pair
  std::vector<Eigen::Matrix4d> T_W_C;  ///< one per frame, starting at the first true pose
  std::size_t failures = 0;
};

/// Tracks every frame against the one before it and chains the motions from the first
/// ground-truth pose: T_W_Ci = T_W_Ci-1 * T_Ci-1_Ci. A frame whose tracking fails keeps the
/// previous pose. `load(i)` turns frame i into the peer's own types (not timed), `prepare(raw)`
/// builds what tracking needs (timed as prepare), and `track(previous, current)` solves for
/// T_Ci-1_Ci, or returns nothing when the peer reports failure (timed as track). Only the
/// previous and current frames are kept, so tracking adds little to the peer's peak memory.
template <typename Load, typename Prepare, typename Track>
OdometryRun runOdometry(const FusionBenchInput& input, Load&& load, Prepare&& prepare,
                        Track&& track) {
  const std::size_t n = input.T_W_C.size();
  OdometryRun run;
  run.prepare_ms.reserve(n);
  run.track_ms.reserve(n - 1);
  run.T_W_C.reserve(n);

  auto prepared = [&](std::size_t i) {
    auto raw = load(i);
    decltype(prepare(raw)) frame;
    run.prepare_ms.push_back(timeMs([&] { frame = prepare(raw); }));
    return frame;
  };

  auto previous = prepared(0);
  run.T_W_C.push_back(input.T_W_C.front());
  for (std::size_t i = 1; i < n; ++i) {
    auto current = prepared(i);
    std::optional<Eigen::Matrix4d> T_prev_cur;
    run.track_ms.push_back(timeMs([&] { T_prev_cur = track(previous, current); }));
    if (T_prev_cur) {
      run.T_W_C.push_back(run.T_W_C.back() * *T_prev_cur);
    } else {
      ++run.failures;
      run.T_W_C.push_back(run.T_W_C.back());
    }
    previous = std::move(current);
  }
  return run;
}

Trajectory indexStampedTrajectory(const std::vector<Eigen::Matrix4d>& T_W_C) {
  Trajectory trajectory;
  trajectory.poses.reserve(T_W_C.size());
  for (std::size_t i = 0; i < T_W_C.size(); ++i) {
    StampedPose pose;
    pose.stamp_s = static_cast<double>(i);
    pose.T_W_C.matrix() = T_W_C[i].cast<float>();
    trajectory.poses.push_back(pose);
  }
  return trajectory;
}

/// Fills the tracking fields of `result`, with the ATE of the chained trajectory.
void storeOdometry(const OdometryRun& run, const FusionBenchInput& input,
                   FusionBenchResult& result) {
  result.prepare_ms = meanMs(run.prepare_ms);
  result.track_ms = meanMs(run.track_ms);
  result.tracking_failures = run.failures;
  result.ate_rmse_m = absoluteTrajectoryError(indexStampedTrajectory(run.T_W_C),
                                              indexStampedTrajectory(input.T_W_C), kAteMaxDtS)
                          .rmse_m;
}

// ---------------------------------------------------------------------------------------------
// Open3D

/// Copies an OpenCV image into an Open3D one (same channel order and element size).
open3d::geometry::Image toOpen3d(const cv::Mat& mat) {
  open3d::geometry::Image image;
  image.Prepare(mat.cols, mat.rows, mat.channels(), static_cast<int>(mat.elemSize1()));
  const std::size_t row_bytes = static_cast<std::size_t>(mat.cols) * mat.elemSize();
  for (int v = 0; v < mat.rows; ++v) {
    std::memcpy(image.data_.data() + static_cast<std::size_t>(v) * row_bytes, mat.ptr(v),
                row_bytes);
  }
  return image;
}

struct Open3dFrame {
  open3d::geometry::Image color;
  open3d::geometry::Image depth_mm;
};

Open3dFrame loadOpen3dFrame(const FusionBenchInput& input, std::size_t i) {
  return {toOpen3d(input.color_rgb[i]), toOpen3d(input.depth_mm[i])};
}

/// Open3D's RGB-D image: depth in float metres, zero beyond max_depth_m; colour kept as RGB for
/// integration, or turned into float intensity for odometry.
std::shared_ptr<open3d::geometry::RGBDImage> makeOpen3dRgbd(const Open3dFrame& frame,
                                                            const FusionBenchInput& input,
                                                            bool intensity) {
  constexpr double kMillimetresPerMetre = 1000.0;
  return open3d::geometry::RGBDImage::CreateFromColorAndDepth(
      frame.color, frame.depth_mm, kMillimetresPerMetre, input.max_depth_m, intensity);
}

/// Integrates every frame at its true pose; returns the mean time of an Integrate call. Each
/// frame's RGB-D image is built just before its call (untimed) rather than all up front, so the
/// peer's peak memory does not include a second copy of the whole sequence.
double integrateOpen3d(const FusionBenchInput& input,
                       const open3d::camera::PinholeCameraIntrinsic& intrinsic,
                       open3d::pipelines::integration::ScalableTSDFVolume& volume) {
  std::vector<double> times_ms;
  times_ms.reserve(input.T_W_C.size());
  for (std::size_t i = 0; i < input.T_W_C.size(); ++i) {
    const auto rgbd = makeOpen3dRgbd(loadOpen3dFrame(input, i), input, /*intensity=*/false);
    // Open3D's extrinsic maps world points into the camera: T_C_W.
    const Eigen::Matrix4d T_C_W = input.T_W_C[i].inverse();
    times_ms.push_back(timeMs([&] { volume.Integrate(*rgbd, intrinsic, T_C_W); }));
  }
  return meanMs(times_ms);
}

/// Open3D's option lists the iterations coarsest level first; ours lists them finest first.
std::vector<int> coarsestFirst(const std::vector<int>& finest_first) {
  return {finest_first.rbegin(), finest_first.rend()};
}

OdometryRun trackOpen3d(const FusionBenchInput& input,
                        const open3d::camera::PinholeCameraIntrinsic& intrinsic,
                        const open3d::pipelines::odometry::OdometryOption& option) {
  namespace odometry = open3d::pipelines::odometry;
  const odometry::RGBDOdometryJacobianFromHybridTerm jacobian;
  return runOdometry(
      input, [&](std::size_t i) { return loadOpen3dFrame(input, i); },
      [&](const Open3dFrame& frame) { return makeOpen3dRgbd(frame, input, /*intensity=*/true); },
      [&](const std::shared_ptr<open3d::geometry::RGBDImage>& previous,
          const std::shared_ptr<open3d::geometry::RGBDImage>& current)
          -> std::optional<Eigen::Matrix4d> {
        // The result maps source points into the target frame; with the current frame as
        // source and the previous one as target that is T_Ci-1_Ci.
        [[maybe_unused]] const auto [success, T_target_source, information] =
            odometry::ComputeRGBDOdometry(*current, *previous, intrinsic,
                                          Eigen::Matrix4d::Identity(), jacobian, option);
        if (!success) return std::nullopt;
        return T_target_source;
      });
}

// ---------------------------------------------------------------------------------------------
// OpenCV

cv::Matx44f toMatx(const Eigen::Matrix4d& T) {
  cv::Matx44f m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = static_cast<float>(T(r, c));
  }
  return m;
}

Eigen::Matrix4d toEigen(const cv::Mat& Rt) {
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) T(r, c) = Rt.at<double>(r, c);
  }
  return T;
}

/// Integrates every frame (float metres, so a depth factor of 1) at its true camera-to-world
/// pose, which is what OpenCV's volume expects; returns the mean time of an integrate call.
double integrateOpenCv(const FusionBenchInput& input, const cv::kinfu::Intr& intrinsics,
                       cv::kinfu::Volume& volume) {
  constexpr float kDepthFactor = 1.0f;
  std::vector<double> times_ms;
  times_ms.reserve(input.T_W_C.size());
  for (std::size_t i = 0; i < input.T_W_C.size(); ++i) {
    const cv::Matx44f T_W_C = toMatx(input.T_W_C[i]);
    times_ms.push_back(
        timeMs([&] { volume.integrate(input.depth_m[i], kDepthFactor, T_W_C, intrinsics); }));
  }
  return meanMs(times_ms);
}

/// Raycasts a full-size vertex and normal map of the finished volume from true poses spread over
/// the sequence; returns the mean time of a call and how many calls were made.
std::pair<double, std::size_t> raycastOpenCv(const FusionBenchInput& input,
                                             const cv::kinfu::Intr& intrinsics,
                                             const cv::kinfu::Volume& volume) {
  const std::size_t n = input.T_W_C.size();
  const std::size_t stride = raycastPoseStride(n);
  const cv::Size size(input.width, input.height);
  cv::Mat points, normals;  // reused, as a tracking loop would
  std::vector<double> times_ms;
  for (std::size_t i = 0; i < n; i += stride) {
    const cv::Matx44f T_W_C = toMatx(input.T_W_C[i]);
    times_ms.push_back(timeMs([&] { volume.raycast(T_W_C, intrinsics, size, points, normals); }));
  }
  return {meanMs(times_ms), times_ms.size()};
}

OdometryRun trackOpenCv(const FusionBenchInput& input, const cv::rgbd::ICPOdometry& odometry) {
  using cv::rgbd::OdometryFrame;
  return runOdometry(
      input,
      // ICP uses depth only. The frame gets its own copy: its pyramids share that Mat's pixels,
      // and the input is const.
      [&](std::size_t i) { return OdometryFrame::create(cv::Mat(), input.depth_m[i].clone()); },
      [&](cv::Ptr<OdometryFrame> frame) {
        // Every frame is the source of one pair and the destination of the next.
        odometry.prepareFrameCache(frame, OdometryFrame::CACHE_ALL);
        return frame;
      },
      [&](cv::Ptr<OdometryFrame>& previous,
          cv::Ptr<OdometryFrame>& current) -> std::optional<Eigen::Matrix4d> {
        // Rt maps points of the source frame into the destination frame; with the current frame
        // as source and the previous one as destination that is T_Ci-1_Ci.
        cv::Mat Rt;
        if (!odometry.compute(current, previous, Rt)) return std::nullopt;
        return toEigen(Rt);
      });
}

}  // namespace

FusionBenchResult runOpen3dPeer(const FusionBenchInput& input) {
  namespace integration = open3d::pipelines::integration;
  namespace odometry = open3d::pipelines::odometry;
  checkInput(input);
  FusionBenchResult result;
  result.system = "Open3D " OPEN3D_VERSION " (legacy)";
  const open3d::camera::PinholeCameraIntrinsic intrinsic(input.width, input.height, input.fx,
                                                         input.fy, input.cx, input.cy);

  // Integration and meshing. The unit resolution and depth sampling stride are Open3D's defaults.
  constexpr int kVolumeUnitResolution = 16;
  constexpr int kDepthSamplingStride = 4;
  integration::ScalableTSDFVolume volume(input.voxel_m, input.truncation_m,
                                         integration::TSDFVolumeColorType::RGB8,
                                         kVolumeUnitResolution, kDepthSamplingStride);
  result.integrate_ms = integrateOpen3d(input, intrinsic, volume);
  std::shared_ptr<open3d::geometry::TriangleMesh> mesh;
  result.mesh_ms = timeMs([&] { mesh = volume.ExtractTriangleMesh(); });
  result.mesh_vertices = mesh->vertices_.size();
  result.mesh_triangles = mesh->triangles_.size();
  mesh.reset();

  // Frame-to-frame RGB-D odometry; the depth difference limit is Open3D's default.
  const odometry::OdometryOption option(coarsestFirst(input.icp_iterations),
                                        odometry::OdometryOption().depth_diff_max_,
                                        input.min_depth_m, input.max_depth_m);
  storeOdometry(trackOpen3d(input, intrinsic, option), input, result);

  result.notes = {
      {"volume", "ScalableTSDFVolume, RGB8 colour"},
      {"volume_unit_resolution_vox", kVolumeUnitResolution},
      {"depth_sampling_stride_px", kDepthSamplingStride},
      {"min_depth",
       "not applied to integration: ScalableTSDFVolume has no minimum depth, only depth_trunc "
       "(= max_depth_m); odometry does apply depth_min"},
      {"raycast", "not measured: the legacy ScalableTSDFVolume has no raycast"},
      {"odometry", "ComputeRGBDOdometry, hybrid (photometric + depth) Jacobian, frame to frame"},
      {"odometry_iterations_coarsest_first", option.iteration_number_per_pyramid_level_},
      {"odometry_depth_diff_max_m", forNotes(option.depth_diff_max_)},
      {"prepare", "CreateFromColorAndDepth to float intensity + float depth"},
      {"track",
       "includes Open3D's own per-pair preprocessing (smoothing, intensity normalisation, image "
       "pyramids, gradients), which its API does not let a caller prepare once per frame"},
  };
  return result;
}

FusionBenchResult runOpenCvPeer(const FusionBenchInput& input) {
  checkInput(input);
  FusionBenchResult result;
  result.system = "OpenCV " CV_VERSION " rgbd";

  // With OpenCL on and a device present, OpenCV would pick its OpenCL volume. objscan runs on the
  // CPU, so the comparison uses OpenCV's CPU path. The switch is per thread, and the driver runs
  // each peer in its own process.
  cv::ocl::setUseOpenCL(false);

  // HashTSDF volume with OpenCV's own defaults for everything the input does not set. This
  // makeVolume overload ignores the resolution for HashTSDF (the volume grows as needed) and uses
  // its factory's default volume unit of 16^3 voxels, which is also what defaultParams reports.
  const cv::Ptr<cv::kinfu::VolumeParams> defaults =
      cv::kinfu::VolumeParams::defaultParams(cv::kinfu::VolumeType::HASHTSDF);
  const cv::Ptr<cv::kinfu::Volume> volume =
      cv::kinfu::makeVolume(cv::kinfu::VolumeType::HASHTSDF, input.voxel_m, cv::Matx44f::eye(),
                            defaults->raycastStepFactor, input.truncation_m, defaults->maxWeight,
                            input.max_depth_m, defaults->resolution);
  const cv::kinfu::Intr intrinsics(static_cast<float>(input.fx), static_cast<float>(input.fy),
                                   static_cast<float>(input.cx), static_cast<float>(input.cy));
  result.integrate_ms = integrateOpenCv(input, intrinsics, *volume);
  const auto [raycast_ms, raycasts] = raycastOpenCv(input, intrinsics, *volume);
  result.raycast_ms = raycast_ms;

  // Frame-to-frame ICP; the depth difference, point share and motion limits are OpenCV's
  // defaults. Its iteration counts, like ours, list the finest pyramid level first.
  const cv::Mat camera_matrix =
      (cv::Mat_<double>(3, 3) << input.fx, 0, input.cx, 0, input.fy, input.cy, 0, 0, 1);
  const cv::Ptr<cv::rgbd::ICPOdometry> odometry = cv::rgbd::ICPOdometry::create(
      camera_matrix, input.min_depth_m, input.max_depth_m,
      cv::rgbd::Odometry::DEFAULT_MAX_DEPTH_DIFF(), cv::rgbd::Odometry::DEFAULT_MAX_POINTS_PART(),
      input.icp_iterations, cv::rgbd::Odometry::RIGID_BODY_MOTION);
  storeOdometry(trackOpenCv(input, *odometry), input, result);

  result.notes = {
      {"volume", "HashTSDF (CPU, OpenCL off)"},
      {"volume_unit_resolution_vox", defaults->unitResolution},
      {"raycast_step_factor", forNotes(defaults->raycastStepFactor)},
      {"max_weight", defaults->maxWeight},
      {"min_depth",
       "not applied to integration: the volume has no minimum depth, only its truncate "
       "threshold (= max_depth_m); ICP does apply minDepth"},
      {"raycast_poses", raycasts},
      {"mesh", "not measured: the HashTSDF volume has no mesher (only a point and normal dump)"},
      {"odometry", "ICPOdometry (point-to-plane), frame to frame"},
      {"odometry_iterations_finest_first", input.icp_iterations},
      {"odometry_max_depth_diff_m", forNotes(odometry->getMaxDepthDiff())},
      {"odometry_max_points_part", forNotes(odometry->getMaxPointsPart())},
      {"odometry_max_translation_m", forNotes(odometry->getMaxTranslation())},
      {"odometry_max_rotation_deg", forNotes(odometry->getMaxRotation())},
      {"prepare", "prepareFrameCache(CACHE_ALL): depth pyramid, point clouds, normals, masks"},
      {"threads", cv::getNumThreads()},
  };
  return result;
}

}  // namespace objscan::bench
