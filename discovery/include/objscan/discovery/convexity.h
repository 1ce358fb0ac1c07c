#pragma once

#include <cstdint>
#include <vector>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segmentation.h"

/// Convexity segmentation: objscan's second pool of candidates beside the paper's FH scales (on by
/// default, off with --paper-segmentation). The idea is PCL's LCCP (Stein et al., CVPR 2014):
/// objects are convex where their surfaces meet and meet each other and their supports in concave
/// folds; so the surface is cut into small patches, neighbouring patches are joined unless they
/// meet concavely, and each connected set of joined patches is a segment.
///
/// Written here rather than taken from PCL's LCCP because the mesh already says which patches
/// touch: LCCP finds supervoxel neighbours by voxel adjacency, which joins surfaces across a depth
/// jump (a box in front of another); the mesh's edges never cross one (meshOrganized cuts them,
/// and fusion leaves free space between surfaces). Patch normals are fitted to the patch's
/// vertices, so they do not depend on the per-vertex normals' noise on a single view.
namespace objscan::discovery {

struct ConvexityConfig {
  bool enabled = true;
  /// Patches: the connected pieces of the mesh within each cell of a grid of this size. One
  /// segmentation per size; small patches find small objects, large ones steadier normals.
  std::vector<float> patch_sizes_m = {0.015f, 0.03f};
  /// Two neighbouring patches whose normals differ by less than this are joined whatever their
  /// convexity (sensor noise makes flat surfaces slightly concave here and there); LCCP's
  /// concavity tolerance. One segmentation per tolerance and patch size.
  std::vector<float> tolerances_deg = {10.0f, 20.0f};
  /// A patch never crosses a mesh edge whose two vertex normals meet concavely at more than this
  /// angle (degrees; 0: patches are the cells' connected pieces, whatever their shape), and a
  /// patch too small to fit a normal is not joined across one either. Without it, a cell that
  /// holds a crease, where two touching objects meet or an object meets its table, makes one
  /// patch of both sides, and its fitted normal, between the two, can join both. 20 degrees, the
  /// larger tolerance, chosen rather than tuned. Fused meshes only (DiscoveredScene's configOf
  /// sets 0 for single views, whose per-vertex normals are too noisy: it cost mOSD learn 0.03
  /// AP@0.5).
  float crease_deg = 20.0f;
  /// A patch fits its normal only from this many vertices; smaller ones join the neighbour they
  /// share the most edges with.
  int min_patch_vertices = 6;
  /// Colour cuts (off by default; `--color-cuts` gives {20}), for touching objects that meet flat
  /// or convexly (a lid on a jar): for each entry, one more segmentation per patch size and
  /// tolerance in which two patches the geometry would join stay apart when both are plain and
  /// their colours differ by more than the entry. A patch is plain when its vertices' colours lie
  /// within the entry of its mean (RMS), so a print on a box does not cut the box into pieces.
  /// Colours are compared in CIE L*a*b* with the lightness scaled by colour_lightness_weight
  /// (shading and shadows change lightness more than hue). Empty, or a mesh without colours:
  /// geometry only. Off by default because the cut is fragile: a patch that straddles the colour
  /// edge holds both colours, is not plain, and joins both sides, so whether two objects come
  /// apart hangs on a few borderline patches (docs/discovery.md, "Colour cuts").
  std::vector<float> colour_limits = {};
  /// What L* is multiplied by before colours are compared: 0.5 (chosen, not tuned; full weight was
  /// no better on the tuning views).
  float colour_lightness_weight = 0.5f;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// The convexity segmentations of `mesh` (graph: its edges), one per patch size and tolerance, as
/// per-vertex labels. Vertices with `excluded` set (support surfaces) are never joined to others:
/// each is a segment of its own. `excluded` is empty or has one entry per vertex.
std::vector<Segmentation> convexSegmentations(const TriangleMesh& mesh, const MeshGraph& graph,
                                              const std::vector<std::uint8_t>& excluded,
                                              const ConvexityConfig& config);

}  // namespace objscan::discovery
