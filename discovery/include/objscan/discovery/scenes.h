#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/core/intrinsics.h"
#include "objscan/core/organized_cloud.h"
#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/discover.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scoring.h"

/// Discovery for a user: scenes (meshes in memory) and a catalog of the scenes seen before, to
/// ranked hypotheses. The one entry point `objscan discover`, `eval`, `train` and `scan`, the
/// tests and the benches run: each scene's candidates and five measures (or the catalog's for a
/// scene it has seen with these settings), new scenes added to the catalog, recurrence against
/// every other scene known, the measures normalised over the data set, scores and suppression.
namespace objscan::discovery {

/// One scene to find objects in.
struct SceneInput {
  /// Where the mesh came from: the mesh file as the user named it (hypotheses.json's "scene"),
  /// or a label for a mesh that has no file.
  std::string name;
  TriangleMesh mesh;  ///< with normals; loadScene computes those a file lacks
  /// The content hash of the mesh file's bytes (contentHash), by which the catalog knows a scene
  /// it has seen; empty: the catalog neither looks it up nor keeps it.
  std::string content_hash;
  /// The ground-truth objects, for labelled runs (eval, train).
  std::optional<GroundTruthObjects> truth;
  /// Where the truth has objects made of parts (a PCD's labels 10 k + p): each object whole,
  /// reported beside the parts.
  std::optional<GroundTruthObjects> whole_objects;
  /// Which way was up for the camera, in the mesh's frame (ContextConfig::view_up): a single
  /// view's -y, a fused scan's viewUp of its trajectory; nothing when unknown.
  std::optional<Eigen::Vector3f> view_up;
  /// A camera's single view (a point cloud or a frame, meshed by joining pixels), not a fused
  /// mesh: its objects' feet were not rounded by fusion (SupportConfig::trim_feet is off for it).
  bool single_view = false;
};

/// How loadScene reads a scene.
struct SceneReading {
  /// Also the ground truth: scene_gt.ply in a scene folder, the mesh's own object_id, or a PCD's
  /// label field (each object part an object; SceneInput::whole_objects merges the parts).
  bool labelled = false;
  /// With `labelled`: lay the fused mesh of a scene folder onto the folder's scene_gt.ply before
  /// the labels move onto it (truthFromMesh's `align`). A scene whose labels are its own (a
  /// mesh's object_id, a PCD's label field) has nothing to be aligned to: a warning says so.
  bool align_truth = false;
  /// The file's content hash for the catalog (a run without one need not read the file twice).
  bool hash = true;
  /// The camera of an unorganized PCD (its points are put back on this pixel grid); nothing: the
  /// pinhole that fits its points (fitPinhole), and a clear refusal when none does.
  std::optional<Intrinsics> intrinsics;
  std::string intrinsics_origin;  ///< where `intrinsics` came from (a file), for messages
  /// How a PCD's pixels are joined into a mesh.
  OrganizedMeshConfig meshing;
  /// Which way is up in the scene's frame (`--up`), replacing what the scene says (its camera's
  /// -y, or the view up of the camera path beside a mesh): for a mesh from another tool, in a
  /// frame whose up the user knows.
  std::optional<Eigen::Vector3f> view_up;
};

/// Throws std::runtime_error, with the estimate, the memory free and what to change, when
/// discovering `inputs` would not fit in memory (availableMemoryBytes): 1 kB per vertex of the
/// largest scene and 150 bytes per vertex of all, measured (scenes.cpp). discoverScenes calls it
/// first; a command calls it before it makes its output folder.
void requireMemoryFor(const std::vector<SceneInput>& inputs);

/// Reads a scene as the command line names it: a mesh file (.ply), a folder holding
/// fused/mesh.ply or mesh.ply, or a camera's point cloud (.pcd, organized or put back on its
/// pixel grid), meshed by joining neighbouring pixels (meshOrganized). A mesh's view up comes from
/// the camera path objscan writes beside it (trajectory.txt, TUM format), when there is one and
/// it reads; a cloud's is its camera's -y. Throws InputError naming
/// the file for a scene that cannot be used (missing, truncated, corrupt, empty, no faces, NaN,
/// an unorganized cloud with no camera that fits it, ...) or a labelled scene without labels.
SceneInput loadScene(const std::filesystem::path& argument, const SceneReading& reading = {});

/// A single view as a scene: the organized cloud meshed (meshOrganized), its labels (when it has
/// them) as the ground truth of `labelled`, named `name`. Throws InputError naming `name` when it
/// has no surface to discover objects on.
SceneInput sceneFromCloud(std::string name, const OrganizedCloud& cloud, bool labelled,
                          const OrganizedMeshConfig& meshing = {});

/// A scene input made from a mesh in memory (normals computed if missing), checked as loadScene
/// checks a file; `content_hash` as contentHash gives it for the bytes of the mesh's file.
/// Throws std::invalid_argument for a mesh discovery cannot use.
SceneInput sceneFromMesh(std::string name, TriangleMesh mesh, std::string content_hash = {});

/// The ground-truth objects of `mesh` from a labelled mesh of the same scene in the same frame:
/// objscan synth's scene_gt.ply (per-vertex object_id; each vertex takes the id of the nearest
/// surface within 1 cm), or a hand-labelled fusion with per-vertex label and ignore flags (each
/// vertex takes both from the nearest labelled vertex within kLabelledMeshDistanceM, and is
/// ignored where there is none). With `align`, `mesh` is first laid onto the truth's surface by
/// alignToTruth, and a line says how far it moved. Throws InputError naming `truth_path` when it
/// cannot be read, has no ids, or (with `align`) has too little near the mesh to align it.
GroundTruthObjects truthFromMesh(const std::filesystem::path& truth_path, const TriangleMesh& mesh,
                                 bool align = false);

/// The default catalog: $OBJSCAN_CATALOG, else $XDG_DATA_HOME/objscan/catalog.sqlite, else
/// ~/.local/share/objscan/catalog.sqlite (its folder is created).
std::filesystem::path defaultCatalogPath();

struct SceneDiscoveryOptions {
  DiscoveryConfig config;
  /// The catalog file; nothing: no catalog (recurrence then comes from this run's scenes, and the
  /// measures are normalised over them).
  std::optional<std::filesystem::path> catalog;
  /// Scores from a classifier (objscan train's); nothing: the average of the normalised measures.
  std::optional<ObjectnessModel> model;
  /// The label of the progress bar over the scenes ("" for none).
  std::string progress_label = "finding candidates";
};

/// One scene of a run, with what discovery made of it.
struct DiscoveredScene {
  std::string name;  ///< SceneInput::name
  TriangleMesh mesh;
  std::string content_hash;    ///< its catalog key: SceneInput::content_hash and the camera's up
  SceneCandidates candidates;  ///< recurrence filled in
  bool from_catalog = false;   ///< candidates and measures read from the catalog, not computed
  std::int64_t scene_id = 0;   ///< in the catalog, or the scene's index without one
  std::optional<GroundTruthObjects> truth;          ///< labelled runs only
  std::optional<GroundTruthObjects> whole_objects;  ///< SceneInput::whole_objects
  std::optional<Eigen::Vector3f> view_up;           ///< SceneInput::view_up
  bool single_view = false;                         ///< SceneInput::single_view
  std::size_t hypotheses = 0;  ///< how many of SceneDiscovery::ranked are this scene's
};

/// A hypothesis of a run: the scene it is in (index into SceneDiscovery::scenes) and itself.
struct RankedHypothesis {
  std::size_t scene = 0;
  Hypothesis hypothesis;
};

/// What discoverScenes found.
struct SceneDiscovery {
  std::vector<DiscoveredScene> scenes;
  /// Each measure's mean and spread over the data set: the catalog's segments when there is a
  /// catalog (the paper normalises over its whole data set), else this run's candidates.
  /// Recurrence is normalised over this run's candidates either way.
  MeasureNormaliser normaliser;
  /// The catalog used, and its scenes and segments measured with this run's settings (those
  /// compared and normalised over); 0 without a catalog.
  std::optional<std::filesystem::path> catalog;
  std::size_t catalog_scenes = 0, catalog_segments = 0;
  std::vector<RankedHypothesis> ranked;  ///< best first, over all scenes
  ScoreKind scorer = ScoreKind::kAverage;
  /// What the scores' normalisation came from: "the model's training segments", "catalog" or
  /// "these scenes" (hypotheses.json's scoring.normalised_over).
  std::string normalised_over;
  double seconds = 0.0;  ///< wall time of the whole call
};

/// Finds the candidates of every scene (or takes them from the catalog), adds new scenes to the
/// catalog, computes recurrence against every other scene known, normalises, scores with the
/// model (or the average), suppresses overlaps within each scene and ranks all hypotheses best
/// first. Throws std::invalid_argument for a bad config or a mesh discovery cannot use, InputError
/// naming the catalog when it is damaged.
SceneDiscovery discoverScenes(std::vector<SceneInput> scenes, const SceneDiscoveryOptions& options);

/// The segments people labelled object (1) or not (0) in a catalog (objscan view), among the
/// scenes measured with `config`'s settings, with recurrence computed against every other such
/// scene and the normaliser discoverScenes would use with this catalog (the five measures' over
/// its segments of these settings, recurrence's over the labelled scenes' segments); unsure labels
/// are left out (counted). Every labelled segment of the catalog is counted once: in `labels`,
/// `unsure` or `other_settings`.
struct CatalogTrainingSet {
  MeasureNormaliser normaliser;
  std::vector<ShapeMeasures> measures;  ///< recurrence filled in
  std::vector<int> labels;              ///< 1 object, 0 not
  std::vector<std::int64_t> segment_ids;
  std::vector<std::size_t> scene_of;  ///< per row, its scene (0 to scenes - 1)
  std::size_t scenes = 0;  ///< scenes with at least one label used
  std::size_t unsure = 0;  ///< left out: unsure
  /// Left out: labelled segments of scenes measured with other settings.
  std::size_t other_settings = 0;
};
/// Throws InputError naming the catalog when it does not exist or is damaged,
/// std::invalid_argument for a bad config. Writes nothing of its own; opening a catalog of schema
/// version 1 upgrades it, as any Catalog does.
CatalogTrainingSet catalogTrainingSet(const std::filesystem::path& catalog,
                                      const DiscoveryConfig& config);

/// The segments a labelled run evaluates or trains on: each scene's candidates after
/// non-maximum suppression by the average score (as the paper's data set holds them), scene by
/// scene, each with its best ground-truth match. Every scene must carry its truth.
struct LabelledSegments {
  std::vector<ShapeMeasures> measures;
  std::vector<ObjectMatch> matches;
  std::vector<std::size_t> scene;  ///< index into SceneDiscovery::scenes

