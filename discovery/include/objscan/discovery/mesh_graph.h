#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"

/// The scene mesh as a graph for segmentation (paper, section IV-A): vertices are the nodes, the
/// edges of the triangles are the graph's edges, weighted by the paper's curvature-aware
/// dissimilarity (Eq. 1).
namespace objscan::discovery {

/// Whether an edge between p_i and p_j is convex (the surface curves outward across it). The
/// paper's predicate, (p_j - p_i) . n_j > 0, depends on which end is called j; it is evaluated
/// from both ends and the two sides summed, (p_j - p_i) . (n_j - n_i) > 0, so that an edge is
/// convex or not whichever way it is read. On a smooth surface both ends agree.
bool isConvex(const Eigen::Vector3f& p_i, const Eigen::Vector3f& n_i, const Eigen::Vector3f& p_j,
              const Eigen::Vector3f& n_j);

/// Eq. 1: (1 - n_i . n_j)^2 across a convex edge, 1 - n_i . n_j across a concave (or flat) one.
/// In [0, 4]; 0 inside a plane. Squaring makes convex folds, which hold objects together, cheaper
/// to keep than concave ones, where objects meet their support.
float edgeWeight(const Eigen::Vector3f& n_i, const Eigen::Vector3f& n_j, bool convex);

struct MeshEdge {
  std::int32_t a = 0;  ///< the smaller vertex index
  std::int32_t b = 0;  ///< the larger
  float weight = 0.0f;
  bool convex = false;
};

struct MeshGraph {
  std::size_t vertex_count = 0;
  std::vector<MeshEdge> edges;  ///< every triangle edge once, ordered by (a, b)
};

/// Throws std::invalid_argument when the mesh fails validate() or has no normals.
MeshGraph buildMeshGraph(const TriangleMesh& mesh);

}  // namespace objscan::discovery
