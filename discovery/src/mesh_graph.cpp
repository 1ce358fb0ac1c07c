#include "objscan/discovery/mesh_graph.h"

#include <algorithm>
#include <stdexcept>

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

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
  // Each triangle edge as a packed (smaller, larger) key; an edge shared by two triangles appears
  // twice and is kept once.
  std::vector<std::uint64_t> keys;
  keys.reserve(3 * mesh.triangles.size());
  const auto key = [](std::int32_t i, std::int32_t j) {
    const auto lo = static_cast<std::uint64_t>(std::min(i, j));
    const auto hi = static_cast<std::uint64_t>(std::max(i, j));
    return (lo << 32) | hi;
  };
  for (const Eigen::Vector3i& t : mesh.triangles) {
    keys.push_back(key(t[0], t[1]));
    keys.push_back(key(t[1], t[2]));
    keys.push_back(key(t[2], t[0]));
  }
  tbb::parallel_sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());

  MeshGraph graph;
  graph.vertex_count = mesh.positions.size();
  graph.edges.resize(keys.size());
  tbb::parallel_for(std::size_t{0}, keys.size(), [&](std::size_t e) {
    MeshEdge& edge = graph.edges[e];
    edge.a = static_cast<std::int32_t>(keys[e] >> 32);
    edge.b = static_cast<std::int32_t>(keys[e] & 0xffffffffu);
    const auto a = static_cast<std::size_t>(edge.a), b = static_cast<std::size_t>(edge.b);
    edge.convex = isConvex(mesh.positions[a], mesh.normals[a], mesh.positions[b], mesh.normals[b]);
    edge.weight = edgeWeight(mesh.normals[a], mesh.normals[b], edge.convex);
  });
  return graph;
}

}  // namespace objscan::discovery
