#include "objscan/core/mesh_decimation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

namespace objscan {
namespace {

/// One clustering pass with cells of edge `cell_m`: the coarse mesh's triangles and, per
/// original vertex, its cluster.
struct Clustering {
  std::vector<std::int32_t> cluster_of;  ///< per original vertex
  std::size_t clusters = 0;
  std::vector<Eigen::Vector3i> triangles;  ///< in clusters, collapsed and repeated ones dropped
};

Clustering cluster(const TriangleMesh& mesh, const Eigen::Vector3f& origin, float cell_m) {
  Clustering c;
  c.cluster_of.resize(mesh.positions.size());
  std::unordered_map<std::uint64_t, std::int32_t> cells;
  cells.reserve(mesh.positions.size() / 4 + 16);
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const Eigen::Vector3f g = (mesh.positions[v] - origin) / cell_m;
    // 21 bits a coordinate: 2 million cells an axis, far past any preview's grid.
    std::uint64_t key = 0;
    for (int d = 0; d < 3; ++d) {
      // A non-finite coordinate (a damaged file) goes to cell 0 rather than into an undefined cast.
      const float cell = std::isfinite(g[d]) ? std::clamp(g[d], 0.0f, 2097151.0f) : 0.0f;
      const auto i = static_cast<std::uint64_t>(cell);
      key = (key << 21) | i;
    }
    const auto [it, added] = cells.try_emplace(key, static_cast<std::int32_t>(c.clusters));
    if (added) ++c.clusters;
    c.cluster_of[v] = it->second;
  }
  c.triangles.reserve(mesh.triangles.size() / 2);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3i m(c.cluster_of[static_cast<std::size_t>(t[0])],
                            c.cluster_of[static_cast<std::size_t>(t[1])],
                            c.cluster_of[static_cast<std::size_t>(t[2])]);
    if (m[0] != m[1] && m[1] != m[2] && m[0] != m[2]) c.triangles.push_back(m);
  }
  // Copies of one triangle (same vertices, either winding kept once per orientation).
  const auto key = [](const Eigen::Vector3i& t) {
    // Rotate so the smallest index comes first: the same triangle, the same key.
    int first = 0;
    if (t[1] < t[first]) first = 1;
    if (t[2] < t[first]) first = 2;
    return std::array<int, 3>{t[first], t[(first + 1) % 3], t[(first + 2) % 3]};
  };
  std::sort(c.triangles.begin(), c.triangles.end(),
            [&](const Eigen::Vector3i& a, const Eigen::Vector3i& b) { return key(a) < key(b); });
  c.triangles.erase(std::unique(c.triangles.begin(), c.triangles.end(),
                                [&](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
                                  return key(a) == key(b);
                                }),
                    c.triangles.end());
  return c;
}

}  // namespace

DecimatedMesh decimateByClustering(const TriangleMesh& mesh, std::size_t max_triangles) {
  if (max_triangles == 0) throw std::invalid_argument("decimation to 0 triangles");
  DecimatedMesh out;
  if (mesh.triangles.size() <= max_triangles) {
    out.mesh = mesh;
    out.vertex_map.resize(mesh.positions.size());
    std::iota(out.vertex_map.begin(), out.vertex_map.end(), 0);
    return out;
  }
  const Eigen::AlignedBox3f box = mesh.bounds();
  // A cell that leaves about max_triangles of a surface of this area (two triangles a cell),
  // grown by a quarter each time the count still exceeds it.
  const double area = std::max(mesh.surfaceArea(), 1e-12);
  auto cell = static_cast<float>(std::sqrt(2.0 * area / static_cast<double>(max_triangles)));
  const float diagonal = box.diagonal().norm();
  cell = std::max(cell, diagonal / 2e6f);
  Clustering c = cluster(mesh, box.min(), cell);
  while (c.triangles.size() > max_triangles) {
    cell *= 1.25f;
    c = cluster(mesh, box.min(), cell);
  }

  // Cluster vertices: the mean of their members, over the vertices triangles still use.
  std::vector<std::int32_t> used(c.clusters, -1);
  std::int32_t kept = 0;
  for (const Eigen::Vector3i& t : c.triangles) {
    for (int k = 0; k < 3; ++k) {
      std::int32_t& u = used[static_cast<std::size_t>(t[k])];
      if (u < 0) u = kept++;
    }
  }
  const auto n = static_cast<std::size_t>(kept);
  std::vector<Eigen::Vector3d> sum_position(n, Eigen::Vector3d::Zero());
  std::vector<Eigen::Vector3d> sum_normal(mesh.hasNormals() ? n : 0, Eigen::Vector3d::Zero());
  std::vector<Eigen::Vector3d> sum_color(mesh.hasColors() ? n : 0, Eigen::Vector3d::Zero());
  std::vector<double> sum_weight(mesh.hasWeights() ? n : 0, 0.0);
  std::vector<std::uint32_t> members(n, 0);
  out.mesh.labels.assign(mesh.hasLabels() ? n : 0, 0);
  out.mesh.ignore.assign(mesh.hasIgnore() ? n : 0, 0);
  out.vertex_map.resize(mesh.positions.size());
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const std::int32_t u = used[static_cast<std::size_t>(c.cluster_of[v])];
    out.vertex_map[v] = u;
    if (u < 0) continue;
    const auto i = static_cast<std::size_t>(u);
    if (members[i]++ == 0) {
      if (mesh.hasLabels()) out.mesh.labels[i] = mesh.labels[v];
      if (mesh.hasIgnore()) out.mesh.ignore[i] = mesh.ignore[v];
    }
    sum_position[i] += mesh.positions[v].cast<double>();
    if (mesh.hasNormals()) sum_normal[i] += mesh.normals[v].cast<double>();
    if (mesh.hasColors()) sum_color[i] += mesh.colors[v].cast<double>();
    if (mesh.hasWeights()) sum_weight[i] += mesh.weights[v];
  }
  out.mesh.positions.resize(n);
  if (mesh.hasNormals()) out.mesh.normals.resize(n);
  if (mesh.hasColors()) out.mesh.colors.resize(n);
  if (mesh.hasWeights()) out.mesh.weights.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double count = members[i];
    out.mesh.positions[i] = (sum_position[i] / count).cast<float>();
    if (mesh.hasNormals()) {
      const double length = sum_normal[i].norm();
      out.mesh.normals[i] = Eigen::Vector3f::UnitZ();
      if (length > 1e-12) out.mesh.normals[i] = (sum_normal[i] / length).cast<float>();
    }
    if (mesh.hasColors()) {
      out.mesh.colors[i] = (sum_color[i] / count).array().round().cast<std::uint8_t>().matrix();
    }
    if (mesh.hasWeights()) out.mesh.weights[i] = static_cast<float>(sum_weight[i] / count);
  }
  out.mesh.triangles.reserve(c.triangles.size());
  for (const Eigen::Vector3i& t : c.triangles) {
    out.mesh.triangles.emplace_back(used[static_cast<std::size_t>(t[0])],
                                    used[static_cast<std::size_t>(t[1])],
                                    used[static_cast<std::size_t>(t[2])]);
  }
  out.cell_m = cell;
  return out;
}

}  // namespace objscan
