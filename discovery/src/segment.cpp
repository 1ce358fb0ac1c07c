#include "objscan/discovery/segment.h"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>

namespace objscan::discovery {

Segment describeSegment(const TriangleMesh& mesh, std::vector<std::int32_t> vertices, float scale) {
  if (vertices.empty()) throw std::invalid_argument("a segment needs at least one vertex");
  for (std::int32_t v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= mesh.positions.size()) {
      throw std::invalid_argument("segment vertex " + std::to_string(v) + " is not in the mesh");
    }
  }
  Segment s;
  s.vertices = std::move(vertices);
  s.scale = scale;
  // Mean and covariance in double: a scene's coordinates are metres from an arbitrary origin.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::int32_t v : s.vertices)
    mean += mesh.positions[static_cast<std::size_t>(v)].cast<double>();
  mean /= static_cast<double>(s.vertices.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::int32_t v : s.vertices) {
    const Eigen::Vector3d d = mesh.positions[static_cast<std::size_t>(v)].cast<double>() - mean;
    scatter += d * d.transpose();
  }
  scatter /= static_cast<double>(s.vertices.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  // Eigen sorts increasingly; the paper's lambda0 is the largest.
  for (int k = 0; k < 3; ++k) {
    s.eigenvalues[k] = static_cast<float>(std::max(0.0, eig.eigenvalues()[2 - k]));
    s.axes.col(k) = eig.eigenvectors().col(2 - k).cast<float>();
  }
  s.centroid = mean.cast<float>();
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f hi = -lo;
  for (std::int32_t v : s.vertices) {
    const Eigen::Vector3f p =
        s.axes.transpose() * (mesh.positions[static_cast<std::size_t>(v)] - s.centroid);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  s.extents = hi - lo;
  return s;
}

std::optional<std::string> rejection(const Segment& s, const SegmentFilter& f) {
  char why[96];
  if (s.extents[0] > f.max_size_m) {
    std::snprintf(why, sizeof why, "larger than %.2f m (%.2f m)", f.max_size_m, s.extents[0]);
    return std::string(why);
  }
  if (s.extents[2] < f.min_thickness_m) {
    std::snprintf(why, sizeof why, "thinner than %.0f mm (%.1f mm)", 1e3 * f.min_thickness_m,
                  1e3 * s.extents[2]);
    return std::string(why);
  }
  const float l0 = s.eigenvalues[0];
  if (!(l0 > 0.0f) || s.eigenvalues[1] < f.min_lambda1_over_lambda0 * l0) {
    return std::string("too thin relative to its length (lambda1 / lambda0)");
  }
  if (s.eigenvalues[2] < f.min_lambda2_over_lambda0 * l0) {
    return std::string("too flat relative to its length (lambda2 / lambda0)");
  }
  return std::nullopt;
}

std::vector<Segment> candidateSegments(const TriangleMesh& mesh,
                                       const std::vector<Segmentation>& segmentations,
                                       std::size_t min_size, const SegmentFilter& filter) {
  std::vector<Segment> out;
  for (const Segmentation& seg : segmentations) {
    if (seg.labels.size() != mesh.positions.size()) {
      throw std::invalid_argument("a segmentation's labels do not match the mesh's vertices");
    }
    std::vector<std::vector<std::int32_t>> members(seg.segment_count);
    for (std::size_t v = 0; v < seg.labels.size(); ++v) {
      members[static_cast<std::size_t>(seg.labels[v])].push_back(static_cast<std::int32_t>(v));
    }
    for (std::vector<std::int32_t>& m : members) {
      if (m.size() < min_size) continue;
      Segment s = describeSegment(mesh, std::move(m), seg.scale);
      if (!rejection(s, filter)) out.push_back(std::move(s));
    }
  }
  return out;
}

double vertexIoU(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b) {
  std::size_t common = 0;
  auto i = a.begin(), j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (*i < *j) {
      ++i;
    } else if (*j < *i) {
      ++j;
    } else {
      ++common;
      ++i;
      ++j;
    }
  }
  const std::size_t unite = a.size() + b.size() - common;
  return unite > 0 ? static_cast<double>(common) / static_cast<double>(unite) : 0.0;
}

std::vector<std::size_t> suppressOverlaps(const std::vector<Segment>& segments,
                                          const std::vector<double>& scores, double max_iou) {
  if (segments.size() != scores.size()) {
    throw std::invalid_argument("suppressOverlaps: one score per segment is needed");
  }
  std::vector<std::size_t> order(segments.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return scores[a] > scores[b]; });
  std::vector<std::size_t> kept;
  for (std::size_t i : order) {
    const Segment& s = segments[i];
    bool overlaps = false;
    for (std::size_t k : kept) {
      const Segment& t = segments[k];
      // Disjoint index ranges share no vertex: skip the merge walk.
      if (s.vertices.back() < t.vertices.front() || t.vertices.back() < s.vertices.front())
        continue;
      if (vertexIoU(s.vertices, t.vertices) > max_iou) {
        overlaps = true;
        break;
      }
    }
    if (!overlaps) kept.push_back(i);
  }
  return kept;
}

}  // namespace objscan::discovery
