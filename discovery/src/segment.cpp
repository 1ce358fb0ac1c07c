#include "objscan/discovery/segment.h"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include <tbb/parallel_for.h>
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

namespace {

/// FNV-1a over a vertex list and its length: equal lists hash equal.
std::uint64_t hashVertices(const std::vector<std::int32_t>& vertices) {
  std::uint64_t hash = 1469598103934665603ull ^ vertices.size();
  for (std::int32_t v : vertices) hash = (hash ^ static_cast<std::uint32_t>(v)) * 1099511628211ull;
  return hash;
}

/// For each list, the index of the first equal one (its own when none comes before it).
std::vector<std::size_t> firstEqual(const std::vector<const std::vector<std::int32_t>*>& lists,
                                    const std::vector<std::uint64_t>& hashes) {
  std::vector<std::size_t> first(lists.size());
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> by_hash;
  for (std::size_t i = 0; i < lists.size(); ++i) {
    first[i] = i;
    std::vector<std::size_t>& same = by_hash[hashes[i]];
    for (std::size_t j : same) {
      if (*lists[j] == *lists[i]) {
        first[i] = j;
        break;
      }
    }
    if (first[i] == i) same.push_back(i);
  }
  return first;
}

}  // namespace

std::vector<Segment> candidateSegments(const TriangleMesh& mesh,
                                       const std::vector<Segmentation>& segmentations,
                                       std::size_t min_size, const SegmentFilter& filter) {
  for (const Segmentation& seg : segmentations) {
    if (seg.labels.size() != mesh.positions.size()) {
      throw std::invalid_argument("a segmentation's labels do not match the mesh's vertices");
    }
  }
  // The scales in parallel, each gathering only its large enough segments' vertices.
  struct Found {
    std::vector<std::int32_t> vertices;
    std::uint64_t hash = 0;
  };
  std::vector<std::vector<Found>> per_scale(segmentations.size());
  tbb::parallel_for(std::size_t{0}, segmentations.size(), [&](std::size_t i) {
    const Segmentation& seg = segmentations[i];
    std::vector<std::size_t> sizes(seg.segment_count, 0);
    for (std::int32_t label : seg.labels) ++sizes[static_cast<std::size_t>(label)];
    std::vector<std::vector<std::int32_t>> members(seg.segment_count);
    for (std::size_t label = 0; label < sizes.size(); ++label) {
      if (sizes[label] >= min_size) members[label].reserve(sizes[label]);
    }
    for (std::size_t v = 0; v < seg.labels.size(); ++v) {
      const auto label = static_cast<std::size_t>(seg.labels[v]);
      if (sizes[label] >= min_size) members[label].push_back(static_cast<std::int32_t>(v));
    }
    for (std::size_t label = 0; label < sizes.size(); ++label) {
      if (sizes[label] < min_size || sizes[label] == 0) continue;
      const std::uint64_t hash = hashVertices(members[label]);
      per_scale[i].push_back({std::move(members[label]), hash});
    }
  });
  // The same segment often comes out of several scales: each distinct one is described and
  // filtered once, in parallel.
  std::vector<const std::vector<std::int32_t>*> lists;
  std::vector<std::uint64_t> hashes;
  std::vector<float> scales;
  for (std::size_t i = 0; i < per_scale.size(); ++i) {
    for (const Found& f : per_scale[i]) {
      lists.push_back(&f.vertices);
      hashes.push_back(f.hash);
      scales.push_back(segmentations[i].scale);
    }
  }
  const std::vector<std::size_t> first = firstEqual(lists, hashes);
  std::vector<std::optional<Segment>> kept(lists.size());
  tbb::parallel_for(std::size_t{0}, lists.size(), [&](std::size_t k) {
    if (first[k] != k) return;
    Segment s = describeSegment(mesh, *lists[k], scales[k]);
    if (!rejection(s, filter)) kept[k] = std::move(s);
  });
  std::vector<Segment> out;
  for (std::size_t k = 0; k < lists.size(); ++k) {
    if (!kept[first[k]]) continue;
    out.push_back(*kept[first[k]]);
    out.back().scale = scales[k];
  }
  return out;
}

std::vector<std::size_t> firstOfEach(const std::vector<Segment>& segments) {
  std::vector<const std::vector<std::int32_t>*> lists;
  std::vector<std::uint64_t> hashes;
  for (const Segment& s : segments) {
    lists.push_back(&s.vertices);
    hashes.push_back(hashVertices(s.vertices));
  }
  return firstEqual(lists, hashes);
}

std::size_t sharedVertexCount(const std::vector<std::int32_t>& a,
                              const std::vector<std::int32_t>& b) {
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
  return common;
}

double vertexIoU(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b) {
  const std::size_t common = sharedVertexCount(a, b);
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
      // Disjoint index ranges share no vertex: skip the merge walk. Nor can two segments whose
      // sizes differ by more than max_iou overlap by more: IoU <= smaller / larger.
      if (s.vertices.back() < t.vertices.front() || t.vertices.back() < s.vertices.front())
        continue;
      const double smaller = static_cast<double>(std::min(s.vertices.size(), t.vertices.size()));
      const double larger = static_cast<double>(std::max(s.vertices.size(), t.vertices.size()));
      if (smaller <= max_iou * larger) continue;
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
