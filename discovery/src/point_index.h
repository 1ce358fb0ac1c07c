#pragma once

// Nearest-neighbour and radius look-ups among a segment's points: a kd-tree from nanoflann
// (header-only, Debian's libnanoflann-dev), kept out of the public headers.

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nanoflann.hpp>

namespace objscan::discovery {

/// nanoflann's view of a vector of points (which must outlive the tree).
struct PointCloudAdaptor {
  const std::vector<Eigen::Vector3f>* points = nullptr;
  std::size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(std::size_t i, std::size_t d) const {
    return (*points)[i][static_cast<Eigen::Index>(d)];
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using PointTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloudAdaptor>,
                                        PointCloudAdaptor, 3, std::uint32_t>;

class PointIndex {
 public:
  explicit PointIndex(const std::vector<Eigen::Vector3f>& points)
      : cloud_{&points}, tree_(3, cloud_, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {}

  /// The index of the point nearest q (the index must hold at least one point).
  std::uint32_t nearest(const Eigen::Vector3f& q) const {
    std::uint32_t index = 0;
    float distance_sq = 0.0f;
    tree_.knnSearch(q.data(), 1, &index, &distance_sq);
    return index;
  }

  /// The points within `radius` of q (q itself included when it is one), unordered.
  void within(const Eigen::Vector3f& q, float radius,
              std::vector<std::pair<std::uint32_t, float>>* found) const {
    found->clear();
    nanoflann::SearchParams params;
    params.sorted = false;
    tree_.radiusSearch(q.data(), radius * radius, *found, params);  // squared for L2
  }

 private:
  PointCloudAdaptor cloud_;
  PointTree tree_;
};

}  // namespace objscan::discovery
