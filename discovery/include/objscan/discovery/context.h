#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"
#include "objscan/discovery/supports.h"

/// Where a candidate is and how well it was seen: what the paper's five shape measures do not
/// say (its section VI names context as future work). objscan uses it to choose the object set,
/// the hypotheses a user sees (objects.h).
namespace objscan::discovery {

/// How a candidate stands in its scene.
enum class Footing : std::uint8_t {
  kNone,       ///< nothing holds it up: a piece of foliage, a fragment of a lamp or a wall's edge
  kSupport,    ///< its lowest part touches a support surface (a table, a shelf board, the floor)
  /// its lowest part rests on another surface facing up: an object under it (a stack), or a
  /// shelf board too small to be a support
  kOnObject,
};
/// "none", "support", "object".
const char* toString(Footing footing);
/// The object set's order of footings: 0 on a support, 1 on another candidate, 2 none. Standing
/// on a support is the strongest evidence of a whole object; a fragment of a plant or of a
/// monitor can rest on the rest of it.
int footingTier(Footing footing);

struct ContextConfig {
  /// A candidate stands on a support when its lowest vertex lies at most this far above the
  /// support's plane (or on another candidate when that close to it), or `gap_edges` of its own
  /// mean edge length, whichever is larger: the sensor's noise grows with depth, and so do a
  /// single view's edges. Chosen on synthetic scenes (docs/discovery.md, "Object set").
  float gap_m = 0.02f;
  float gap_edges = 3.0f;
  /// ... and lies no further than this below it (noise, and a fold rounded into the support).
  float below_m = 0.02f;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// One candidate's context.
struct SegmentContext {
  Footing footing = Footing::kNone;
  /// Height of its lowest vertex above the plane of the support it stands on or, for
  /// kOnObject and kNone, above the nearest support plane under it; NaN without one.
  double height_m = std::numeric_limits<double>::quiet_NaN();
  /// Its share of the part of the scene it belongs to: the connected region of the mesh off the
  /// supports that holds it (an object alone on a table is all of its region: 1; a leaf of a
  /// plant is a small share of the plant).
  double share_of_region = 0.0;
  /// Mean fusion weight of its vertices over the scene's median vertex weight (1: seen as often
  /// as the scene's typical surface); NaN when the mesh has no weights.
  double observation = std::numeric_limits<double>::quiet_NaN();
  /// Mean length of its mesh edges, metres: its noise scale (a fused mesh's voxel, a single
  /// view's pixel footprint at its depth).
  double mean_edge_m = 0.0;
};

/// The context of each of `segments` in `mesh` (whose graph is `graph`, cut at the supports or
/// not) with the supports found on it. Parallel (oneTBB). Throws std::invalid_argument when
/// `supports.on_support` does not have one entry per vertex, or a segment indexes outside.
std::vector<SegmentContext> segmentContexts(const TriangleMesh& mesh, const MeshGraph& graph,
                                            const Supports& supports,
                                            const std::vector<Segment>& segments,
                                            const ContextConfig& config = {});

}  // namespace objscan::discovery
