#include "objscan/discovery/segmentation.h"

#include "disjoint_sets.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include <tbb/parallel_for.h>

namespace objscan::discovery {

namespace {

/// Union-find over the vertices, with each component's size and FH's internal difference (the
/// largest edge weight of its minimum spanning tree so far). The parents apart from the rest: most
/// look-ups only follow parents, and the smaller their array, the more of it stays in cache.
class Components {
 public:
  explicit Components(std::size_t n) : parents_(n), root_(n) {}

  std::int32_t find(std::int32_t x) { return parents_.find(x); }

  /// Joins the roots a and b through an edge of weight w (the largest so far in both).
  void join(std::int32_t a, std::int32_t b, float w) {
    if (root(a).size < root(b).size) std::swap(a, b);
    parents_.attach(b, a);
    root(a).size += root(b).size;
    root(a).internal = w;
  }

  std::size_t size(std::int32_t r) const { return root_[static_cast<std::size_t>(r)].size; }
  float internal(std::int32_t r) const { return root_[static_cast<std::size_t>(r)].internal; }

  void prefetch(std::int32_t x) const { parents_.prefetch(x); }

 private:
  /// What a component's root holds (meaningless for other vertices).
  struct Root {
    std::uint32_t size = 1;
    float internal = 0.0f;
  };
  Root& root(std::int32_t r) { return root_[static_cast<std::size_t>(r)]; }
  DisjointSets parents_;
  std::vector<Root> root_;
};

/// The graph's edges in increasing weight, ties in increasing index (so that the result does not
/// depend on the sort), copied into one array that the scales read front to back.
std::vector<MeshEdge> edgesByWeight(const MeshGraph& graph) {
  // Each weight's bits, turned so that they order as the floats do (negatives reversed below the
  // positives; -0 taken as +0), sorted by a stable least-significant-digit radix sort: the edges
  // start in index order, so ties stay in it.
  const std::size_t n = graph.edges.size();
  std::vector<std::uint32_t> key(n), index(n), key_out(n), index_out(n);
  for (std::size_t e = 0; e < n; ++e) {
    const auto bits = std::bit_cast<std::uint32_t>(graph.edges[e].weight + 0.0f);
    key[e] = (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
    index[e] = static_cast<std::uint32_t>(e);
  }
  for (int shift = 0; shift < 32; shift += 8) {
    std::array<std::size_t, 257> start{};
    for (std::uint32_t k : key) ++start[((k >> shift) & 0xffu) + 1];
    // A digit that all keys share leaves the order as it is.
    if (std::find(start.begin(), start.end(), n) != start.end()) continue;
    std::partial_sum(start.begin(), start.end(), start.begin());
    for (std::size_t e = 0; e < n; ++e) {
      const std::size_t to = start[(key[e] >> shift) & 0xffu]++;
      key_out[to] = key[e];
      index_out[to] = index[e];
    }
    key.swap(key_out);
    index.swap(index_out);
  }
  key = {};  // freed before the copy is made: a smaller peak
  key_out = {};
  index_out = {};
  std::vector<MeshEdge> sorted(n);
  for (std::size_t k = 0; k < n; ++k) sorted[k] = graph.edges[index[k]];
  return sorted;
}

Segmentation segmentSorted(std::size_t vertex_count, const std::vector<MeshEdge>& sorted,
                           float scale, std::size_t min_size) {
  if (!(scale >= 0.0f) || !std::isfinite(scale)) {
    throw std::invalid_argument("the segmentation scale must be a finite number >= 0");
  }
  // Edges far enough ahead are prefetched: their ends are scattered over the vertices.
  constexpr std::size_t kAhead = 8;
  Components c(vertex_count);
  for (std::size_t k = 0; k < sorted.size(); ++k) {
    if (k + kAhead < sorted.size()) {
      c.prefetch(sorted[k + kAhead].a);
      c.prefetch(sorted[k + kAhead].b);
    }
    const MeshEdge& edge = sorted[k];
    const std::int32_t a = c.find(edge.a), b = c.find(edge.b);
    if (a == b) continue;
    const float limit_a = c.internal(a) + scale / static_cast<float>(c.size(a));
    const float limit_b = c.internal(b) + scale / static_cast<float>(c.size(b));
    // Edges come in increasing weight, so edge.weight is the joined tree's largest.
    if (edge.weight <= std::min(limit_a, limit_b)) c.join(a, b, edge.weight);
  }
  // Components only grow, so an edge between two that are already large enough is never taken
  // below: only the edges that touch a small one are looked at.
  std::vector<std::uint8_t> small(vertex_count);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    small[v] = c.size(c.find(static_cast<std::int32_t>(v))) < min_size ? 1 : 0;
  }
  for (const MeshEdge& edge : sorted) {
    // An edge of infinite weight is a cut (see cutAtSupports): never crossed, not even here.
    if (!std::isfinite(edge.weight)) break;
    if (!small[static_cast<std::size_t>(edge.a)] && !small[static_cast<std::size_t>(edge.b)]) {
      continue;
    }
    const std::int32_t a = c.find(edge.a), b = c.find(edge.b);
    if (a != b && (c.size(a) < min_size || c.size(b) < min_size)) {
      c.join(a, b, std::max({edge.weight, c.internal(a), c.internal(b)}));
    }
  }
  Segmentation s;
  s.scale = scale;
  s.labels.assign(vertex_count, -1);
  std::vector<std::int32_t> label_of_root(vertex_count, -1);
  for (std::size_t v = 0; v < vertex_count; ++v) {
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
  if (!(scale >= 0.0f) || !std::isfinite(scale)) {
    throw std::invalid_argument("the segmentation scale must be a finite number >= 0");
  }
  return segmentSorted(graph.vertex_count, edgesByWeight(graph), scale, min_size);
}

std::vector<Segmentation> segmentAtScales(const MeshGraph& graph, const std::vector<float>& scales,
                                          std::size_t min_size) {
  for (float scale : scales) {
    if (!(scale >= 0.0f) || !std::isfinite(scale)) {
      throw std::invalid_argument("the segmentation scale must be a finite number >= 0");
    }
  }
  const std::vector<MeshEdge> sorted = edgesByWeight(graph);
  std::vector<Segmentation> out(scales.size());
  tbb::parallel_for(std::size_t{0}, scales.size(), [&](std::size_t i) {
    out[i] = segmentSorted(graph.vertex_count, sorted, scales[i], min_size);
  });
  return out;
}

}  // namespace objscan::discovery
