#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/discover.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scoring.h"

/// What `objscan discover`, `train` and `eval` share: reading scene meshes, finding each one's
/// candidates (or taking them from the catalog), and recurrence against the other scenes.
namespace objscan::app {

struct SceneSetOptions {
  discovery::DiscoveryConfig config;
  /// The catalog file; nothing means no catalog (recurrence then comes from this run's scenes).
  std::optional<std::filesystem::path> catalog;
  /// Read ground-truth labels: each argument must be a labelled scene (see readScenes).
  bool labelled = false;
};

/// One scene of the run.
struct LoadedScene {
  std::filesystem::path argument;  ///< as the user gave it
  std::filesystem::path mesh_path;
  TriangleMesh mesh;
  discovery::SceneCandidates candidates;  ///< recurrence filled in by readScenes
  bool from_catalog = false;              ///< candidates and measures read, not computed
  std::int64_t scene_id = 0;              ///< in the catalog, or the scene's index without one
  /// The ground-truth objects as sets of mesh vertices (labelled runs only).
  std::optional<discovery::GroundTruthObjects> truth;
};

/// The scenes of a run and the normalisation their scores share.
struct SceneSet {
  std::vector<LoadedScene> scenes;
  /// Each measure's mean and spread over the data set: the catalog's segments when there is a
  /// catalog (the paper normalises over its whole data set), else this run's candidates.
  /// Recurrence is normalised over this run's candidates either way.
  discovery::MeasureNormaliser normaliser;
  /// The catalog's scenes and segments measured with this run's settings (those compared and
  /// normalised over); 0 without a catalog.
  std::size_t catalog_scenes = 0, catalog_segments = 0;
};

/// The default catalog: $OBJSCAN_CATALOG, else $XDG_DATA_HOME/objscan/catalog.sqlite, else
/// ~/.local/share/objscan/catalog.sqlite (its folder is created).
std::filesystem::path defaultCatalogPath();

/// Reads each argument, finds its candidates and five measures (or reuses the catalog's for a
/// mesh file whose content and settings it has seen), adds new scenes to the catalog, then
/// computes every candidate's recurrence against all other scenes known (the catalog's, or this
/// run's without one). An argument is a mesh (.ply) or, for discover, a folder holding
/// fused/mesh.ply or mesh.ply. A labelled scene is a folder with scene_gt.ply (objscan synth's
/// ground truth, ids moved onto the fused mesh by the nearest surface within 1 cm) and a fused
/// mesh, or a mesh whose vertices carry object_id. Throws InputError naming the file for a mesh
/// that cannot be used (empty, no faces, NaN, ...).
SceneSet readScenes(const std::vector<std::filesystem::path>& arguments,
                    const SceneSetOptions& options);

/// The object id of each vertex of `mesh`, moved from a ground-truth mesh whose vertices carry
/// object_id (objscan synth's scene_gt.ply) by the nearest surface within 1 cm. Throws InputError
/// naming `truth_path` when it cannot be read or has no ids.
std::vector<std::int32_t> labelsFromTruthMesh(const std::filesystem::path& truth_path,
                                              const TriangleMesh& mesh);

/// The segments a labelled run evaluates or trains on: each scene's candidates after
/// non-maximum suppression by the average score (as the paper's data set holds them), each with
/// its best ground-truth match.
struct LabelledSegments {
  std::vector<discovery::ShapeMeasures> measures;
  std::vector<discovery::ObjectMatch> matches;
  std::vector<std::size_t> scene;  ///< index into SceneSet::scenes

  /// 1 where the match reaches `min_iou` (the paper's object label), else 0.
  std::vector<int> labels(double min_iou) const;
};
LabelledSegments labelledSegments(const SceneSet& set, double max_iou);

}  // namespace objscan::app
