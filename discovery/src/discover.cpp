#include "objscan/discovery/discover.h"

#include <array>
#include <chrono>
#include <cmath>

#include <tbb/parallel_for.h>

#include "objscan/discovery/segmentation.h"

namespace objscan::discovery {

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

ShapeMeasures measureSegment(const TriangleMesh& mesh, const MeshGraph& graph,
                             const VertexEdges& by_vertex, const Segment& segment,
                             const DiscoveryConfig& config) {
  ShapeMeasures m;
  m.compactness = compactness(mesh, segment);
  m.symmetry = symmetry(mesh, segment, config.symmetry_beta);
  m.smoothness = smoothness(mesh, segment, config.smoothness_radius_m, config.smoothness_bins);
  m.local_convexity = localConvexity(graph, by_vertex, segment);
  m.global_convexity = hullDistance(mesh, segment);
  return m;
}

std::vector<double> averageScores(const std::vector<ShapeMeasures>& all) {
  const std::size_t n = all.size();
  std::vector<double> scores(n, 0.0);
  if (n == 0) return scores;
  for (std::size_t k = 0; k < 5; ++k) {
    double mean = 0.0, square = 0.0;
    for (const ShapeMeasures& m : all) mean += orientedMeasures(m)[k];
    mean /= static_cast<double>(n);
    for (const ShapeMeasures& m : all) square += std::pow(orientedMeasures(m)[k] - mean, 2.0);
    const double sd = std::sqrt(square / static_cast<double>(n));
    // A measure that does not vary says nothing about which candidate is better.
    if (!(sd > 0.0)) continue;
    for (std::size_t i = 0; i < n; ++i)
      scores[i] += (orientedMeasures(all[i])[k] - mean) / sd / 5.0;
  }
  return scores;
}

std::vector<Hypothesis> discoverObjects(const TriangleMesh& mesh, const DiscoveryConfig& config,
                                        DiscoveryTimings* timings) {
  DiscoveryTimings t;
  auto start = Clock::now();
  const MeshGraph graph = buildMeshGraph(mesh);
  const VertexEdges by_vertex = vertexEdges(graph);
  t.graph_ms = msSince(start);

  start = Clock::now();
  const std::vector<Segmentation> segmentations =
      segmentAtScales(graph, config.scales, config.min_size);
  t.segment_ms = msSince(start);

  start = Clock::now();
  std::vector<Segment> candidates =
      candidateSegments(mesh, segmentations, config.min_size, config.filter);
  t.filter_ms = msSince(start);

  start = Clock::now();
  std::vector<ShapeMeasures> measures(candidates.size());
  tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t i) {
    measures[i] = measureSegment(mesh, graph, by_vertex, candidates[i], config);
  });
  const std::vector<double> scores = averageScores(measures);
  t.measure_ms = msSince(start);

  start = Clock::now();
  const std::vector<std::size_t> kept = suppressOverlaps(candidates, scores, config.max_iou);
  std::vector<Hypothesis> out;
  out.reserve(kept.size());
  for (std::size_t i : kept) out.push_back({std::move(candidates[i]), measures[i], scores[i]});
  t.suppress_ms = msSince(start);
  if (timings) *timings = t;
  return out;
}

}  // namespace objscan::discovery
