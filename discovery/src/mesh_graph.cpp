#include "objscan/discovery/mesh_graph.h"

#include <algorithm>
#include <cstddef>
#include <numeric>
#include <stdexcept>

#include <tbb/parallel_for.h>

namespace objscan::discovery {

bool isConvex(const Eigen::Vector3f& p_i, const Eigen::Vector3f& n_i, const Eigen::Vector3f& p_j,
              const Eigen::Vector3f& n_j) {
  return (p_j - p_i).dot(n_j - n_i) > 0.0f;
}

float edgeWeight(const Eigen::Vector3f& n_i, const Eigen::Vector3f& n_j, bool convex) {
  const float d = 1.0f - n_i.dot(n_j);
  return convex ? d * d : d;
}

MeshGraph buildMeshGraph(const TriangleMesh& mesh) {
  mesh.validate();
  if (!mesh.hasNormals()) {
    throw std::invalid_argument("the mesh has no vertex normals, which segmentation needs");
  }
  // Each triangle edge filed under its smaller end (a counting sort); each end's short list then
  // sorted and its repeats dropped (an edge shared by two triangles appears twice): every edge
  // once, ordered by (a, b).
  const std::size_t n = mesh.positions.size();
  std::vector<std::size_t> start(n + 1, 0);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k)
      ++start[static_cast<std::size_t>(std::min(t[k], t[(k + 1) % 3])) + 1];
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<std::int32_t> larger(start[n]);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (const Eigen::Vector3i& t : mesh.triangles) {
      for (int k = 0; k < 3; ++k) {
        const std::int32_t i = t[k], j = t[(k + 1) % 3];
        larger[fill[static_cast<std::size_t>(std::min(i, j))]++] = std::max(i, j);
      }
    }
  }
  std::vector<std::size_t> first(n + 1, 0);  // vertex v's edges: [first[v], first[v + 1])
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t v) {
    const auto begin = larger.begin() + static_cast<std::ptrdiff_t>(start[v]);
    const auto end = larger.begin() + static_cast<std::ptrdiff_t>(start[v + 1]);
    std::sort(begin, end);
    first[v + 1] = static_cast<std::size_t>(std::unique(begin, end) - begin);
  });
  std::partial_sum(first.begin(), first.end(), first.begin());

  MeshGraph graph;
  graph.vertex_count = n;
  graph.edges.resize(first[n]);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t v) {
    for (std::size_t e = first[v]; e < first[v + 1]; ++e) {
      MeshEdge& edge = graph.edges[e];
      edge.a = static_cast<std::int32_t>(v);
      edge.b = larger[start[v] + (e - first[v])];
      const auto a = static_cast<std::size_t>(edge.a), b = static_cast<std::size_t>(edge.b);
      edge.convex =
          isConvex(mesh.positions[a], mesh.normals[a], mesh.positions[b], mesh.normals[b]);
      edge.weight = edgeWeight(mesh.normals[a], mesh.normals[b], edge.convex);
    }
  });
  return graph;
}

}  // namespace objscan::discovery
