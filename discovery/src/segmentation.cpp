#include "objscan/discovery/segmentation.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

namespace objscan::discovery {

namespace {

/// Union-find over the vertices, with each component's size and FH's internal difference (the
/// largest edge weight of its minimum spanning tree so far).
class Components {
 public:
  explicit Components(std::size_t n) : parent_(n), size_(n, 1), internal_(n, 0.0f) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }

  std::int32_t find(std::int32_t x) {
    while (parent_[static_cast<std::size_t>(x)] != x) {
      auto& p = parent_[static_cast<std::size_t>(x)];
      p = parent_[static_cast<std::size_t>(p)];  // path halving
      x = p;
    }
    return x;
  }

  /// Joins the roots a and b through an edge of weight w (the largest so far in both).
  void join(std::int32_t a, std::int32_t b, float w) {
    if (size_[static_cast<std::size_t>(a)] < size_[static_cast<std::size_t>(b)]) std::swap(a, b);
    parent_[static_cast<std::size_t>(b)] = a;
    size_[static_cast<std::size_t>(a)] += size_[static_cast<std::size_t>(b)];
    internal_[static_cast<std::size_t>(a)] = w;
  }

  std::size_t size(std::int32_t root) const { return size_[static_cast<std::size_t>(root)]; }
  float internal(std::int32_t root) const { return internal_[static_cast<std::size_t>(root)]; }

 private:
  std::vector<std::int32_t> parent_;
  std::vector<std::size_t> size_;
  std::vector<float> internal_;
};

std::vector<std::size_t> edgesByWeight(const MeshGraph& graph) {
  std::vector<std::size_t> order(graph.edges.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  // Ties broken by index, so that the result does not depend on the sort.
  tbb::parallel_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    const float wx = graph.edges[x].weight, wy = graph.edges[y].weight;
    return wx < wy || (wx == wy && x < y);
  });
  return order;
}

Segmentation segmentSorted(const MeshGraph& graph, const std::vector<std::size_t>& order,
                           float scale, std::size_t min_size) {
  if (!(scale >= 0.0f) || !std::isfinite(scale)) {
    throw std::invalid_argument("the segmentation scale must be a finite number >= 0");
  }
  Components c(graph.vertex_count);
  for (std::size_t e : order) {
    const MeshEdge& edge = graph.edges[e];
    const std::int32_t a = c.find(edge.a), b = c.find(edge.b);
    if (a == b) continue;
    const float limit_a = c.internal(a) + scale / static_cast<float>(c.size(a));
    const float limit_b = c.internal(b) + scale / static_cast<float>(c.size(b));
    // Edges come in increasing weight, so edge.weight is the joined tree's largest.
    if (edge.weight <= std::min(limit_a, limit_b)) c.join(a, b, edge.weight);
  }
  for (std::size_t e : order) {
    const MeshEdge& edge = graph.edges[e];
    const std::int32_t a = c.find(edge.a), b = c.find(edge.b);
    if (a != b && (c.size(a) < min_size || c.size(b) < min_size)) {
      c.join(a, b, std::max({edge.weight, c.internal(a), c.internal(b)}));
    }
  }
  Segmentation s;
  s.scale = scale;
  s.labels.assign(graph.vertex_count, -1);
  std::vector<std::int32_t> label_of_root(graph.vertex_count, -1);
  for (std::size_t v = 0; v < graph.vertex_count; ++v) {
    const auto root = static_cast<std::size_t>(c.find(static_cast<std::int32_t>(v)));
    if (label_of_root[root] < 0) {
      label_of_root[root] = static_cast<std::int32_t>(s.segment_count++);
    }
    s.labels[v] = label_of_root[root];
  }
  return s;
}

}  // namespace

Segmentation segmentGraph(const MeshGraph& graph, float scale, std::size_t min_size) {
  return segmentSorted(graph, edgesByWeight(graph), scale, min_size);
}

std::vector<Segmentation> segmentAtScales(const MeshGraph& graph, const std::vector<float>& scales,
                                          std::size_t min_size) {
  const std::vector<std::size_t> order = edgesByWeight(graph);
  std::vector<Segmentation> out(scales.size());
  tbb::parallel_for(std::size_t{0}, scales.size(), [&](std::size_t i) {
    out[i] = segmentSorted(graph, order, scales[i], min_size);
  });
  return out;
}

}  // namespace objscan::discovery
