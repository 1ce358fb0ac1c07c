#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/segmentation.h"

/// Candidate segments: their shape statistics and the paper's hard filters (section IV-A).
namespace objscan::discovery {

/// A set of a scene mesh's vertices with the statistics the filters and measures need.
struct Segment {
  std::vector<std::int32_t> vertices;  ///< indices into the scene mesh, increasing
  float scale = 0.0f;                  ///< the segmentation granularity it came from
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  /// Principal axes (columns) of the vertices' scatter matrix, by decreasing eigenvalue.
  Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();
  /// Eigenvalues of the scatter matrix (per vertex: the covariance), lambda0 >= lambda1 >= lambda2.
  Eigen::Vector3f eigenvalues = Eigen::Vector3f::Zero();
  /// Extent along each principal axis (max - min of the projections), metres.
  Eigen::Vector3f extents = Eigen::Vector3f::Zero();
};

/// The statistics of `vertices` (increasing indices into `mesh`). Throws std::invalid_argument
/// for an empty set or an index outside the mesh.
Segment describeSegment(const TriangleMesh& mesh, std::vector<std::int32_t> vertices,
                        float scale = 0.0f);

/// The paper's hard filters. "Larger than 1 m" is read as the largest extent, "thinner than
/// 2 cm" as the smallest extent (the thickness along the third principal axis).
struct SegmentFilter {
  float max_size_m = 1.0f;
  /// The paper's 2 cm rejects what a single view shows of a box seen nearly face-on, and an
  /// occluded object's thin sliver; 1 cm keeps them (chosen on half of mosd_learn, where 5 mm
  /// let in so many slivers of the table's edge that AP fell from 0.95 to 0.64).
  float min_thickness_m = 0.01f;
  /// Below: too thin, relatively (a stick: a cable, a table's edge). The paper's 0.05 rejects
  /// long thin objects: a fork (19 x 2.5 cm: 0.017), a spoon, a marker, a banana seen from one
  /// side (0.06 whole, less in part). 0.01 keeps what is a tenth as wide as it is long.
  float min_lambda1_over_lambda0 = 0.01f;
  float min_lambda2_over_lambda0 = 0.001f;  ///< below: too flat, relatively (a sheet)
};

/// Why `segment` is rejected, in a few words, or nothing when it passes.
std::optional<std::string> rejection(const Segment& segment, const SegmentFilter& filter);

/// The segments of every segmentation with at least `min_size` vertices that pass the filter,
/// in order of scale, then of label. The scales are gathered in parallel (oneTBB), and a segment
/// that several scales produce is described once.
std::vector<Segment> candidateSegments(const TriangleMesh& mesh,
                                       const std::vector<Segmentation>& segmentations,
                                       std::size_t min_size, const SegmentFilter& filter);

/// For each segment, the index of the first segment with the same vertices (its own index when
/// none comes before it). The same segment often comes out of several scales, and its measures
/// need computing once.
std::vector<std::size_t> firstOfEach(const std::vector<Segment>& segments);

/// How many vertices two sorted vertex lists share.
std::size_t sharedVertexCount(const std::vector<std::int32_t>& a,
                              const std::vector<std::int32_t>& b);

/// Intersection over union of two increasing vertex-index lists.
double vertexIoU(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b);

/// Greedy non-maximum suppression (the paper's, IoU threshold 0.7): the segments are taken in
/// decreasing score, and one whose vertex-set IoU with a segment already kept exceeds `max_iou`
/// is dropped. Returns the indices kept, best first (ties keep the lower index first). Throws
/// std::invalid_argument when the two lists differ in length.
std::vector<std::size_t> suppressOverlaps(const std::vector<Segment>& segments,
                                          const std::vector<double>& scores, double max_iou = 0.7);

}  // namespace objscan::discovery
