#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/context.h"
#include "objscan/discovery/convexity.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/recurrence.h"
#include "objscan/discovery/scoring.h"
#include "objscan/discovery/segment.h"
#include "objscan/discovery/shape_measures.h"
#include "objscan/discovery/supports.h"

/// One scene mesh to ranked object hypotheses (the paper's section IV): graph, segmentation at
/// several scales, hard filters, the five shape measures (findCandidates); recurrence against
/// other scenes (addRecurrence); scores and non-maximum suppression (rankCandidates).
namespace objscan::discovery {

/// The object set: objscan's answer to "which objects are on this desk", beside the paper's ranked
/// list of overlapping hypotheses. Every candidate gets an object score (its score weighed by its
/// evidence, its share of its region and how it stands: SegmentContext), and candidates are
/// taken greedily by it: one joins when at most max_taken_share of its vertices belong to those
/// taken before (those few are then left out of it), so every surface region belongs to at most
/// one object. The other hypotheses (non-maximum suppression at max_iou, as the paper's) follow
/// as alternatives. docs/discovery.md, "Object set", says why and what it was chosen on.
struct ObjectSetConfig {
  bool enabled = true;    ///< off: the paper's list (rankCandidates')
  ContextConfig context;  ///< how footings are judged
  /// Evidence: with f = n / (n + evidence_vertices), n its vertex count, a positive score is
  /// multiplied by f and a negative one divided by it: the measures of a blob of a few dozen
  /// vertices, a few noise lengths across, say little, so it ranks lower either way. Vertices at
  /// the reference density (scaled as min_size is).
  std::size_t evidence_vertices = 100;
  /// On a fused mesh (SegmentContext::observation known), n counts each vertex by how well it was
  /// seen: n times min(1, observation), so a fragment seen a tenth as often as the scene's typical
  /// surface (the edge of the scan, a glimpse through a gap) is a tenth of the evidence. Off:
  /// vertices count alike.
  bool weigh_by_observation = true;
  /// Plus this weight times ln(share of its region) (SegmentContext::share_of_region, at least
  /// 0.001): a fragment of something larger (a leaf of a plant, the base of a lamp) scores lower
  /// than a whole thing standing alone (with weight 0.1: -0.23 for a tenth of its region, -0.46
  /// for a hundredth).
  double region_share_weight = 0.1;
  /// discoverScenes uses this region share weight for single views (SceneInput::single_view). A
  /// camera's view breaks its mesh at every depth edge, so a thing in front of another is a region
  /// of its own, and a small share says more than on a fused mesh, whose surfaces join whatever
  /// touches them. Chosen on synthetic single views of hard clutter (weights 0.1 to 1.0: 0.7 and
  /// 1.0 alike); on fused scenes of such clutter 0.5 lost AP (docs/discovery.md, "Single views
  /// of clutter").
  double single_view_region_share_weight = 0.7;
  /// Less these, in the score's units, for a candidate that stands on another surface rather
  /// than a support (Footing::kOnSurface), and for one that stands on nothing, is a patch of a
  /// support or reaches up to one (Footing::kNone, kPatch, kUnder).
  double on_surface_penalty = 0.3;
  double floating_penalty = 1.0;
  /// discoverScenes uses this floating penalty for single views (SceneInput::single_view): one
  /// view often hides where a thing meets its support, and a fused mesh, seen from around, less
  /// so. Chosen on synthetic fused scenes (1.0) and on mOSD learn (0.6); docs/discovery.md.
  double single_view_floating_penalty = 0.6;
  /// Less this for a candidate on a support with surface floating over it (SegmentContext::
  /// covered_share): in part from a tenth of its own vertex count, in full from four tenths. A
  /// pot under its plant's leaves is the base of a larger thing. Chosen on fused synthetic table
  /// tops, and kept in single views (docs/discovery.md, "What floats over a pot").
  double covered_penalty = 1.0;
  /// The share of a candidate's vertices that objects before it may already hold.
  double max_taken_share = 0.1;
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

struct DiscoveryConfig {
  /// Felzenszwalb-Huttenlocher granularities k at the reference density: ten doublings from 5.
  /// Chosen on the fused TUM desk (5.86 mm voxels, the paper's density): below 5 the segments
  /// barely change, above 2560 objects merge with their supports.
  std::vector<float> scales = {5, 10, 20, 40, 80, 160, 320, 640, 1280, 2560};
  std::size_t min_size = 500;  ///< the paper's m_size (section IV-A), at the reference density
  /// Scale min_size and the scales with the mesh's vertex density: both count vertices, so a mesh
  /// with twice the vertices per square metre gets twice the values and the same segments in
  /// metres. The density is read as (reference_spacing_m / median edge length)^2.
  bool scale_with_density = true;
  /// Median edge length of a mesh at the paper's density: marching cubes on KinFu's 3 m / 512
  /// voxels (5.86 mm), measured on objscan fuse's meshes of TUM fr2/desk and the synthetic scenes.
  float reference_spacing_m = 0.00587f;
  /// Cut the mesh at its support surfaces before segmenting (objscan's extension; see
  /// supports.h). Off: the paper's segmentation.
  SupportConfig supports;
  /// A second pool of candidates: convexity segmentations (objscan's extension; see
  /// convexity.h). Off: the paper's FH scales only.
  ConvexityConfig convexity;
  SegmentFilter filter;
  double max_iou = 0.7;               ///< the paper's non-maximum suppression threshold
  float symmetry_beta = 0.2f;         ///< the paper's beta (section IV-B)
  float smoothness_radius_m = 0.01f;  ///< the paper's r
  int smoothness_bins = 8;            ///< the paper's b
  ObjectSetConfig objects;
  int recurrence_neighbours = kRecurrenceNeighbours;   ///< the paper's k = 10
  double recurrence_window = kRecurrenceExtentWindow;  ///< the paper's 25 %

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// The settings that change a scene's candidates and measures, as a short string: the catalog
/// recomputes a scene seen with different settings.
std::string settingsKey(const DiscoveryConfig& config);

/// min_size, scales and the support size for `mesh` (the config's without scale_with_density).
struct EffectiveScales {
  std::vector<float> scales;
  std::size_t min_size = 0;
  std::size_t support_min_vertices = 0;
  /// The smallest candidate: min_size, or with supports the smaller min_cut_off_size (segments
  /// under min_size exist only where segmentation could not merge them).
  std::size_t candidate_min_size = 0;
  std::size_t evidence_vertices = 0;  ///< ObjectSetConfig::evidence_vertices, scaled
  std::size_t foot_trim_vertices = 0;  ///< SupportConfig::foot_trim_vertices, scaled
  std::size_t top_min_vertices = 0;    ///< SupportConfig::top_min_vertices, scaled
  double median_edge_m = 0.0;
};
EffectiveScales effectiveScales(const MeshGraph& graph, const TriangleMesh& mesh,
                                const DiscoveryConfig& config);

struct Hypothesis {
  Segment segment;
  ShapeMeasures measures;
  double score = 0.0;  ///< the objectness score (model or average): higher is more object-like
  SegmentContext context;
  /// What the object set is chosen by (ObjectSetConfig): the score weighed by the evidence and
  /// the region share, less the footing's penalty; NaN when the object set is off.
  double object_score = std::numeric_limits<double>::quiet_NaN();
  /// Its place in its scene's object set (1 = first), 0 for an alternative. An object's segment
  /// may be its candidate less a few vertices that an object before it holds.
  std::size_t object_rank = 0;
};

/// CPU time, milliseconds, of each of the five measures that measureSegment computes, in
/// kMeasureNames' order (recurrence excluded).
using MeasureCpuMs = std::array<double, 5>;

/// Where a discoverObjects call spent its time, and how much it found.
struct DiscoveryTimings {
  /// Wall-clock time of each stage, milliseconds.
  double graph_ms = 0.0, support_ms = 0.0, segment_ms = 0.0, filter_ms = 0.0, measure_ms = 0.0,
         suppress_ms = 0.0;
  /// CPU time of the whole process (all threads) during each stage, milliseconds.
  double graph_cpu_ms = 0.0, support_cpu_ms = 0.0, segment_cpu_ms = 0.0, filter_cpu_ms = 0.0,
         measure_cpu_ms = 0.0, suppress_cpu_ms = 0.0;
  /// Each measure's CPU time, milliseconds: its thread time summed over the distinct candidates
  /// (a segment that several scales produce is measured once), plus the per-scene look-up it
  /// needs (compactness: the triangle index; smoothness: the tangent neighbours; local
  /// convexity: the vertex-edge index).
  MeasureCpuMs per_measure_cpu_ms{};
  /// Segments that passed the filters, repeats across scales included (distinct ones: fewer).
  std::size_t candidate_count = 0;
};

/// The five shape measures of one segment. `lookups` must have been built for `mesh` and `graph`,
/// its tangent neighbours for every vertex of `segment`, with the config's smoothness radius and
/// bins. With `cpu_ms`, each measure's CPU time on the calling thread is added to it.
ShapeMeasures measureSegment(const TriangleMesh& mesh, const MeshGraph& graph,
                             const SceneLookups& lookups, const Segment& segment,
                             const DiscoveryConfig& config, MeasureCpuMs* cpu_ms = nullptr);

/// The five measures of each of one scene's candidates (in their order), as measureSegment gives
/// them: the scene's look-ups built once, a segment that several scales produce measured once,
/// the segments in parallel (oneTBB), largest first. With `cpu_ms`, each measure's CPU time (with
/// the look-up it needs) is added to it.
std::vector<ShapeMeasures> measureCandidates(const TriangleMesh& mesh, const MeshGraph& graph,
                                             const std::vector<Segment>& candidates,
                                             const DiscoveryConfig& config,
                                             MeasureCpuMs* cpu_ms = nullptr);

/// Unsupervised objectness over one set of candidates: each measure z-normalised over `all`
/// (oriented so that higher is more object-like), then the varying ones averaged.
std::vector<double> averageScores(const std::vector<ShapeMeasures>& all);

/// One scene's candidate segments (those that pass the hard filters, from every scale; a segment
/// that several scales produce once, at the finest of them) and their measures; recurrence NaN
/// until addRecurrence.
struct SceneCandidates {
  std::vector<Segment> segments;
  std::vector<ShapeMeasures> measures;
  std::vector<SegmentContext> context;  ///< one per segment
  DiscoveryTimings timings;
  EffectiveScales effective;         ///< the min_size and scales used, and the mesh's median edge
  std::size_t support_planes = 0;    ///< planes with support regions (none when disabled)
  std::size_t support_vertices = 0;  ///< vertices on them and on their folds
};

/// Graph, supports (unless disabled), segmentation at every scale, filters and the five shape
/// measures. Throws
/// std::invalid_argument for a bad config or a mesh that fails validate() or has no normals.
SceneCandidates findCandidates(const TriangleMesh& mesh, const DiscoveryConfig& config);

/// Fills `candidates.context` (and `effective`): for candidates the catalog held, which it keeps
/// without their context. Builds the graph and finds the supports again.
void addContext(const TriangleMesh& mesh, SceneCandidates& candidates,
                const DiscoveryConfig& config);

/// Fills each candidate's recurrence against the index's segments of scenes other than
/// `scene_id` (NaN where none is within the extent window).
void addRecurrence(SceneCandidates& candidates, const RecurrenceIndex& index, std::int64_t scene_id,
                   const DiscoveryConfig& config);

/// Scores every candidate with `model`, suppresses overlaps (vertex IoU above `max_iou`, the
/// better score kept) and returns the hypotheses best first.
std::vector<Hypothesis> rankCandidates(const SceneCandidates& candidates,
                                       const ObjectnessModel& model, double max_iou);

/// A scene's hypotheses as a user gets them: its object set (ObjectSetConfig), then the
/// alternatives rankCandidates keeps that are not in it, by score. With the object set off,
/// rankCandidates' list. `candidates.context` must hold one entry per segment.
std::vector<Hypothesis> rankObjects(const TriangleMesh& mesh, const SceneCandidates& candidates,
                                    const ObjectnessModel& model, const DiscoveryConfig& config);

}  // namespace objscan::discovery
