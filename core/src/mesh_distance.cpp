#include "objscan/core/mesh_distance.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace objscan {
namespace {

/// Grid cells are this many search radii wide: big triangles touch fewer cells, queries see a
/// few more candidates.
constexpr float kCellPerRadius = 8.0f;
constexpr float kMinCell_m = 0.01f;
/// Cell coordinates stay within +-2^20 (the key packs 21 bits per axis).
constexpr float kMaxCells = 1 << 20;

}  // namespace

MeshDistance::MeshDistance(const TriangleMesh& mesh, float radius_m)
    : mesh_(mesh), radius_m_(radius_m), cell_m_(std::max(kMinCell_m, kCellPerRadius * radius_m)) {
  for (int t = 0; t < static_cast<int>(mesh.triangles.size()); ++t) {
    Eigen::AlignedBox3f box;
    for (int k = 0; k < 3; ++k) box.extend(mesh.positions[mesh.triangles[t][k]]);
    const Eigen::Vector3f lo = (box.min().array() - radius_m) / cell_m_;
    const Eigen::Vector3f hi = (box.max().array() + radius_m) / cell_m_;
    if (!(lo.array().abs() < kMaxCells).all() || !(hi.array().abs() < kMaxCells).all()) {
      throw std::invalid_argument("MeshDistance: triangle " + std::to_string(t) +
                                  " lies beyond the grid's reach (about 10 km at 1 cm cells)");
    }
    for (int x = static_cast<int>(std::floor(lo.x())); x <= static_cast<int>(std::floor(hi.x()));
         ++x) {
      for (int y = static_cast<int>(std::floor(lo.y())); y <= static_cast<int>(std::floor(hi.y()));
           ++y) {
        for (int z = static_cast<int>(std::floor(lo.z()));
             z <= static_cast<int>(std::floor(hi.z())); ++z) {
          cells_[key(x, y, z)].push_back(t);
        }
      }
    }
  }
}

long long MeshDistance::key(int x, int y, int z) const {
  // 21 bits per axis: +-1 million cells, far beyond any room at centimetre cells.
  const auto b = [](int v) { return static_cast<long long>(v + (1 << 20)) & 0x1fffff; };
  return (b(x) << 42) | (b(y) << 21) | b(z);
}

MeshDistance::Closest MeshDistance::closest(const Eigen::Vector3f& p) const {
  Closest best;
  const auto it = cells_.find(key(static_cast<int>(std::floor(p.x() / cell_m_)),
                                  static_cast<int>(std::floor(p.y() / cell_m_)),
                                  static_cast<int>(std::floor(p.z() / cell_m_))));
  if (it == cells_.end()) return best;
  for (const int t : it->second) {
    const Eigen::Vector3i& tri = mesh_.triangles[t];
    const Eigen::Vector3f q = closestOnTriangle(p, mesh_.positions[tri[0]], mesh_.positions[tri[1]],
                                                mesh_.positions[tri[2]]);
    const float d = (q - p).norm();
    if (d <= radius_m_ && d < best.distance_m) best = {d, t, q};
  }
  return best;
}

Eigen::Vector3f MeshDistance::closestOnTriangle(const Eigen::Vector3f& p, const Eigen::Vector3f& a,
                                                const Eigen::Vector3f& b,
                                                const Eigen::Vector3f& c) {
  const Eigen::Vector3f ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3f bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3f cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  }
  const float denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace objscan
