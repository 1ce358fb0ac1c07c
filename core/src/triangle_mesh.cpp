#include "objscan/core/triangle_mesh.h"

#include <cmath>
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
  std::vector<std::int32_t> renumbered(positions.size(), -1);
  TriangleMesh out;
  std::int32_t previous = -1;
  for (std::int32_t v : vertices) {
    if (v <= previous || static_cast<std::size_t>(v) >= positions.size()) {
      throw std::invalid_argument("subset: vertex " + std::to_string(v) +
                                  " is outside the mesh or out of increasing order");
    }
    previous = v;
    renumbered[v] = static_cast<std::int32_t>(out.positions.size());
    out.positions.push_back(positions[v]);
    if (hasNormals()) out.normals.push_back(normals[v]);
    if (hasColors()) out.colors.push_back(colors[v]);
    if (hasLabels()) out.labels.push_back(labels[v]);
    if (hasWeights()) out.weights.push_back(weights[v]);
    if (hasIgnore()) out.ignore.push_back(ignore[v]);
  }
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector3i r(renumbered[t[0]], renumbered[t[1]], renumbered[t[2]]);
    if (r.minCoeff() >= 0) out.triangles.push_back(r);
  }
  return out;
}

}  // namespace objscan