  /// 1 where the match reaches `min_iou` (the paper's object label), else 0.
  std::vector<int> labels(double min_iou) const;
};
LabelledSegments labelledSegments(const SceneDiscovery& discovery, double max_iou);

/// One ground-truth object of a labelled run and how well the run cut it out.
struct ObjectRecall {
  std::size_t scene = 0;  ///< index into SceneDiscovery::scenes
  std::int32_t object_id = 0;
  std::size_t vertices = 0;          ///< the object's vertices on the scene mesh
  double best_candidate_iou = 0.0;   ///< of any candidate (after the filters)
  double best_hypothesis_iou = 0.0;  ///< of any of `kept` (after suppression)
};
/// Object recall: every ground-truth object of every scene, by scene and id.
std::vector<ObjectRecall> objectRecall(const SceneDiscovery& discovery,
                                       const LabelledSegments& kept);

/// How well one scene's ranked hypotheses (SceneDiscovery::ranked, as discover hands them out)
/// find its ground-truth objects: evaluateRanking at IoU 0.5 and 0.7.
struct SceneRecall {
  std::size_t scene = 0;                    ///< index into SceneDiscovery::scenes
  std::size_t objects = 0;                  ///< ground-truth objects with at least one vertex
  double recall_05 = 0.0, recall_07 = 0.0;  ///< objects found / objects
  double ap_05 = 0.0, ap_07 = 0.0;          ///< averagePrecisionOfRanking
};
/// Every labelled scene's figures; with `whole_objects`, against DiscoveredScene::whole_objects
/// where a scene has them (its truth elsewhere).
std::vector<SceneRecall> sceneRecall(const SceneDiscovery& discovery, bool whole_objects = false);

/// One scene on its own, through discoverScenes (no catalog, the average score): its hypotheses
/// best first, empty when it has no object candidates. With `timings`, where the scene's time
/// went. Throws std::invalid_argument for a bad config or a mesh discovery cannot use.
std::vector<Hypothesis> discoverObjects(const TriangleMesh& mesh, const DiscoveryConfig& config,
                                        DiscoveryTimings* timings = nullptr);

}  // namespace objscan::discovery
