#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "objscan/core/pose.h"
#include "objscan/core/trajectory.h"
#include "objscan/core/triangle_mesh.h"

namespace objscan::capture {

enum class ScenePreset {
  kDesk,     ///< a desk against a wall, on a floor
  kShelf,    ///< a bookshelf with three shelves against a wall
  kCounter,  ///< a kitchen counter with a wall cabinet above it
};

/// "desk", "shelf", "counter".
const char* toString(ScenePreset preset);
/// Throws std::invalid_argument for any other name.
ScenePreset scenePresetFromString(const std::string& name);

struct SceneConfig {
  ScenePreset preset = ScenePreset::kDesk;
  /// How many objects to place (the issue asks for 5-20; 1-30 accepted).
  int objects = 10;
  /// Seeds every random choice: the same config gives the same scene, bit for bit.
  std::uint64_t seed = 1;
  /// Optional folder of .ply meshes (metres, z up, e.g. the YCB set) added to the built-in shapes.
  std::filesystem::path object_dir;
  /// Share of objects placed flush against the wall or against an earlier object.
  double touching_fraction = 0.3;
  /// Harder clutter, for judging discovery on scenes harder than the real ones: a third of the
  /// objects small (shapes::smallNames: 1.6-4.3 cm, and a flat spoon), stacked on an earlier
  /// object with a flat top in a fifth of the draws, at least half touching, colours drawn at random (so neighbours may share
  /// one) and half the objects in two colours, a potted plant (clutter, label 0) on desks and
  /// counters, and three cables instead of one. Off: the scene is what it was before this
  /// existed, bit for bit.
  bool hard_clutter = false;

  /// Throws std::invalid_argument naming the bad field.
  void validate() const;
};

/// One object of a synthetic scene; its vertices carry `id` as their label.
struct SceneObject {
  std::int32_t id = 0;            ///< 1.. in placement order; 0 is reserved for "not an object"
  std::string name;               ///< built-in name ("mug") or the mesh file's stem ("025_mug")
  Pose T_W_O = Pose::Identity();  ///< object frame (z up, resting on z = 0) to world
  Eigen::Vector3f box_min_O = Eigen::Vector3f::Zero();  ///< oriented box, object frame, metres
  Eigen::Vector3f box_max_O = Eigen::Vector3f::Zero();
  std::size_t vertex_count = 0;
  bool touching = false;  ///< placed flush against the wall or another object
  bool stacked = false;   ///< standing on another object (hard_clutter)
};

/// A composed scene in the world frame W: z up, the floor at z = 0, the wall behind the supports
/// at y = kWallY facing -y, where the camera is.
struct SyntheticScene {
  static constexpr float kWallY = 0.35f;
  /// Everything: supports and clutter (label 0) and objects (label = id); colours and normals.
  TriangleMesh mesh;
  std::vector<SceneObject> objects;
  /// Where a camera should look: the middle of the area objects stand on.
  Eigen::Vector3f look_at_W = Eigen::Vector3f::Zero();
  ScenePreset preset = ScenePreset::kDesk;
};

/// Builds a scene. Throws std::invalid_argument for a bad config, InputError for an unreadable
/// mesh in object_dir, std::runtime_error when the requested objects do not fit.
SyntheticScene composeScene(const SceneConfig& config);

/// A hand-held-like camera path around the scene: a sweeping arc in front of it, the distance to
/// the look-at point varying between min and max, with small jitter and roll.
struct HandheldPathConfig {
  int frames = 300;
  double rate_hz = 30.0;
  double min_distance_m = 0.6;
  double max_distance_m = 1.5;
  /// Azimuth swept over the whole path, centred in front of the wall; reached only by paths of
  /// 10 s or more (the sweep turns at most 0.12 rad/s, as a hand would).
  double sweep_rad = 1.2;
  double min_elevation_rad = 0.35;  ///< camera height above the look-at point, as an angle
  double max_elevation_rad = 0.8;
  double jitter_m = 0.01;  ///< amplitude of the hand's wobble
  double roll_rad = 0.06;  ///< amplitude of roll about the optical axis
  std::uint64_t seed = 1;

  void validate() const;
};

/// Camera poses T_W_C (x right, y down, z forward) at rate_hz, time stamps from 0 s.
Trajectory makeHandheldPath(const SyntheticScene& scene, const HandheldPathConfig& config);

}  // namespace objscan::capture
