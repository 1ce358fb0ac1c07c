#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"
#include "objscan/discovery/supports.h"

/// Where a candidate is and how well it was seen: what the paper's five shape measures do not
/// say (its section VI names context as future work). objscan uses it to choose the object set,
/// the hypotheses a user sees first (ObjectSetConfig in discover.h).
namespace objscan::discovery {

/// How a candidate stands in its scene.
enum class Footing : std::uint8_t {
  kNone,     ///< nothing holds it up: a piece of foliage, a fragment of a lamp or a wall's edge
  kSupport,  ///< its lowest part touches a support surface (a table, a shelf board, the floor)
  /// its lowest part rests on another surface facing up, of a candidate that stands itself (an
  /// object under it: a stack) or broad (a counter no support plane found); in a single view any
  /// such surface (ContextConfig::stacks_need_standing_holder)
  kOnSurface,
  /// it lies on a support but rises no more than the support's noise: a patch of the table
  kPatch,
  /// it stands on a support and its top reaches to within 15 cm under another one that covers
  /// it: a table's leg, a shelf's side
  kUnder,
};
/// "none", "support", "surface", "patch", "under".
const char* toString(Footing footing);

struct ContextConfig {
  /// A candidate stands on a support when its lowest vertex lies at most this far above the
  /// support's plane (or on another candidate when that close to it), or `gap_edges` of its own
  /// mean edge length, whichever is larger: the sensor's noise grows with depth, and so do a
  /// single view's edges. Chosen on synthetic scenes (docs/discovery.md, "Object set").
  float gap_m = 0.02f;
  float gap_edges = 3.0f;
  /// ... and lies no further than this below it (noise, and a fold rounded into the support).
  float below_m = 0.02f;
  /// A candidate on a support must rise over its plane by this many times the support's noise
  /// around its foot (SegmentContext::support_noise_m), and by min_rise_m (the hard filter's
  /// least thickness, SegmentFilter::min_thickness_m, measured from the support), or it is a
  /// patch of the support.
  double min_rise_noises = 3.0;
  double min_rise_m = 0.01;

  /// Which way was up for the camera, in the mesh's frame: a hint for gravity. discoverScenes sets
  /// it per scene from SceneInput::view_up. With it, the support plane that faces up (the largest
  /// whose free side lies within `up_hint_deg` of the hint) is the ground, and only the supports
  /// level with it (their free sides within `level_deg` of its) hold candidates up: a table, a
  /// shelf board, the floor; a fragment on a wall or a cupboard's front stands on nothing. Without
  /// the hint, or with no support near it (a camera looking straight down, or at a wall), every
  /// support holds.
  std::optional<Eigen::Vector3f> view_up;
  /// The ground is the largest support whose free side lies within this angle of the hint (a
  /// camera tilted down less than 60 degrees finds the floor or the table; its walls face it at
  /// 90 degrees or more).
  float up_hint_deg = 60.0f;
  /// The supports whose free sides lie within this angle of the ground's hold candidates up.
  float level_deg = 25.0f;
  /// A candidate resting on a surface (Footing::kOnSurface) needs that surface to belong to a
  /// candidate that stands itself (on a support, or on a surface in turn): a leaf resting on a
  /// leaf of a plant stands on nothing. Off: any surface facing up holds it. discoverScenes turns
  /// it off for single views (SceneInput::single_view), where the lower box of a stack often
  /// shows no foot of its own (hidden behind what stands in front of it).
  bool stacks_need_standing_holder = true;
  /// Cut the regions that share_of_region is measured against where a candidate rests on a
  /// surface (Footing::kOnSurface) of another candidate that stands, and is at least a quarter of
  /// its region: the mesh's edges from the foot of its storey (it and the strip of its side its
  /// segment left out) to anything outside the storey. Each storey of a stack is then a region of
  /// its own: a box on a box is all of its region, and the box under it nearly all of its own,
  /// while the pair as one candidate spans two. discoverScenes turns it on for single views
  /// (SceneInput::single_view), where the share weighs most.
  bool split_regions_at_stacks = false;
  /// Measure what floats over each candidate on a support (SegmentContext::covered_share).
  bool judge_cover = true;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// One candidate's context.
struct SegmentContext {
  Footing footing = Footing::kNone;
  /// Height of its lowest vertex above the plane of the support it stands on or, for
  /// kOnSurface and kNone, above the nearest support plane under it; NaN without one.
  double height_m = std::numeric_limits<double>::quiet_NaN();
  /// Its share of the part of the scene it belongs to: the connected region of the mesh off the
  /// supports that holds it (an object alone on a table is all of its region: 1; a leaf of a
  /// plant is a small share of the plant). One that spans regions (ContextConfig::
  /// split_regions_at_stacks) is measured against the region that holds most of it, times the
  /// share of its own vertices that region holds.
  double share_of_region = 0.0;
  /// Mean fusion weight of its vertices over the scene's median vertex weight (1: seen as often
  /// as the scene's typical surface); NaN when the mesh has no weights.
  double observation = std::numeric_limits<double>::quiet_NaN();
  /// Mean length of its mesh edges, metres: its noise scale (a fused mesh's voxel, a single
  /// view's pixel footprint at its depth).
  double mean_edge_m = 0.0;
  /// For one on a support (kSupport, kPatch): its highest vertex over the support's plane, and
  /// the RMS height over that plane of the support's vertices near its foot; NaN otherwise.
  double rise_m = std::numeric_limits<double>::quiet_NaN();
  double support_noise_m = std::numeric_limits<double>::quiet_NaN();
  /// For one on a support (kSupport only, with ContextConfig::judge_cover): what floats over it,
  /// over its own vertex count. Floating: the vertices of the regions off the supports that touch
  /// none, but for its own, within its reach along the support (its farthest vertex from its
  /// middle) and up to 30 cm over its top. A plant's leaves hang over its pot, their stems too thin
  /// for the mesh to hold (5.9 mm voxels): the pot is the base of a larger thing, not an object of
  /// its own. A thing on a thing touches what holds it, so a stack's storey does not float over the
  /// one under it. NaN otherwise.
  double covered_share = std::numeric_limits<double>::quiet_NaN();
};

/// The context of each of `segments` in `mesh` (whose graph is `graph`, cut at the supports or
/// not) with the supports found on it. Parallel (oneTBB). Throws std::invalid_argument when
/// `supports.on_support` does not have one entry per vertex, or a segment indexes outside.
std::vector<SegmentContext> segmentContexts(const TriangleMesh& mesh, const MeshGraph& graph,
                                            const Supports& supports,
                                            const std::vector<Segment>& segments,
                                            const ContextConfig& config = {});

}  // namespace objscan::discovery
