#pragma once

#include <cstddef>
#include <vector>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"
#include "objscan/discovery/shape_measures.h"

/// One scene mesh to ranked object hypotheses: the paper's section IV without recurrence (which
/// needs the catalog of other scenes) and with the unsupervised score.
namespace objscan::discovery {

struct DiscoveryConfig {
  /// Felzenszwalb-Huttenlocher granularities: ten doublings from 5. Chosen on the fused TUM
  /// desk (5.86 mm voxels, 207 k vertices, the paper's density): below 5 the segments barely
  /// change, above 2560 objects are merged with their supports. Not yet scaled with density.
  std::vector<float> scales = {5, 10, 20, 40, 80, 160, 320, 640, 1280, 2560};
  std::size_t min_size = 500;  ///< the paper's m_size, at its density
  SegmentFilter filter;
  double max_iou = 0.7;
  float symmetry_beta = 0.2f;
  float smoothness_radius_m = 0.01f;
  int smoothness_bins = 8;
};

struct Hypothesis {
  Segment segment;
  ShapeMeasures measures;
  double score = 0.0;  ///< mean of the measures z-normalised over the scene's candidates
};

struct DiscoveryTimings {
  double graph_ms = 0.0, segment_ms = 0.0, filter_ms = 0.0, measure_ms = 0.0, suppress_ms = 0.0;
};

/// The five shape measures of one segment.
ShapeMeasures measureSegment(const TriangleMesh& mesh, const MeshGraph& graph,
                             const VertexEdges& by_vertex, const Segment& segment,
                             const DiscoveryConfig& config);

/// Unsupervised objectness: each measure z-normalised over `all` (oriented so that higher is
/// more object-like: symmetry and the hull distance are negated), then averaged. The paper
/// normalises over its whole data set; until the catalog exists, over this scene's candidates.
std::vector<double> averageScores(const std::vector<ShapeMeasures>& all);

/// Segments at every scale, filters, measures, scores, suppresses overlaps; the hypotheses best
/// first. An empty result means no object candidates. Throws std::invalid_argument for a mesh
/// that fails validate() or has no normals.
std::vector<Hypothesis> discoverObjects(const TriangleMesh& mesh, const DiscoveryConfig& config,
                                        DiscoveryTimings* timings = nullptr);

}  // namespace objscan::discovery
