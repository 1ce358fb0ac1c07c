#pragma once

#include <limits>
#include <unordered_map>
#include <vector>

#include "objscan/core/triangle_mesh.h"

namespace objscan {

/// Exact distance from points to a triangle mesh, for points near it: triangles are binned in a
/// uniform grid, and a query looks only at the triangles whose bounds, grown by the search
/// radius, hold the point. Built once, then const and thread-safe.
class MeshDistance {
 public:
  struct Closest {
    float distance_m = std::numeric_limits<float>::infinity();  ///< inf if none within radius
    int triangle = -1;
    Eigen::Vector3f point = Eigen::Vector3f::Zero();  ///< closest point on that triangle
  };

  /// `radius_m`: queries report triangles up to this far away; farther ones count as none.
  /// Throws std::invalid_argument for a mesh reaching beyond about 10 km from the origin.
  MeshDistance(const TriangleMesh& mesh, float radius_m);

  Closest closest(const Eigen::Vector3f& p) const;

  /// Closest point to p on triangle (a, b, c), exact (Ericson, Real-Time Collision
  /// Detection 5.1.5).
  static Eigen::Vector3f closestOnTriangle(const Eigen::Vector3f& p, const Eigen::Vector3f& a,
                                           const Eigen::Vector3f& b, const Eigen::Vector3f& c);

 private:
  long long key(int x, int y, int z) const;

  const TriangleMesh& mesh_;
  float radius_m_;
  float cell_m_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

}  // namespace objscan
