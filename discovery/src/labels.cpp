#include "objscan/discovery/labels.h"

#include <algorithm>
#include <stdexcept>
#include <unordered_map>

#include <tbb/parallel_for.h>

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
