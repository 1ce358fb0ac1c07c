#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "objscan/core/intrinsics.h"
#include "objscan/core/progress.h"
#include "objscan/core/trajectory.h"
#include "objscan/render/sensor_model.h"
#include "objscan/render/synthetic_scene.h"

namespace objscan::render {

/// How often each object was seen, from the ideal (noise-free) label images.
struct Visibility {
  std::int32_t id = 0;
  std::size_t pixels = 0;  ///< summed over all frames
  std::size_t frames = 0;  ///< frames with at least one pixel
};

/// Renders `scene` along `path` and writes a TUM RGB-D folder to `out_dir`:
///   rgb/ depth/ (16-bit PNG, value / 5000 = metres, 0 = no reading) label/ (16-bit PNG, object
///   id per pixel) rgb.txt depth.txt associations.txt groundtruth.txt intrinsics.json
///   scene_gt.ply (the scene with per-vertex object_id) scene_gt.json (objects, poses, boxes)
/// Everything is written to a temporary folder next to `out_dir` and renamed into place at the
/// end, so an interrupted run leaves no folder that looks complete. `out_dir` must not exist or be
/// an empty folder (std::invalid_argument otherwise). `seed` drives the sensor noise; `progress`
/// (optional) advances once per frame. Throws OutputError when writing fails.
std::vector<Visibility> writeSyntheticRecording(const SyntheticScene& scene, const Trajectory& path,
                                                const Intrinsics& intrinsics,
                                                const SensorModelConfig& sensor, std::uint64_t seed,
                                                const std::filesystem::path& out_dir,
                                                ProgressBar* progress = nullptr);

}  // namespace objscan::render
