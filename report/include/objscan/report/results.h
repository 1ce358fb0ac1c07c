#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/intrinsics.h"
#include "objscan/core/pose.h"
#include "objscan/core/trajectory.h"
#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/shape_measures.h"

/// The results model: what a results folder holds, as typed values. Each file has one writer and
/// one reader (results_io.h); the commands pass these values from stage to stage and write each
/// file once. Keys absent from an older file read as unknown (std::nullopt / NaN).
namespace objscan::report {

// ---- hypotheses.json ---------------------------------------------------------------------------

/// A segment's oriented box: centre (the middle of the extents, not the centroid), principal axes
/// (unit, columns) and the extent along each, metres.
struct OrientedBox {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();
  Eigen::Vector3f extents = Eigen::Vector3f::Zero();
};

/// One ranked hypothesis.
struct HypothesisRecord {
  std::size_t rank = 0;         ///< 1 = best
  std::optional<double> score;  ///< objectness: higher is more object-like
  std::string scene;            ///< the scene mesh it was cut from (SceneRecord::mesh)
  /// The paper's six measures, raw; NaN where unknown (recurrence with no other scene).
  discovery::ShapeMeasures measures;
  std::optional<OrientedBox> box;
  std::optional<float> scale;               ///< the segmentation granularity it came from
  std::vector<std::int32_t> vertices;       ///< indices into the scene mesh, increasing
  std::optional<std::size_t> vertex_count;  ///< as written; vertices.size() when those were read
  std::string file;  ///< its sub-mesh, relative to the folder: objects/rank_NNN.ply
  /// Its place in its scene's object set (1 = first; the hypotheses a user sees, which never
  /// overlap); 0 for an alternative; nothing in a file from before the object set.
  std::optional<std::size_t> object_rank;
  /// What the object set is chosen by: the score weighed by its evidence and region share, less
  /// its footing's penalty (discovery::Hypothesis::object_score).
  std::optional<double> object_score;
  /// The object score it is ranked by when it is one of the object set; nothing for an
  /// alternative (ranked by its score) or a file from before the object set.
  std::optional<double> objectScoreIfObject() const {
    return object_rank.value_or(0) > 0 ? object_score : std::nullopt;
  }
  /// Its context (discovery::SegmentContext): how it stands ("support", "surface", "patch",
  /// "under" or "none"; empty when unknown), the height of its lowest point over the support
  /// plane under it, its share of its region off the supports, how well fusion saw it, and for
  /// one on a support how far it rises over it, the support's noise there and what floats over
  /// it.
  std::string footing;
  std::optional<double> height_m, share_of_region, observation, rise_m, support_noise_m,
      covered_share;
};

/// Where discovery spent its time on one scene, milliseconds.
struct SceneTimesMs {
  double graph = 0.0, supports = 0.0, segmentation = 0.0, filters = 0.0, measures = 0.0;
};

/// What discovery did with a scene whose candidates it computed (not taken from the catalog).
struct SceneFindings {
  double median_edge_m = 0.0;
  std::size_t min_size = 0;  ///< m_size after density scaling
  std::size_t support_planes = 0, support_vertices = 0;
  SceneTimesMs timings_ms;
};

struct SceneRecord {
  /// The scene's file relative to the results folder (so the folder can move with its scenes,
  /// and be rendered from any working directory); as given to discovery when it names no file.
  std::string mesh;
  std::string mesh_absolute;  ///< the same file's absolute path; empty when it names no file
  /// The mesh discovery worked on, written into the folder (scenes/scene_NNN.ply, relative to
  /// it) when the scene is not a PLY file: a PCD view or a frame of a source become meshes only
  /// once objscan has read them, and view and render show this one. Empty for a PLY scene.
  std::string mesh_copy;
  /// The scene's key as the catalog knows it (DiscoveredScene::content_hash: the hash of the PCD
  /// file, or of the frame's depth, colour and camera, and the camera's up where the candidates
  /// depend on it); noted with mesh_copy, by which the viewer finds the scene in the catalog.
  /// Empty otherwise.
  std::string content_hash;
  std::optional<std::size_t> vertices, faces, candidates, hypotheses;
  bool from_catalog = false;
  /// The scene's id in the catalog the run used (CatalogUse::path); nothing without a catalog, or
  /// in a file from before it was written.
  std::optional<std::int64_t> catalog_scene;
  std::optional<SceneFindings> findings;  ///< absent when the catalog supplied the candidates
};

struct Scoring {
  std::string kind;             ///< "average", "rbf_svm", ...
  std::string model;            ///< the model file; empty for the average
  std::string normalised_over;  ///< "catalog", "these scenes", "the model's training segments"
};

/// The catalog a run used and what it held with the run's settings.
struct CatalogUse {
  std::string path;  ///< absolute
  std::size_t scenes = 0, segments = 0;
};

/// hypotheses.json.
struct Hypotheses {
  std::optional<Scoring> scoring;
  std::optional<CatalogUse> catalog;
  std::vector<SceneRecord> scenes;
  std::vector<HypothesisRecord> hypotheses;  ///< by rank
};

// ---- evaluation.json ---------------------------------------------------------------------------

struct EvaluatedRank {
  std::size_t rank = 0;
  std::int32_t object_id = 0;  ///< the ground-truth object it overlaps most; 0 none
  std::string object;          ///< its name (scene_gt.json); empty when unknown
  double iou = 0.0;
  bool found = false;  ///< this rank found the object (no better rank had)
  /// Not scored: mostly where the labels say nothing (discovery::RankMatch::ignored).
  bool ignored = false;
  double precision = 0.0, recall = 0.0;
};

/// evaluation.json: one scan's ranked hypotheses against its ground truth.
struct Evaluation {
  std::string ground_truth;                   ///< the labelled mesh
  std::optional<std::size_t> objects, found;  ///< unknown only in a damaged or cut file
  double min_iou = 0.7;
  double ap = 0.0;
  std::vector<EvaluatedRank> ranks;
};

// ---- timings.json ------------------------------------------------------------------------------

struct StageTime {
  std::string name;
  double seconds = 0.0;
};

struct FrameCounts {
  std::optional<std::size_t> read, fused, lost, without_depth, unreadable;
};

/// timings.json: what a scan did and how long each stage took.
struct Timings {
  std::string source;
  bool interrupted = false;
  std::vector<std::string> not_produced;  ///< outputs an interrupted scan did not write
  std::vector<StageTime> stages;
  std::optional<double> total_s;
  std::optional<FrameCounts> frames;
  std::optional<std::size_t> mesh_vertices, mesh_faces;
  std::optional<std::size_t> hypotheses;
  std::string sensor_lost;  ///< the error when the sensor stopped mid-capture; empty otherwise
};

// ---- renders/ ----------------------------------------------------------------------------------

/// A PNG picture in memory: the file's bytes and its size.
struct Picture {
  std::string png;
  std::uint32_t width = 0, height = 0;
};

/// renders/overview_camera.json: the overview's camera, so that a script can project into (or
/// render again) the same picture.
struct OverviewCamera {
  std::string view;               ///< "trajectory", "three-quarter" or "top"
  Pose T_W_C = Pose::Identity();  ///< camera x right, y down, z forward, metres
  Intrinsics intrinsics;
};

/// How many of the best hypotheses the pictures paint (and close up) unless told otherwise
/// (render and scan --top); the 3-D views paint as many, in the same colours.
inline constexpr std::size_t kDefaultPaintedTop = 5;

/// renders/: the pictures of the top hypotheses.
struct Pictures {
  std::optional<Picture> overview, overview_ranks, contact_sheet;
  std::map<std::size_t, Picture> closeups;  ///< by rank
  std::optional<OverviewCamera> camera;
  std::vector<std::size_t> visible;  ///< ranks labelled in the overview (not stored in a file)
};

// ---- settings.json -----------------------------------------------------------------------------

/// One option of the command that made the results, by its long flag name, as given or its
/// default: text values; a flag is "true" or "false"; an option with several values has several.
struct OptionSetting {
  std::string name;
  std::vector<std::string> values;
  bool flag = false;
  bool list = false;  ///< takes several values (written as a JSON array)
};

/// settings.json: how the results were made, enough to make them again (`--config`).
struct Settings {
  std::string objscan_version;
  std::string command;  ///< "scan", "discover", "fuse", ...
  std::vector<OptionSetting> options;
  /// Values the command worked out from the options, for an option left to its default (e.g.
  /// "truncation": 3 cm or 3 voxels): the options keep it unset, so that a run repeated with
  /// another voxel size works it out again.
  std::vector<OptionSetting> resolved;
  std::optional<Intrinsics> intrinsics;  ///< of the frames fused
  std::string intrinsics_origin;         ///< where they came from
  std::optional<CatalogUse> catalog;     ///< nothing: no catalog
};

// ---- the folder --------------------------------------------------------------------------------

/// Everything a results folder holds (objscan scan writes all of it; discover, fuse and render
/// parts). Parts not produced (yet) are empty.
struct ScanResults {
  std::optional<TriangleMesh> mesh;      ///< mesh.ply
  std::optional<Trajectory> trajectory;  ///< trajectory.txt
  std::optional<Hypotheses> hypotheses;  ///< hypotheses.json (objects/ holds their sub-meshes)
  std::optional<Evaluation> evaluation;  ///< evaluation.json
  std::optional<Pictures> pictures;      ///< renders/
  std::optional<Timings> timings;        ///< timings.json
  std::optional<Settings> settings;      ///< settings.json
};

}  // namespace objscan::report
