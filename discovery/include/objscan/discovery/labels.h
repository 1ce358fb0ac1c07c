#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "objscan/core/triangle_mesh.h"

/// Ground-truth labels for discovery's segments (issue 6, "Labels and evaluation"): object ids
/// moved from a synthetic scene's exact mesh onto the fused mesh, and each segment matched to the
/// ground-truth object it overlaps most.
namespace objscan::discovery {

/// The object id of each vertex of `mesh`: that of the nearest surface of `truth` (whose
/// TriangleMesh::labels hold per-vertex ids, 0 = not an object) when it lies within
/// `max_distance_m`, else 0. Throws std::invalid_argument when `truth` has no labels or no
/// triangles. Runs in parallel.
std::vector<std::int32_t> transferLabels(const TriangleMesh& mesh, const TriangleMesh& truth,
                                         float max_distance_m = 0.01f);

/// How a fused mesh was laid onto its ground truth (alignToTruth).
struct TruthAlignment {
  Eigen::Isometry3f T_truth_mesh = Eigen::Isometry3f::Identity();  ///< mesh frame -> truth's
  /// How far the motion moves the mesh: the RMS of |T p - p| over the picked vertices (the
  /// translation alone would count the turn's lever arm from the world's origin).
  float moved_m = 0.0f;
  float rms_before_m = 0.0f;  ///< RMS distance of the paired vertices to the truth, unmoved
  float rms_after_m = 0.0f;   ///< the same, moved
  std::size_t samples = 0;    ///< vertices picked
  std::size_t pairs = 0;      ///< of them, within reach of the truth at the end
  int iterations = 0;         ///< steps taken
  bool converged = false;     ///< the last step moved less than the stopping test's bounds
};

/// The rigid motion that lays `mesh` onto the surface of `truth` (both in metres): point-to-plane
/// ICP from the identity on at most 5,000 evenly picked vertices, each paired with the closest
/// point of `truth` within `reach_m`, each step a damped linear least-squares solve, until a
/// step moves less than 0.01 mm and 0.001 degrees (at most 30 steps). A fusion drifts and its
/// sensor's depth is biased, so its map is displaced from the truth by millimetres to
/// centimetres, as much as a small object is wide; evaluations of reconstructions align first
/// for the same reason (TUM's ATE, Horn). Throws std::invalid_argument when `truth` has no
/// triangles or fewer than 100 picked vertices lie within reach.
TruthAlignment alignToTruth(const TriangleMesh& mesh, const TriangleMesh& truth,
                            float reach_m = 0.02f);

/// A hand-labelled fusion's labels moved onto another fusion of the same frames: each vertex
/// takes the label and ignore flag of the nearest labelled vertex within this distance (1.5 cm,
/// as the labels of ../shared/data/tum_fr2_desk_50/objects/ are meant to be moved).
inline constexpr float kLabelledMeshDistanceM = 0.015f;

struct LabelTransfer {
  std::vector<std::int32_t> labels;
  /// 1 where the labels say nothing, or no labelled vertex is near.
  std::vector<std::uint8_t> ignore;
  std::size_t unmatched = 0;  ///< vertices with no labelled vertex near
};
/// Per vertex of `mesh`, the label and ignore flag (TriangleMesh::ignore; 0 when `truth` has
/// none) of `truth`'s nearest vertex within `max_distance_m`; ignored where none is that near.
/// Throws std::invalid_argument when `truth` has no labels. Runs in parallel.
LabelTransfer transferVertexLabels(const TriangleMesh& mesh, const TriangleMesh& truth,
                                   float max_distance_m = kLabelledMeshDistanceM);

struct ObjectMatch {
  std::int32_t object_id = 0;  ///< 0 when the segment touches no object vertex
  double iou = 0.0;            ///< vertex-set intersection over union with that object
};

/// The ground-truth objects of one scene mesh, as sets of its vertices.
class GroundTruthObjects {
 public:
  /// `vertex_labels`: an object id per vertex of the scene mesh (0 = none), e.g. from
  /// transferLabels or a mesh's own `object_id` property. Ids must lie in 0..1,000,000
  /// (std::invalid_argument otherwise). `ignore` (empty, or one flag per vertex): 1 where the
  /// labels say nothing (a hand-labelled scene's lamp or plant, the band where an object meets
  /// the table): such vertices count in no object and in no hypothesis.
  explicit GroundTruthObjects(std::vector<std::int32_t> vertex_labels,
                              std::vector<std::uint8_t> ignore = {});

  /// The object whose vertex set has the highest IoU with `vertices` (increasing indices),
  /// ignored vertices left out of both.
  ObjectMatch bestMatch(const std::vector<std::int32_t>& vertices) const;

  /// The share of `vertices` that are ignored (0 without an ignore mask).
  double ignoredShare(const std::vector<std::int32_t>& vertices) const;
  bool hasIgnored() const { return !ignore_.empty(); }

  /// The ids of the objects with at least one vertex, increasing.
  std::vector<std::int32_t> objectIds() const;
  /// How many vertices carry `id` (0 for an unknown id).
  std::size_t objectSize(std::int32_t id) const;
  const std::vector<std::int32_t>& vertexLabels() const { return labels_; }

 private:
  std::vector<std::int32_t> labels_;
  bool ignored(std::size_t v) const { return !ignore_.empty() && ignore_[v] != 0; }

  std::vector<std::uint8_t> ignore_;
  std::vector<std::size_t> sizes_;  ///< by id, ignored vertices left out
};

/// The paper's label (section IV-C): a segment is an object when its IoU with one ground-truth
/// object reaches `min_iou` (0.7 by default; evaluation also reports 0.5 and 0.8).
inline bool isObject(const ObjectMatch& match, double min_iou = 0.7) {
  return match.object_id != 0 && match.iou >= min_iou;
}

}  // namespace objscan::discovery
