#include "objscan/core/triangle_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace objscan {
namespace {

std::string str(const Eigen::Vector3f& v) {
  return "(" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + ", " + std::to_string(v.z()) +
         ")";
}

}  // namespace

void TriangleMesh::validate() const {
  const size_t n = positions.size();
  for (size_t i = 0; i < n; ++i) {
    if (!positions[i].allFinite()) {
      throw std::invalid_argument("vertex " + std::to_string(i) + " has a non-finite position " +
                                  str(positions[i]));
    }
  }
  if (!normals.empty()) {
    if (normals.size() != n) {
      throw std::invalid_argument("mesh has " + std::to_string(normals.size()) + " normals for " +
                                  std::to_string(n) + " vertices");
    }
    for (size_t i = 0; i < n; ++i) {
      if (!normals[i].allFinite()) {
        throw std::invalid_argument("vertex " + std::to_string(i) + " has a non-finite normal " +
                                    str(normals[i]));
      }
    }
  }
  if (!colors.empty() && colors.size() != n) {
    throw std::invalid_argument("mesh has " + std::to_string(colors.size()) + " colours for " +
                                std::to_string(n) + " vertices");
  }
  if (!labels.empty() && labels.size() != n) {
    throw std::invalid_argument("mesh has " + std::to_string(labels.size()) + " labels for " +
                                std::to_string(n) + " vertices");
  }
  if (!weights.empty()) {
    if (weights.size() != n) {
      throw std::invalid_argument("mesh has " + std::to_string(weights.size()) + " weights for " +
                                  std::to_string(n) + " vertices");
    }
    for (size_t i = 0; i < n; ++i) {
      if (!(std::isfinite(weights[i]) && weights[i] >= 0.0f)) {
        throw std::invalid_argument("vertex " + std::to_string(i) + " has the weight " +
                                    std::to_string(weights[i]) +
                                    "; a weight must be a finite number >= 0");
      }
    }
  }
  if (!ignore.empty() && ignore.size() != n) {
    throw std::invalid_argument("mesh has " + std::to_string(ignore.size()) + " ignore flags for " +
                                std::to_string(n) + " vertices");
  }
  const auto count = static_cast<long long>(n);
  for (size_t t = 0; t < triangles.size(); ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0 || tri[k] >= count) {
        throw std::invalid_argument("triangle " + std::to_string(t) + " refers to vertex " +
                                    std::to_string(tri[k]) + ", but the mesh has " +
                                    std::to_string(n) + " vertices");
      }
    }
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      throw std::invalid_argument("triangle " + std::to_string(t) + " is degenerate: vertices " +
                                  std::to_string(tri[0]) + ", " + std::to_string(tri[1]) + ", " +
                                  std::to_string(tri[2]));
    }
  }
}

Eigen::AlignedBox3f TriangleMesh::bounds() const {
  Eigen::AlignedBox3f box;
  for (const auto& p : positions) box.extend(p);
  return box;
}

void TriangleMesh::computeNormals() {
  std::vector<Eigen::Vector3f> sum(positions.size(), Eigen::Vector3f::Zero());
  for (const auto& t : triangles) {
    // The cross product's length is twice the area: an area-weighted sum.
    const Eigen::Vector3f n =
        (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]);
    for (int k = 0; k < 3; ++k) sum[t[k]] += n;
  }
  normals.resize(positions.size());
  for (std::size_t i = 0; i < sum.size(); ++i) {
    const float length = sum[i].norm();
    normals[i] = length > 0.0f ? Eigen::Vector3f(sum[i] / length) : Eigen::Vector3f::UnitZ();
  }
}

double TriangleMesh::surfaceArea() const {
  double area = 0.0;
  for (const auto& t : triangles) {
    const Eigen::Vector3d a = positions[t[0]].cast<double>();
    const Eigen::Vector3d b = positions[t[1]].cast<double>();
    const Eigen::Vector3d c = positions[t[2]].cast<double>();
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  return area;
}

TriangleMesh TriangleMesh::subset(const std::vector<std::int32_t>& vertices) const {
  return MeshSubsets(*this).subset(vertices);
}

MeshSubsets::MeshSubsets(const TriangleMesh& mesh) : mesh_(mesh) {
  if (mesh.triangles.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw std::invalid_argument("MeshSubsets: too many triangles for 32-bit indices");
  }
  const std::size_t n = mesh.positions.size();
  const auto valid = [n](const Eigen::Vector3i& t) {
    return t.minCoeff() >= 0 && static_cast<std::size_t>(t.maxCoeff()) < n;
  };
  first_.assign(n + 1, 0);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (valid(t)) ++first_[static_cast<std::size_t>(t.minCoeff()) + 1];
  }
  for (std::size_t v = 0; v < n; ++v) first_[v + 1] += first_[v];
  by_vertex_.resize(first_[n]);
  std::vector<std::uint32_t> next(first_.begin(), first_.end() - 1);
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    if (!valid(t)) continue;
    by_vertex_[next[static_cast<std::size_t>(t.minCoeff())]++] = static_cast<std::uint32_t>(i);
  }
}

TriangleMesh MeshSubsets::subset(const std::vector<std::int32_t>& vertices) const {
  const TriangleMesh& m = mesh_;
  TriangleMesh out;
  std::int32_t previous = -1;
  for (std::int32_t v : vertices) {
    if (v <= previous || static_cast<std::size_t>(v) >= m.positions.size()) {
      throw std::invalid_argument("subset: vertex " + std::to_string(v) +
                                  " is outside the mesh or out of increasing order");
    }
    previous = v;
    out.positions.push_back(m.positions[v]);
    if (m.hasNormals()) out.normals.push_back(m.normals[v]);
    if (m.hasColors()) out.colors.push_back(m.colors[v]);
    if (m.hasLabels()) out.labels.push_back(m.labels[v]);
    if (m.hasWeights()) out.weights.push_back(m.weights[v]);
    if (m.hasIgnore()) out.ignore.push_back(m.ignore[v]);
  }
  // A vertex's new index is its place in `vertices` (increasing): -1 when it is not there.
  const auto renumbered = [&](int v) {
    const auto it = std::lower_bound(vertices.begin(), vertices.end(), v);
    return it != vertices.end() && *it == v ? static_cast<int>(it - vertices.begin()) : -1;
  };
  std::vector<std::uint32_t> inner;
  for (std::int32_t v : vertices) {
    for (std::uint32_t k = first_[v]; k < first_[v + 1]; ++k) {
      const Eigen::Vector3i& t = m.triangles[by_vertex_[k]];
      if (renumbered(t[0]) >= 0 && renumbered(t[1]) >= 0 && renumbered(t[2]) >= 0) {
        inner.push_back(by_vertex_[k]);
      }
    }
  }
  std::sort(inner.begin(), inner.end());
  out.triangles.reserve(inner.size());
  for (std::uint32_t i : inner) {
    const Eigen::Vector3i& t = m.triangles[i];
    out.triangles.emplace_back(renumbered(t[0]), renumbered(t[1]), renumbered(t[2]));
  }
  return out;
}

}  // namespace objscan
