#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "objscan/core/triangle_mesh.h"

namespace objscan {

/// A coarser copy of a mesh and where each of the original's vertices went.
struct DecimatedMesh {
  TriangleMesh mesh;
  /// For every vertex of the original, its vertex in `mesh` (-1 when no triangle of `mesh` uses
  /// it: it lay on triangles that collapsed). Lets a vertex list of the original (a segment, a
  /// hypothesis) be drawn on the coarser mesh.
  std::vector<std::int32_t> vertex_map;
  float cell_m = 0.0f;  ///< the clustering cell's edge; 0 when the mesh was copied unchanged
};

/// The mesh with at most `max_triangles` triangles, by vertex clustering (Rossignac and Borrel):
/// the vertices in each cubic cell of a grid become one vertex at their mean (colours and weights
/// averaged, normals averaged and renormalised, labels and ignore flags the first vertex's), and
/// triangles that collapse are dropped, as are copies of one triangle. The cell grows until the
/// count fits. A mesh already within the limit is returned as it is, with the identity map.
/// Clustering, not quadric simplification: it is one linear pass and keeps a many-to-one vertex
/// map, which is what a preview needs to paint segments of the full mesh; none of our
/// dependencies offers it without VTK. Throws std::invalid_argument for max_triangles 0.
DecimatedMesh decimateByClustering(const TriangleMesh& mesh, std::size_t max_triangles);

}  // namespace objscan
