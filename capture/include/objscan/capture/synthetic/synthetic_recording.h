#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "objscan/capture/synthetic/sensor_model.h"
#include "objscan/capture/synthetic/synthetic_scene.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/organized_cloud.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "objscan/render/offscreen_renderer.h"

namespace objscan::capture {

/// How often each object was seen, from the ideal (noise-free) label images.
struct Visibility {
  std::int32_t id = 0;
  std::size_t pixels = 0;  ///< summed over all frames
  std::size_t frames = 0;  ///< frames with at least one pixel
};

/// Checks that `out` can become a new recording folder (absent, or an empty folder) and returns
/// it normalised ("out/" -> "out"). Throws std::invalid_argument naming the problem.
std::filesystem::path checkNewFolder(const std::filesystem::path& out);

/// A scene and the path that sees it.
struct SceneAndPath {
  SyntheticScene scene;
  Trajectory path;
  std::uint64_t scene_seed = 0;  ///< the seed the scene was finally composed with
};

/// Composes the scene and its hand-held path, then renders every 10th pose: if an object never
/// shows at least 20 pixels (hidden behind others or outside every view), composes again with a
/// seed derived from config.seed, up to 8 times, and keeps the last try. Deterministic.
SceneAndPath composeSceneSeenAlongPath(const SceneConfig& config,
                                       const HandheldPathConfig& path_config,
                                       const Intrinsics& intrinsics);

/// One frame of a synthetic recording, before any file format touches it.
struct SyntheticFrame {
  render::RenderedView view;  ///< the ideal view: exact depth, colour (RGB), labels, incidence
  cv::Mat depth_m;            ///< CV_32FC1: the sensor's depth, metres, 0 = no reading
};

/// Frame `index` of a recording along a path: renders the mesh uploaded to `renderer` from T_W_C
/// and applies the sensor model with a seed derived from `noise_seed` and `index`, so a frame's
/// noise does not depend on which other frames were rendered. writeSyntheticRecording writes
/// these pixels and SyntheticSource streams them. Same thread-safety as `renderer`.
SyntheticFrame renderSyntheticFrame(render::OffscreenRenderer& renderer, const Pose& T_W_C,
                                    std::size_t index, const SensorModelConfig& sensor,
                                    std::uint64_t noise_seed);

/// Renders `scene` along `path` and writes a TUM RGB-D folder to `out_dir`:
///   rgb/ depth/ (16-bit PNG, value / 5000 = metres, 0 = no reading) label/ (16-bit PNG, object
///   id per pixel) rgb.txt depth.txt associations.txt groundtruth.txt intrinsics.json
///   scene_gt.ply (the scene with per-vertex object_id) scene_gt.json (objects, poses, boxes)
/// Everything is written to a temporary folder next to `out_dir` and renamed into place at the
/// end, so an interrupted run leaves no folder that looks complete. `out_dir` must not exist or be
/// an empty folder (std::invalid_argument otherwise). `seed` drives the sensor noise: frame i is
/// renderSyntheticFrame(renderer, pose i, i, sensor, seed). `progress` (optional) advances once
/// per frame. With `views` > 0, that many of the frames, evenly spread along the path, are also
/// written to views/<timestamp>.pcd as labelled single views (syntheticView), for `objscan eval`
/// and `discover` (at most one per frame: std::invalid_argument beyond). Throws OutputError when
/// writing fails.
std::vector<Visibility> writeSyntheticRecording(const SyntheticScene& scene, const Trajectory& path,
                                                const Intrinsics& intrinsics,
                                                const SensorModelConfig& sensor, std::uint64_t seed,
                                                const std::filesystem::path& out_dir,
                                                ProgressBar* progress = nullptr,
                                                std::size_t views = 0);

/// A frame as a labelled single view, in the camera frame: the sensor's depth (a pixel without a
/// reading is NaN), the rendered colour, and labels in mOSD's convention (OrganizedCloud::labels):
/// 0 no reading, 1 any surface that is no object (table, walls, plant, cables), 10 k object k.
OrganizedCloud syntheticView(const SyntheticFrame& frame, const Intrinsics& intrinsics);

/// The object names of a scene_gt.json that writeSyntheticRecording wrote (or of a hand-labelled
/// mesh's objects.json, whose objects give their id as "label"), by object id. Throws
/// InputError naming the file when it is not such a file.
std::map<std::int32_t, std::string> readSceneObjectNames(
    const std::filesystem::path& scene_gt_json);

}  // namespace objscan::capture
