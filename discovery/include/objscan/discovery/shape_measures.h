#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"
#include "objscan/discovery/segment.h"

/// The paper's five intrinsic shape measures of a segment (section IV-B): compactness, symmetry,
/// smoothness, local convexity and global convexity.
namespace objscan::discovery {

/// The paper's six objectness measures of one segment, raw (not normalised). Each is oriented as
/// the paper defines it; orientedMeasures() turns them so that higher is more object-like.
struct ShapeMeasures {
  double compactness = 0.0;
  double symmetry = 0.0;  ///< a distance: lower is more symmetric
  double smoothness = 0.0;
  double local_convexity = 0.0;
  double global_convexity = 0.0;  ///< mean distance to the hull, metres: lower is more convex
  /// Mean distance, in z-normalised measure units, to the k most similar segments of other
  /// scenes: lower recurs more. NaN when no other scene is known (no catalog, or the first scene).
  double recurrence = std::numeric_limits<double>::quiet_NaN();
};

inline constexpr std::size_t kMeasureCount = 6;
/// The measures' names, in the order of orientedMeasures() (also the JSON and CSV keys).
inline constexpr std::array<const char*, kMeasureCount> kMeasureNames = {
    "compactness", "symmetry", "smoothness", "local_convexity", "global_convexity", "recurrence"};

/// The measures as a row in kMeasureNames' order, as the paper defines them.
inline std::array<double, kMeasureCount> measureValues(const ShapeMeasures& m) {
  return {m.compactness,     m.symmetry,         m.smoothness,
          m.local_convexity, m.global_convexity, m.recurrence};
}

/// measureValues() oriented so that higher means more object-like: symmetry, the hull distance
/// and recurrence are negated.
inline std::array<double, kMeasureCount> orientedMeasures(const ShapeMeasures& m) {
  std::array<double, kMeasureCount> row = measureValues(m);
  for (std::size_t k : {1, 4, 5}) row[k] = -row[k];
  return row;
}

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

/// For each vertex, the triangles whose smallest vertex it is, so that each triangle is listed
/// once (compressed rows, built once per scene).
struct VertexTriangles {
  /// Vertex v's triangles are triangles[offsets[v] .. offsets[v+1]).
  std::vector<std::size_t> offsets;
  std::vector<std::int32_t> triangles;  ///< indices into TriangleMesh::triangles
};
VertexTriangles vertexTriangles(const TriangleMesh& mesh);

/// Smoothness' look-ups, built once per scene for the vertices it will be asked about: for each
/// such vertex, the others among them within the radius, each with the angular bin its direction
/// falls into in the vertex's tangent plane. These depend on the two vertices only, not on the
/// segment, so every segment of the scene shares them.
struct TangentNeighbours {
  float radius_m = 0.0f;
  int bins = 0;
  /// Per scene vertex: 0 not among the vertices, 1 among them (a neighbour others can find),
  /// 2 also looked up (one of the queries: its neighbours are listed).
  std::vector<std::uint8_t> indexed;
  /// Vertex v's neighbours are neighbours[offsets[v] .. offsets[v+1]).
  std::vector<std::size_t> offsets;
  std::vector<std::int32_t> neighbours;  ///< scene vertex indices
  std::vector<std::uint8_t> bin;         ///< per neighbour, 0 .. bins - 1
};

/// The tangent neighbours of `queries` (by default all of `vertices`) among `vertices`
/// (increasing scene vertex indices; typically every vertex of every candidate, and the union of
/// their smoothnessSample()s). Parallel (oneTBB). Throws std::invalid_argument for a mesh without
/// normals, a radius that is not positive, fewer than 2 or more than 255 bins, a vertex outside
/// the mesh, vertices or queries out of order, or a query that is not among the vertices.
TangentNeighbours tangentNeighbours(const TriangleMesh& mesh,
                                    const std::vector<std::int32_t>& vertices,
                                    float radius_m = 0.01f, int bins = 8,
                                    const std::vector<std::int32_t>* queries = nullptr);

/// The vertices smoothness averages over: all of a segment's up to 4,000; of a larger one's, every
/// k-th in index, k = ceil(n / 4,000), so 2,001 to 4,000 of them (the entropy at each is exact, with
/// all of the segment's neighbours; their mean is within a small fraction of the whole's on a dense
/// single view, at a tenth of the look-ups). Symmetry samples its vertices the same way.
std::vector<std::int32_t> smoothnessSample(const std::vector<std::int32_t>& vertices);

/// What the measures of many segments of one scene share, built once; read-only, so any number
/// of threads may measure with it at once.
struct SceneLookups {
  VertexEdges edges;
  VertexTriangles triangles;
  TangentNeighbours neighbours;
};

/// Compactness: the area of the segment's triangles (those with all three vertices in it) over
/// the area of its smallest enclosing sphere, 4 pi R^2. 1 for a sphere, 1 / (2 pi) for a square.
/// The first form builds `by_vertex` itself (a pass over all the mesh's triangles).
double compactness(const TriangleMesh& mesh, const Segment& segment);
double compactness(const TriangleMesh& mesh, const VertexTriangles& by_vertex,
                   const Segment& segment);

/// Local convexity: the share of the segment's edges (both ends in it) that are convex (Eq. 1's
/// predicate); 0 when it has none.
double localConvexity(const MeshGraph& graph, const VertexEdges& by_vertex, const Segment& segment);

/// Global convexity: the mean distance, metres, from the segment's vertices to the surface of
/// their convex hull (Qhull); 0 when every vertex lies on the hull, or the vertices are flat.
double hullDistance(const TriangleMesh& mesh, const Segment& segment);

/// Symmetry: for each principal axis d, the segment reflected through the plane across d at its
/// centroid is compared with the original both ways; each one-sided overlap O(C1, C2, r) is the
/// mean over C1's vertices of |p - nearest p' in C2| / r + beta (1 - n . n'), with r the extent
/// along d. The sides are summed and weighted by lambda_d / (lambda_0 + lambda_1 + lambda_2).
/// A distance: 0 for a shape that is its own mirror image about all three planes, larger the
/// less symmetric. (The paper writes a sum over C1; the mean makes segments of different vertex
/// counts comparable.) The reflection M is an isometry and its own inverse, so O(C, MC) =
/// O(MC, C): the two sides are equal, and one is computed, with one kd-tree of C. A segment of
/// more than 4,000 vertices averages over 4,000 of them, evenly spaced in index.
double symmetry(const TriangleMesh& mesh, const Segment& segment, float beta = 0.2f);

/// Smoothness: at each vertex, the segment's other vertices within `radius` are projected onto
/// its tangent plane, their directions quantised into `bins` angular bins, and the entropy of that
/// histogram taken, in units of log(bins) (so 1 = spread evenly all round, 0 = no neighbour or
/// all in one direction); the mean over the vertices of smoothnessSample(). The first form builds
/// the look-ups for this one segment; the second uses a scene's, which must hold every vertex of
/// the segment and have looked up every vertex of its sample (std::invalid_argument otherwise).
double smoothness(const TriangleMesh& mesh, const Segment& segment, float radius_m = 0.01f,
                  int bins = 8);
double smoothness(const TangentNeighbours& neighbours, const Segment& segment);

}  // namespace objscan::discovery
