#include "objscan/discovery/labels.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <unordered_map>

#include <tbb/parallel_for.h>
#include <Eigen/Geometry>

#include "objscan/core/mesh_distance.h"
#include "point_index.h"

namespace objscan::discovery {

std::vector<std::int32_t> transferLabels(const TriangleMesh& mesh, const TriangleMesh& truth,
                                         float max_distance_m) {
  if (!truth.hasLabels() || truth.triangles.empty()) {
    throw std::invalid_argument(
        "the ground-truth mesh needs triangles and a per-vertex object_id to transfer labels");
  }
  const MeshDistance distance(truth, max_distance_m);
  std::vector<std::int32_t> labels(mesh.positions.size(), 0);
  tbb::parallel_for(std::size_t{0}, mesh.positions.size(), [&](std::size_t v) {
    const MeshDistance::Closest c = distance.closest(mesh.positions[v]);
    if (c.triangle < 0 || !(c.distance_m <= max_distance_m)) return;
    // Objects are separate surfaces in the ground truth, so a triangle's three vertices share an
    // id; take the vertex nearest the closest point in case a producer mixed them.
    const Eigen::Vector3i& t = truth.triangles[static_cast<std::size_t>(c.triangle)];
    int best = t[0];
    for (int k = 1; k < 3; ++k) {
      if ((truth.positions[t[k]] - c.point).squaredNorm() <
          (truth.positions[best] - c.point).squaredNorm()) {
        best = t[k];
      }
    }
    labels[v] = truth.labels[static_cast<std::size_t>(best)];
  });
  return labels;
}

TruthAlignment alignToTruth(const TriangleMesh& mesh, const TriangleMesh& truth, float reach_m) {
  if (truth.triangles.empty()) {
    throw std::invalid_argument("the ground-truth mesh needs triangles to align a mesh to it");
  }
  constexpr std::size_t kMaxSamples = 5000;
  constexpr std::size_t kMinPairs = 100;
  constexpr int kMaxIterations = 30;
  constexpr double kStillM = 1e-5;                             // 0.01 mm
  constexpr double kStillRad = 1e-3 * std::numbers::pi / 180;  // 0.001 degrees
  // Damping of the normal equations, relative to their mean diagonal: a direction the geometry
  // leaves free (along a lone plane) stays where it is instead of dividing by round-off.
  constexpr double kDamping = 1e-6;
  const std::size_t n_vertices = mesh.positions.size();
  const std::size_t stride = std::max<std::size_t>(1, (n_vertices + kMaxSamples - 1) / kMaxSamples);
  std::vector<std::size_t> samples;
  for (std::size_t v = 0; v < n_vertices; v += stride) samples.push_back(v);

  const MeshDistance distance(truth, reach_m);
  struct Pair {
    Eigen::Vector3d p, q, n;  // the moved vertex, its closest truth point, that triangle's normal
    bool found = false;
  };
  std::vector<Pair> pairs(samples.size());
  // Pairs each moved sample with its closest truth point; returns how many and their RMS.
  const auto pairUp = [&](const Eigen::Isometry3d& T) {
    tbb::parallel_for(std::size_t{0}, samples.size(), [&](std::size_t i) {
      Pair& pr = pairs[i];
      pr.p = T * mesh.positions[samples[i]].cast<double>();
      const MeshDistance::Closest c = distance.closest(pr.p.cast<float>());
      pr.found = false;
      if (c.triangle < 0 || !(c.distance_m <= reach_m)) return;
      const Eigen::Vector3i& t = truth.triangles[static_cast<std::size_t>(c.triangle)];
      const Eigen::Vector3d n = (truth.positions[t[1]] - truth.positions[t[0]])
                                    .cross(truth.positions[t[2]] - truth.positions[t[0]])
                                    .cast<double>();
      if (!(n.norm() > 0.0)) return;
      pr.q = c.point.cast<double>();
      pr.n = n.normalized();
      pr.found = true;
    });
    std::size_t n = 0;
    double sum_sq = 0.0;
    for (const Pair& pr : pairs) {
      if (!pr.found) continue;
      ++n;
      sum_sq += (pr.q - pr.p).squaredNorm();
    }
    return std::make_pair(
        n, n ? static_cast<float>(std::sqrt(sum_sq / static_cast<double>(n))) : 0.0f);
  };
  // Point-to-plane steps (Chen and Medioni; linearised as Low, 2004): the small turn w about the
  // pairs' centroid c and the shift t that minimise the sum of ((p + w x (p - c) + t - q) . n)^2.
  // On a scene of large planes they converge in a few steps where point-to-point ICP slides
  // along the planes for dozens. Turning about the centroid, not the world's origin, keeps the
  // turn and the shift apart, so the stopping test means what it says wherever the scene lies.
  TruthAlignment out;
  out.samples = samples.size();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  while (out.iterations < kMaxIterations) {
    const auto [n, rms] = pairUp(T);
    if (out.iterations == 0) out.rms_before_m = rms;
    if (n < kMinPairs) {
      throw std::invalid_argument(
          "too few of the mesh's vertices lie near the ground truth to align them (" +
          std::to_string(n) + "); is the mesh in the truth's frame?");
    }
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const Pair& pr : pairs) {
      if (pr.found) c += pr.p;
    }
    c /= static_cast<double>(n);
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    for (const Pair& pr : pairs) {
      if (!pr.found) continue;
      Eigen::Matrix<double, 6, 1> J;
      J << (pr.p - c).cross(pr.n), pr.n;
      A += J * J.transpose();
      b -= J * (pr.p - pr.q).dot(pr.n);
    }
    A.diagonal().array() += kDamping * A.trace() / 6.0;
    const Eigen::Matrix<double, 6, 1> x = A.ldlt().solve(b);
    if (!x.allFinite()) break;
    const Eigen::Vector3d w = x.head<3>();
    // p -> R (p - c) + c + t.
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    if (w.norm() > 0.0) step.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).matrix();
    step.translation() = c - step.linear() * c + x.tail<3>();
    T = step * T;
    ++out.iterations;
    if (x.tail<3>().norm() < kStillM && w.norm() < kStillRad) {
      out.converged = true;
      break;
    }
  }
  const auto [n, rms] = pairUp(T);
  out.T_truth_mesh = T.cast<float>();
  out.pairs = n;
  out.rms_after_m = rms;
  double moved_sq = 0.0;
  for (std::size_t v : samples) {
    const Eigen::Vector3d p = mesh.positions[v].cast<double>();
    moved_sq += (T * p - p).squaredNorm();
  }
  out.moved_m = static_cast<float>(std::sqrt(moved_sq / static_cast<double>(samples.size())));
  return out;
}

