#include "synth_command.h"

#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>

#include "objscan/capture/synthetic/synthetic_recording.h"
#include "objscan/capture/synthetic/synthetic_scene.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/log.h"
#include "objscan/core/progress.h"

namespace objscan::app {

void runSynth(const SynthOptions& options) {
  const std::optional<capture::SensorModelConfig> sensor = capture::sensorForNoise(options.noise);
  if (!sensor) {
    throw std::invalid_argument("--noise must be 'on', 'full' or 'off', not '" + options.noise +
                                "'");
  }
  if (options.clutter != "plain" && options.clutter != "hard") {
    throw std::invalid_argument("--clutter must be 'plain' or 'hard', not '" + options.clutter +
                                "'");
  }
  capture::checkNewFolder(options.out);  // before any work: a bad --out costs nothing
  capture::SceneConfig scene_config;
  scene_config.preset = capture::scenePresetFromString(options.preset);
  scene_config.objects = options.objects;
  scene_config.seed = options.seed;
  scene_config.object_dir = options.object_dir;
  scene_config.hard_clutter = options.clutter == "hard";
  capture::HandheldPathConfig path_config;
  path_config.frames = options.frames;
  path_config.seed = options.seed;
  const Intrinsics intrinsics = options.intrinsics.empty() ? Intrinsics::xtionDefault()
                                                           : readIntrinsicsJson(options.intrinsics);

  if (options.views > options.frames) {
    throw std::invalid_argument("--views " + std::to_string(options.views) + " exceeds --frames " +
                                std::to_string(options.frames));
  }
  const capture::SceneAndPath composed =
      capture::composeSceneSeenAlongPath(scene_config, path_config, intrinsics);
  const capture::SyntheticScene& scene = composed.scene;
  const Trajectory& path = composed.path;
  std::vector<capture::Visibility> visibility;
  {
    ProgressBar progress("rendering frames", path.size());
    visibility = capture::writeSyntheticRecording(scene, path, intrinsics, *sensor, options.seed,
                                                  options.out, &progress,
                                                  static_cast<std::size_t>(options.views));
  }
  std::size_t never_seen = 0;
  for (const auto& v : visibility) {
    if (v.frames == 0) {
      ++never_seen;
      log::warning("object " + std::to_string(v.id) + " (" + scene.objects[v.id - 1].name +
                   ") is not visible in any frame");
    }
  }
  std::printf("scene         %s, %zu objects, seed %llu, noise %s\n",
              capture::toString(scene.preset), scene.objects.size(),
              static_cast<unsigned long long>(options.seed), options.noise.c_str());
  std::printf("mesh          %zu vertices, %zu triangles\n", scene.mesh.positions.size(),
              scene.mesh.triangles.size());
  std::printf("frames        %zu at 30 Hz, %dx%d\n", path.size(), intrinsics.width_px,
              intrinsics.height_px);
  std::printf("visible       %zu of %zu objects in at least one frame\n",
              visibility.size() - never_seen, visibility.size());
  if (options.views > 0) {
    std::printf("views         %d frames as labelled single views (views/*.pcd)\n", options.views);
  }
  std::printf("written       %s (TUM folder; scene_gt.ply, scene_gt.json)\n",
              options.out.string().c_str());
}

}  // namespace objscan::app
