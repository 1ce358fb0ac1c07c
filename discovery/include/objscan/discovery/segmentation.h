#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "objscan/discovery/mesh_graph.h"

/// Felzenszwalb-Huttenlocher graph segmentation ("Efficient graph-based image segmentation",
/// IJCV 2004) on the mesh graph, as the paper uses it (section IV-A).
namespace objscan::discovery {

struct Segmentation {
  float scale = 0.0f;                ///< the k it was made with
  std::vector<std::int32_t> labels;  ///< per vertex, 0 .. segment_count - 1
  std::size_t segment_count = 0;
};

/// Segments at granularity `scale` (FH's k: two components merge across an edge whose weight is
/// at most the smaller of their internal difference plus k / size; a larger k gives larger
/// segments). Then, as in FH's own implementation, every component with fewer than `min_size`
/// vertices is merged across its cheapest edge into a neighbour, edges taken in increasing weight.
/// A group of vertices with no edge to the rest of the mesh stays a segment of its own, whatever
/// its size; so does one whose only edges to the rest have infinite weight (cuts, see
/// cutAtSupports): they are never crossed. Throws std::invalid_argument for a negative or NaN
/// scale.
Segmentation segmentGraph(const MeshGraph& graph, float scale, std::size_t min_size);

/// segmentGraph at each scale, sorting the edges once and running the scales in parallel.
std::vector<Segmentation> segmentAtScales(const MeshGraph& graph, const std::vector<float>& scales,
                                          std::size_t min_size);

}  // namespace objscan::discovery