LabelTransfer transferVertexLabels(const TriangleMesh& mesh, const TriangleMesh& truth,
                                   float max_distance_m) {
  if (!truth.hasLabels() || truth.empty()) {
    throw std::invalid_argument("the labelled mesh needs a per-vertex label to transfer");
  }
  const PointIndex index(truth.positions);
  LabelTransfer out{std::vector<std::int32_t>(mesh.positions.size(), 0),
                    std::vector<std::uint8_t>(mesh.positions.size(), 1)};
  const float max_sq = max_distance_m * max_distance_m;
  std::vector<std::uint8_t> matched(mesh.positions.size(), 0);
  tbb::parallel_for(std::size_t{0}, mesh.positions.size(), [&](std::size_t v) {
    const std::uint32_t nearest = index.nearest(mesh.positions[v]);
    if ((truth.positions[nearest] - mesh.positions[v]).squaredNorm() > max_sq) return;
    matched[v] = 1;
    out.labels[v] = truth.labels[nearest];
    out.ignore[v] = truth.hasIgnore() ? truth.ignore[nearest] : 0;
  });
  out.unmatched = static_cast<std::size_t>(std::count(matched.begin(), matched.end(), 0));
  return out;
}

GroundTruthObjects::GroundTruthObjects(std::vector<std::int32_t> vertex_labels,
                                       std::vector<std::uint8_t> ignore)
    : labels_(std::move(vertex_labels)), ignore_(std::move(ignore)) {
  if (!ignore_.empty() && ignore_.size() != labels_.size()) {
    throw std::invalid_argument("the ignore flags must be one per labelled vertex");
  }
  for (std::size_t v = 0; v < labels_.size(); ++v) {
    const std::int32_t id = labels_[v];
    if (id < 0) throw std::invalid_argument("object ids must not be negative");
    if (id > 1000000) {
      throw std::invalid_argument("object id " + std::to_string(id) + " is implausibly large");
    }
    if (static_cast<std::size_t>(id) >= sizes_.size()) sizes_.resize(id + 1, 0);
    if (!ignored(v)) ++sizes_[id];
  }
}

double GroundTruthObjects::ignoredShare(const std::vector<std::int32_t>& vertices) const {
  if (ignore_.empty() || vertices.empty()) return 0.0;
  std::size_t ignored_count = 0;
  for (std::int32_t v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= labels_.size()) {
      throw std::invalid_argument("segment vertex " + std::to_string(v) + " is outside the mesh");
    }
    ignored_count += ignore_[static_cast<std::size_t>(v)] != 0;
  }
  return static_cast<double>(ignored_count) / static_cast<double>(vertices.size());
}

ObjectMatch GroundTruthObjects::bestMatch(const std::vector<std::int32_t>& vertices) const {
  std::unordered_map<std::int32_t, std::size_t> overlap;
  std::size_t counted = 0;
  for (std::int32_t v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= labels_.size()) {
      throw std::invalid_argument("segment vertex " + std::to_string(v) + " is outside the mesh");
    }
    if (ignored(static_cast<std::size_t>(v))) continue;
    ++counted;
    if (labels_[v] != 0) ++overlap[labels_[v]];
  }
  ObjectMatch best;
  for (const auto& [id, shared] : overlap) {
    const double iou =
        static_cast<double>(shared) / static_cast<double>(counted + sizes_[id] - shared);
    if (iou > best.iou || (iou == best.iou && id < best.object_id)) best = {id, iou};
  }
  return best;
}

std::vector<std::int32_t> GroundTruthObjects::objectIds() const {
  std::vector<std::int32_t> ids;
  for (std::size_t id = 1; id < sizes_.size(); ++id) {
    if (sizes_[id] > 0) ids.push_back(static_cast<std::int32_t>(id));
  }
  return ids;
}

std::size_t GroundTruthObjects::objectSize(std::int32_t id) const {
  return id > 0 && static_cast<std::size_t>(id) < sizes_.size() ? sizes_[id] : 0;
}

}  // namespace objscan::discovery
