#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"

/// The paper's intrinsic shape measures of a segment (section IV-B) that need no neighbour
/// search: compactness, local convexity and global convexity.
namespace objscan::discovery {

struct Sphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

/// The smallest sphere enclosing the points (Welzl's randomised algorithm, expected linear time;
/// written here because neither Eigen, PCL nor OpenCV has it in 3D). Throws for no points.
Sphere smallestEnclosingSphere(std::vector<Eigen::Vector3d> points);

/// For each vertex, the graph edges that touch it (compressed rows, built once per scene).
struct VertexEdges {
  std::vector<std::size_t> offsets;  ///< vertex v's edges are edges[offsets[v] .. offsets[v+1])
  std::vector<std::int32_t> edges;   ///< indices into MeshGraph::edges
};
VertexEdges vertexEdges(const MeshGraph& graph);

/// Compactness: the area of the segment's triangles (those with all three vertices in it) over
/// the area of its smallest enclosing sphere, 4 pi R^2. 1 for a sphere, 1 / (2 pi) for a square.
double compactness(const TriangleMesh& mesh, const Segment& segment);

/// Local convexity: the share of the segment's edges (both ends in it) that are convex (Eq. 1's
/// predicate); 0 when it has none.
double localConvexity(const MeshGraph& graph, const VertexEdges& by_vertex, const Segment& segment);

/// Global convexity: the mean distance, metres, from the segment's vertices to the surface of
/// their convex hull (Qhull); 0 when every vertex lies on the hull, or the vertices are flat.
double hullDistance(const TriangleMesh& mesh, const Segment& segment);

}  // namespace objscan::discovery
