#include "objscan/discovery/discover.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <ctime>
#include <iomanip>
#include <limits>
#include <numeric>
#include <optional>
#include <sstream>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include "connected_regions.h"
#include "ground.h"
#include "objscan/core/clock.h"
#include "objscan/discovery/segmentation.h"
#include "plane_tests.h"
#include "stopwatch.h"

namespace objscan::discovery {

namespace {

using Clock = SteadyClock;

}  // namespace

ShapeMeasures measureSegment(const TriangleMesh& mesh, const MeshGraph& graph,
                             const SceneLookups& lookups, const Segment& segment,
                             const DiscoveryConfig& config, MeasureCpuMs* cpu_ms) {
  ShapeMeasures m;
  double last = cpu_ms ? cpuMs(CLOCK_THREAD_CPUTIME_ID) : 0.0;
  const auto lap = [&](std::size_t k) {
    if (!cpu_ms) return;
    const double now = cpuMs(CLOCK_THREAD_CPUTIME_ID);
    (*cpu_ms)[k] += now - last;
    last = now;
  };
  m.compactness = compactness(mesh, lookups.triangles, segment);
  lap(0);
  m.symmetry = symmetry(mesh, segment, config.symmetry_beta);
  lap(1);
  m.smoothness = smoothness(lookups.neighbours, segment);
  lap(2);
  m.local_convexity = localConvexity(graph, lookups.edges, segment);
  lap(3);
  m.global_convexity = hullDistance(mesh, segment);
  lap(4);
  return m;
}

std::vector<ShapeMeasures> measureCandidates(const TriangleMesh& mesh, const MeshGraph& graph,
                                             const std::vector<Segment>& candidates,
                                             const DiscoveryConfig& config, MeasureCpuMs* cpu_ms) {
  // The same segment often comes out of several scales: each distinct one is measured once,
  // largest first (so that the last to finish is a small one), and its repeats copy it.
  const std::vector<std::size_t> first = firstOfEach(candidates);
  std::vector<std::size_t> distinct;
  // 1: a vertex of a measured candidate; 2: also one smoothness is averaged over.
  std::vector<std::uint8_t> wanted(mesh.positions.size(), 0);
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (first[i] != i) continue;
    distinct.push_back(i);
    for (std::int32_t v : candidates[i].vertices) {
      std::uint8_t& w = wanted[static_cast<std::size_t>(v)];
      w = std::max<std::uint8_t>(w, 1);
    }
    for (std::int32_t v : smoothnessSample(candidates[i].vertices)) {
      wanted[static_cast<std::size_t>(v)] = 2;
    }
  }
  std::stable_sort(distinct.begin(), distinct.end(), [&](std::size_t a, std::size_t b) {
    return candidates[a].vertices.size() > candidates[b].vertices.size();
  });
  std::vector<std::int32_t> measured_vertices, smoothness_queries;
  for (std::size_t v = 0; v < wanted.size(); ++v) {
    if (wanted[v]) measured_vertices.push_back(static_cast<std::int32_t>(v));
    if (wanted[v] == 2) smoothness_queries.push_back(static_cast<std::int32_t>(v));
  }
  // The look-ups, each timed with the measure that needs it (local convexity: the edges).
  SceneLookups lookups;
  double cpu_start = cpuMs(CLOCK_PROCESS_CPUTIME_ID);
  const auto lap = [&](std::size_t k) {
    const double now = cpuMs(CLOCK_PROCESS_CPUTIME_ID);
    if (cpu_ms) (*cpu_ms)[k] += now - cpu_start;
    cpu_start = now;
  };
  lookups.edges = vertexEdges(graph);
  lap(3);
  lookups.triangles = vertexTriangles(mesh);
  lap(0);
  lookups.neighbours = tangentNeighbours(mesh, measured_vertices, config.smoothness_radius_m,
                                         config.smoothness_bins, &smoothness_queries);
  lap(2);

  std::vector<ShapeMeasures> measures(candidates.size());
  std::vector<MeasureCpuMs> cpu(distinct.size(), MeasureCpuMs{});
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, distinct.size(), 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t k = range.begin(); k < range.end(); ++k) {
          const std::size_t i = distinct[k];
          measures[i] = measureSegment(mesh, graph, lookups, candidates[i], config, &cpu[k]);
        }
      },
      tbb::simple_partitioner());
  for (std::size_t i = 0; i < candidates.size(); ++i) measures[i] = measures[first[i]];
  for (const MeasureCpuMs& c : cpu) {
    for (std::size_t k = 0; cpu_ms && k < c.size(); ++k) (*cpu_ms)[k] += c[k];
  }
  return measures;
}

void DiscoveryConfig::validate() const {
  if (scales.empty()) throw std::invalid_argument("discovery needs at least one scale");
  for (float k : scales) {
    if (!(k > 0.0f) || !std::isfinite(k)) throw std::invalid_argument("scales must be positive");
  }
  if (min_size < 1) throw std::invalid_argument("min_size must be at least 1 vertex");
  if (scale_with_density && !(reference_spacing_m > 0.0f)) {
    throw std::invalid_argument("reference_spacing_m must be positive");
  }
  if (!(max_iou > 0.0 && max_iou <= 1.0)) throw std::invalid_argument("max_iou must be in (0, 1]");
  if (!(smoothness_radius_m > 0.0f) || smoothness_bins < 2) {
    throw std::invalid_argument("smoothness needs a positive radius and at least 2 bins");
  }
  if (recurrence_neighbours < 1 || !(recurrence_window > 0.0)) {
    throw std::invalid_argument("recurrence needs k >= 1 and a positive extent window");
  }
  supports.validate();
  convexity.validate();
  objects.validate();
}

void ObjectSetConfig::validate() const {
  context.validate();
  for (const double w : {region_share_weight, single_view_region_share_weight, on_surface_penalty,
                         floating_penalty, single_view_floating_penalty, covered_penalty}) {
    if (!(w >= 0.0) || !std::isfinite(w)) {
      throw std::invalid_argument(
          "the object set's region share weight, footing penalties and covered penalty must be "
          "numbers >= 0");
    }
  }
  if (!(max_taken_share >= 0.0 && max_taken_share < 1.0)) {
    throw std::invalid_argument("the object set's max_taken_share must be in [0, 1)");
  }
}

std::string settingsKey(const DiscoveryConfig& c) {
  std::ostringstream s;
  // Bump kMeasuresVersion whenever a measure's definition changes: the catalog then recomputes.
  constexpr int kMeasuresVersion = 3;
  s << std::setprecision(9) << "measures v" << kMeasuresVersion << " scales";
  for (float k : c.scales) s << ' ' << k;
  s << " min_size " << c.min_size << " density " << c.scale_with_density << ' '
    << c.reference_spacing_m << " filter " << c.filter.max_size_m << ' ' << c.filter.min_thickness_m
    << ' ' << c.filter.min_lambda1_over_lambda0 << ' ' << c.filter.min_lambda2_over_lambda0
    << " beta " << c.symmetry_beta << " smooth " << c.smoothness_radius_m << ' '
    << c.smoothness_bins;
  // Without supports the key is what it was before they existed: catalogs keep their scenes.
  if (c.supports.enabled) {
    s << " supports " << c.supports.distance_m << ' ' << c.supports.max_angle_deg << ' '
      << c.supports.min_vertices << ' ' << c.supports.max_planes << ' '
      << c.supports.ransac_iterations << ' ' << c.supports.min_cut_off_size << " normal rings "
      << c.supports.normal_rings << '/' << c.supports.single_view_normal_rings
      << " folds one-vertex"    // the planes' RANSAC draws one vertex with its normal
      << " surface quadratic";  // heights over the support's own surface (SupportPlane::surface)
    if (c.supports.trim_feet) {
      s << " feet " << c.supports.foot_fold_m << ' ' << c.supports.foot_fold_deg << ' '
        << c.supports.foot_trim_vertices;
    }
    if (c.supports.level_tops) {
      s << " tops " << c.supports.top_level_deg << ' ' << c.supports.top_min_vertices << ' '
        << c.supports.top_flatness_m;
    }
  }
  if (c.convexity.enabled) {
    s << " convexity";
    for (float size : c.convexity.patch_sizes_m) s << ' ' << size;
    s << " /";
    for (float t : c.convexity.tolerances_deg) s << ' ' << t;
    if (!c.convexity.colour_limits.empty()) {
      s << " colour";
      for (float limit : c.convexity.colour_limits) s << ' ' << limit;
      s << " L" << c.convexity.colour_lightness_weight;
    }
    s << " / " << c.convexity.min_patch_vertices;
    if (c.convexity.crease_deg > 0.0f) s << " crease " << c.convexity.crease_deg;
  }
  return s.str();
}

EffectiveScales effectiveScales(const MeshGraph& graph, const TriangleMesh& mesh,
                                const DiscoveryConfig& config) {
  EffectiveScales e{config.scales,
                    config.min_size,
                    config.supports.min_vertices,
                    0,
                    config.objects.evidence_vertices,
                    config.supports.foot_trim_vertices,
                    config.supports.top_min_vertices,
                    0.0};
  std::size_t cut_off_size = config.supports.min_cut_off_size;
  if (!graph.edges.empty()) {
    std::vector<float> lengths(graph.edges.size());
    for (std::size_t i = 0; i < lengths.size(); ++i) {
      const MeshEdge& edge = graph.edges[i];
      lengths[i] = (mesh.positions[edge.a] - mesh.positions[edge.b]).norm();
    }
    std::nth_element(lengths.begin(), lengths.begin() + lengths.size() / 2, lengths.end());
    e.median_edge_m = lengths[lengths.size() / 2];
  }
  if (config.scale_with_density && e.median_edge_m > 0.0) {
    const double density = std::pow(config.reference_spacing_m / e.median_edge_m, 2.0);
    for (float& k : e.scales) k = static_cast<float>(k * density);
    const auto scaled = [&](std::size_t count) {
      return std::max<std::size_t>(
          1, static_cast<std::size_t>(std::lround(static_cast<double>(count) * density)));
    };
    e.min_size = scaled(config.min_size);
    e.evidence_vertices =
        config.objects.evidence_vertices == 0 ? 0 : scaled(config.objects.evidence_vertices);
    e.support_min_vertices = scaled(config.supports.min_vertices);
    e.foot_trim_vertices = scaled(config.supports.foot_trim_vertices);
    e.top_min_vertices = scaled(config.supports.top_min_vertices);
    cut_off_size = scaled(cut_off_size);
  }
  e.candidate_min_size = config.supports.enabled ? std::min(e.min_size, cut_off_size) : e.min_size;
  return e;
}

std::vector<double> averageScores(const std::vector<ShapeMeasures>& all) {
  const MeasureNormaliser normaliser = MeasureNormaliser::fit(all);
  const MeasureMask varying = varyingMeasures(normaliser);
  std::vector<double> scores(all.size(), 0.0);
  if (std::find(varying.begin(), varying.end(), true) == varying.end()) return scores;
  const ObjectnessModel average = ObjectnessModel::average(normaliser, varying);
  for (std::size_t i = 0; i < all.size(); ++i) scores[i] = average.score(all[i]);
  return scores;
}

namespace {

/// The scene's supports, or none (every vertex off them) when they are disabled.
Supports supportsOf(const TriangleMesh& mesh, const MeshGraph& graph, const DiscoveryConfig& config,
                    const EffectiveScales& effective) {
  if (config.supports.enabled) {
    return findSupports(mesh, graph, config.supports, effective.support_min_vertices);
  }
  Supports none;
  none.on_support.assign(mesh.positions.size(), 0);
  return none;
}

/// A small candidate (at most foot_trim_vertices) without its foot, the vertices `inFold` picks,
/// when that removes at least a tenth of it and what is left passes the filter.
template <class InFold>
std::optional<Segment> withoutFoot(const TriangleMesh& mesh, const Segment& s, InFold inFold,
                                   const DiscoveryConfig& config,
                                   const EffectiveScales& effective) {
  if (s.vertices.size() > effective.foot_trim_vertices) return std::nullopt;
  std::vector<std::int32_t> kept;
  for (std::int32_t v : s.vertices) {
    if (!inFold(v)) kept.push_back(v);
  }
  const std::size_t removed = s.vertices.size() - kept.size();
  if (10 * removed < s.vertices.size() || kept.size() < effective.candidate_min_size) {
    return std::nullopt;
  }
  Segment trimmed = describeSegment(mesh, std::move(kept), s.scale);
  if (rejection(trimmed, config.filter)) return std::nullopt;
  return trimmed;
}

/// Appends to `segments` each small one standing on a support again without its foot
/// (SupportConfig::trim_feet), when what is left passes the filter.
void appendTrimmedFeet(const TriangleMesh& mesh, const Supports& supports,
                       const DiscoveryConfig& config, const EffectiveScales& effective,
                       std::vector<Segment>& segments) {
  if (!config.supports.enabled || !config.supports.trim_feet || supports.planes.empty()) return;
  const float min_cos = cosOfDegrees(config.supports.foot_fold_deg);
  const auto inFold = [&](std::int32_t v) {
    const Eigen::Vector3f& p = mesh.positions[static_cast<std::size_t>(v)];
    const Eigen::Vector3f& n = mesh.normals[static_cast<std::size_t>(v)];
    return std::any_of(supports.planes.begin(), supports.planes.end(), [&](const SupportPlane& s) {
      // Against the support's own surface (SupportPlane::height), not its plane.
      return onSurface(s.height(p), s.normal, n, config.supports.foot_fold_m, min_cos);
    });
  };
  const std::size_t count = segments.size();
  for (std::size_t i = 0; i < count; ++i) {
    std::optional<Segment> trimmed = withoutFoot(mesh, segments[i], inFold, config, effective);
    if (trimmed) segments.push_back(std::move(*trimmed));
  }
}

/// A vertex lies over a level top when it is higher than the top by more than kOverTopM (the
/// fold at a thing's foot begins under it) and less than kOverTopMaxM, and no further from the
/// top's middle along it than the top reaches plus kTopMarginM.
constexpr float kOverTopM = 0.004f;
constexpr float kOverTopMaxM = 0.3f;
constexpr float kTopMarginM = 0.01f;

/// Appends the candidates that stand on level tops which are no supports
/// (SupportConfig::level_tops): `graph` is the mesh's, cut at the supports.
void appendOnLevelTops(const TriangleMesh& mesh, const MeshGraph& graph, const Supports& supports,
                       const DiscoveryConfig& config, const EffectiveScales& effective,
                       std::vector<Segment>& segments) {
  if (!config.supports.enabled || !config.supports.level_tops) return;
  const std::optional<Eigen::Vector3f> up = groundUp(supports, config.objects.context);
  if (!up) return;
  const std::size_t n = mesh.positions.size();
  const float min_cos = cosOfDegrees(config.supports.top_level_deg);
  std::vector<std::uint8_t> level(n, 0);
  for (std::size_t v = 0; v < n; ++v) {
    level[v] = !supports.on_support[v] && up->dot(mesh.normals[v]) >= min_cos;
  }
  // The level regions, their sizes and heights; the flat and large enough are tops.
  const std::vector<std::int32_t> region = connectedRegions(graph, level);
  std::vector<double> count(n, 0.0), sum(n, 0.0), sum_sq(n, 0.0);
  for (std::size_t v = 0; v < n; ++v) {
    if (!level[v]) continue;
    const std::size_t r = static_cast<std::size_t>(region[v]);
    const double h = up->dot(mesh.positions[v]);
    count[r] += 1.0;
    sum[r] += h;
    sum_sq[r] += h * h;
  }
  std::vector<std::uint8_t> is_top(n, 0);  // per region
  for (std::size_t r = 0; r < n; ++r) {
    // top_min_vertices is at least 1, so regions without vertices are passed over too.
    if (count[r] < static_cast<double>(effective.top_min_vertices)) continue;
    const double mean = sum[r] / count[r];
    const double spread = std::sqrt(std::max(0.0, sum_sq[r] / count[r] - mean * mean));
    is_top[r] = spread <= config.supports.top_flatness_m;
  }
  std::vector<std::uint8_t> on_top(n, 0);
  bool any = false;
  for (std::size_t v = 0; v < n; ++v) {
    on_top[v] = level[v] && is_top[static_cast<std::size_t>(region[v])];
    any = any || on_top[v];
  }
  if (!any) return;
  // Each top's middle, reach along it and height; what lies over a top (higher than the fold at
  // its foot, within its reach) is cut from the rest and segmented again: a thing on a lid, apart
  // from the lid's rounded edge, through which it would join the box's sides.
  struct Top {
    Eigen::Vector3f middle = Eigen::Vector3f::Zero();
    float reach = 0.0f;
    float height = 0.0f;
    std::size_t count = 0;
  };
  std::vector<Top> tops;
  std::vector<std::int32_t> top_of(n, -1);
  for (std::size_t v = 0; v < n; ++v) {
    if (!on_top[v]) continue;
    const std::size_t r = static_cast<std::size_t>(region[v]);
    if (top_of[r] < 0) {
      top_of[r] = static_cast<std::int32_t>(tops.size());
      tops.emplace_back();
    }
    Top& t = tops[static_cast<std::size_t>(top_of[r])];
    t.middle += mesh.positions[v];
    ++t.count;
  }
  const auto along = [&](const Eigen::Vector3f& d) { return alongPlane(*up, d); };
  for (Top& t : tops) t.middle /= static_cast<float>(t.count);
  for (std::size_t v = 0; v < n; ++v) {
    if (!on_top[v]) continue;
    Top& t = tops[static_cast<std::size_t>(top_of[static_cast<std::size_t>(region[v])])];
    t.reach = std::max(t.reach, along(mesh.positions[v] - t.middle));
  }
  for (Top& t : tops) t.height = up->dot(t.middle);
  // A vertex lies over the highest top under it within reach; a top's own vertices may lie over
  // a lower top (the lid of a box on a box).
  std::vector<std::uint8_t> over(n, 0);
  std::vector<float> over_height(n, 0.0f);  // the height of the top a vertex lies over
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t v = range.begin(); v < range.end(); ++v) {
          if (supports.on_support[v]) continue;
          const Eigen::Vector3f& p = mesh.positions[v];
          for (const Top& t : tops) {
            const float h = up->dot(p) - t.height;
            if (h > kOverTopM && h < kOverTopMaxM && along(p - t.middle) <= t.reach + kTopMarginM &&
                (!over[v] || t.height > over_height[v])) {
              over[v] = 1;
              over_height[v] = t.height;
            }
          }
        }
      });
  // A vertex over a top with a neighbour that is over none and higher than that top's fold
  // belongs to something larger than the top holds (the wall of a bowl round its flat bottom):
  // no thing standing on the top holds it.
  std::vector<std::uint8_t> spills(n, 0);
  for (const MeshEdge& e : graph.edges) {
    const std::size_t a = static_cast<std::size_t>(e.a), b = static_cast<std::size_t>(e.b);
    if (over[a] == over[b]) continue;
    const std::size_t in = over[a] ? a : b, out = over[a] ? b : a;
    if (!supports.on_support[out] && up->dot(mesh.positions[out]) > over_height[in] + kOverTopM) {
      spills[in] = 1;
    }
  }
  // What lies over the tops, segmented at every scale on its own (a graph of its vertices and
  // the edges among them); every other vertex a segment of one, which no candidate is.
  std::vector<std::int32_t> index(n, -1);
  std::vector<std::int32_t> members;
  for (std::size_t v = 0; v < n; ++v) {
    if (!over[v]) continue;
    index[v] = static_cast<std::int32_t>(members.size());
    members.push_back(static_cast<std::int32_t>(v));
  }
  MeshGraph sub;
  sub.vertex_count = members.size();
  for (const MeshEdge& e : graph.edges) {  // indices keep their order: edges stay sorted
    const std::int32_t a = index[static_cast<std::size_t>(e.a)];
    const std::int32_t b = index[static_cast<std::size_t>(e.b)];
    if (a >= 0 && b >= 0) sub.edges.push_back({a, b, e.weight, e.convex});
  }
  std::vector<Segmentation> segmentations =
      segmentAtScales(sub, effective.scales, effective.min_size);
  for (Segmentation& seg : segmentations) {
    std::vector<std::int32_t> labels(n);
    std::int32_t single = static_cast<std::int32_t>(seg.segment_count);
    for (std::size_t v = 0; v < n; ++v) {
      labels[v] = index[v] >= 0 ? seg.labels[static_cast<std::size_t>(index[v])] : single++;
    }
    seg.labels = std::move(labels);
    seg.segment_count = static_cast<std::size_t>(single);
  }
  const std::vector<Segment> found = candidateSegments(
      mesh, segmentations, std::max<std::size_t>(2, effective.candidate_min_size), config.filter);
  const float fold_cos = cosOfDegrees(config.supports.foot_fold_deg);
  for (const Segment& s : found) {
    if (!std::all_of(s.vertices.begin(), s.vertices.end(), [&](std::int32_t v) {
          return over[static_cast<std::size_t>(v)] && !spills[static_cast<std::size_t>(v)];
        })) {
      continue;
    }
    segments.push_back(s);
    // The top it stands on: the highest under its lowest vertex.
    const std::int32_t low = *std::min_element(
        s.vertices.begin(), s.vertices.end(), [&](std::int32_t a, std::int32_t b) {
          return up->dot(mesh.positions[static_cast<std::size_t>(a)]) <
                 up->dot(mesh.positions[static_cast<std::size_t>(b)]);
        });
    const Eigen::Vector3f& low_p = mesh.positions[static_cast<std::size_t>(low)];
    float top_height = -std::numeric_limits<float>::infinity();
    for (const Top& t : tops) {
      if (t.height < up->dot(low_p) && along(low_p - t.middle) <= t.reach + kTopMarginM) {
        top_height = std::max(top_height, t.height);
      }
    }
    // A small one also without its foot, the fold into the top (as appendTrimmedFeet does for
    // the supports).
    if (!config.supports.trim_feet) continue;
    const auto inFold = [&](std::int32_t v) {
      const std::size_t u = static_cast<std::size_t>(v);
      return onPlane(*up, -top_height, mesh.positions[u], mesh.normals[u],
                     config.supports.foot_fold_m, fold_cos);
    };
    std::optional<Segment> trimmed = withoutFoot(mesh, s, inFold, config, effective);
    if (trimmed) segments.push_back(std::move(*trimmed));
  }
}

}  // namespace

SceneCandidates findCandidates(const TriangleMesh& mesh, const DiscoveryConfig& config) {
  config.validate();
  SceneCandidates out;
  DiscoveryTimings& t = out.timings;
  Stopwatch watch;
  MeshGraph graph = buildMeshGraph(mesh);
  out.effective = effectiveScales(graph, mesh, config);
  const EffectiveScales& effective = out.effective;
  watch.stop(&t.graph_ms, &t.graph_cpu_ms);

  // The cuts change edge weights only, which nothing but segmentation reads (the measures read
  // the convexity flags): the graph is cut in place, and the measures see the mesh uncut.
  const Supports supports = supportsOf(mesh, graph, config, effective);
  if (config.supports.enabled) {
    out.support_planes = supports.planes.size();
    out.support_vertices = static_cast<std::size_t>(
        std::count(supports.on_support.begin(), supports.on_support.end(), 1));
    cutAtSupports(graph, supports.on_support);
  }
  const std::vector<std::uint8_t>& on_support = supports.on_support;
  watch.stop(&t.support_ms, &t.support_cpu_ms);

  std::vector<Segmentation> segmentations =
      segmentAtScales(graph, effective.scales, effective.min_size);
  for (Segmentation& s : convexSegmentations(mesh, graph, on_support, config.convexity)) {
    segmentations.push_back(std::move(s));
  }
  watch.stop(&t.segment_ms, &t.segment_cpu_ms);

  out.segments =
      candidateSegments(mesh, segmentations, effective.candidate_min_size, config.filter);
  appendTrimmedFeet(mesh, supports, config, effective, out.segments);
  appendOnLevelTops(mesh, graph, supports, config, effective, out.segments);
  t.candidate_count = out.segments.size();
  // A segment that several scales produce is one candidate: repeats would count twice in the
  // normalisation, in the catalog and among a segment's most similar ones for recurrence.
  const std::vector<std::size_t> first = firstOfEach(out.segments);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < first.size(); ++i) {
    if (first[i] != i) continue;
    if (kept != i) out.segments[kept] = std::move(out.segments[i]);
    ++kept;
  }
  out.segments.resize(kept);
  watch.stop(&t.filter_ms, &t.filter_cpu_ms);

  out.measures = measureCandidates(mesh, graph, out.segments, config, &t.per_measure_cpu_ms);
  out.context = segmentContexts(mesh, graph, supports, out.segments, config.objects.context);
  watch.stop(&t.measure_ms, &t.measure_cpu_ms);
  return out;
}

void addContext(const TriangleMesh& mesh, SceneCandidates& candidates,
                const DiscoveryConfig& config) {
  config.validate();
  if (!config.objects.enabled) {
    candidates.context.assign(candidates.segments.size(), SegmentContext{});
    return;
  }
  const MeshGraph graph = buildMeshGraph(mesh);
  candidates.effective = effectiveScales(graph, mesh, config);
  candidates.context =
      segmentContexts(mesh, graph, supportsOf(mesh, graph, config, candidates.effective),
                      candidates.segments, config.objects.context);
}

void addRecurrence(SceneCandidates& candidates, const RecurrenceIndex& index, std::int64_t scene_id,
                   const DiscoveryConfig& config) {
  std::vector<RecurrenceEntry> queries;
  queries.reserve(candidates.segments.size());
  for (std::size_t i = 0; i < candidates.segments.size(); ++i) {
    queries.push_back(
        {scene_id, candidates.segments[i].extents, recurrenceMeasures(candidates.measures[i])});
  }
  const std::vector<double> r =
      index.recurrences(queries, scene_id, config.recurrence_neighbours, config.recurrence_window);
  for (std::size_t i = 0; i < r.size(); ++i) candidates.measures[i].recurrence = r[i];
}

namespace {

/// Each candidate's score under `model`.
std::vector<double> scoresOf(const SceneCandidates& candidates, const ObjectnessModel& model) {
  std::vector<double> scores;
  scores.reserve(candidates.measures.size());
  for (const ShapeMeasures& m : candidates.measures) scores.push_back(model.score(m));
  return scores;
}

std::vector<Hypothesis> suppress(const SceneCandidates& candidates,
                                 const std::vector<double>& scores, double max_iou) {
  const std::vector<std::size_t> kept = suppressOverlaps(candidates.segments, scores, max_iou);
  std::vector<Hypothesis> out;
  out.reserve(kept.size());
  for (std::size_t i : kept) {
    Hypothesis h;
    h.segment = candidates.segments[i];
    h.measures = candidates.measures[i];
    h.score = scores[i];
    if (candidates.context.size() == candidates.segments.size()) h.context = candidates.context[i];
    out.push_back(std::move(h));
  }
  return out;
}

}  // namespace

std::vector<Hypothesis> rankCandidates(const SceneCandidates& candidates,
                                       const ObjectnessModel& model, double max_iou) {
  return suppress(candidates, scoresOf(candidates, model), max_iou);
}

/// The smallest region share the object score's logarithm takes (ObjectSetConfig).
constexpr double kMinRegionShare = 0.001;

/// ObjectSetConfig::covered_penalty, in full from kCoveredFull of floating surface over a
/// candidate (SegmentContext::covered_share), in part from kCoveredFrom.
constexpr double kCoveredFrom = 0.1;
constexpr double kCoveredFull = 0.4;

double coveredPenalty(const SegmentContext& c, double penalty) {
  if (!(c.covered_share > kCoveredFrom)) return 0.0;  // NaN: not measured
  return penalty * std::min(1.0, (c.covered_share - kCoveredFrom) / (kCoveredFull - kCoveredFrom));
}

std::vector<Hypothesis> rankObjects(const TriangleMesh& mesh, const SceneCandidates& candidates,
                                    const ObjectnessModel& model, const DiscoveryConfig& config) {
  if (!config.objects.enabled) return rankCandidates(candidates, model, config.max_iou);
  const std::size_t n = candidates.segments.size();
  const std::vector<double> scores = scoresOf(candidates, model);
  if (candidates.context.size() != n) {
    throw std::invalid_argument("rankObjects needs the context of every candidate");
  }
  const double evidence = static_cast<double>(candidates.effective.evidence_vertices);
  std::vector<double> object_scores(n);
  for (std::size_t i = 0; i < n; ++i) {
    const SegmentContext& c = candidates.context[i];
    double count = static_cast<double>(candidates.segments[i].vertices.size());
    if (config.objects.weigh_by_observation && std::isfinite(c.observation)) {
      count = std::max(1.0, count * std::min(1.0, c.observation));
    }
    const double f = evidence > 0.0 ? count / (count + evidence) : 1.0;
    // A patch of a support stands on nothing of its own, and what reaches up to a support is
    // part of what holds it: they pay what a floating one does.
    const double penalty = c.footing == Footing::kSupport     ? 0.0
                           : c.footing == Footing::kOnSurface ? config.objects.on_surface_penalty
                                                              : config.objects.floating_penalty;
    object_scores[i] = (scores[i] >= 0.0 ? scores[i] * f : scores[i] / f) +
                       config.objects.region_share_weight *
                           std::log(std::max(c.share_of_region, kMinRegionShare)) -
                       penalty - coveredPenalty(c, config.objects.covered_penalty);
  }
  // By object score; ties keep the candidates' order.
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return object_scores[a] > object_scores[b];
  });
  std::vector<std::uint8_t> taken(mesh.positions.size(), 0);
  std::vector<Hypothesis> objects;
  std::vector<std::uint8_t> chosen(n, 0);
  for (std::size_t i : order) {
    const Segment& s = candidates.segments[i];
    std::size_t overlap = 0;
    for (std::int32_t v : s.vertices) overlap += taken[static_cast<std::size_t>(v)];
    if (static_cast<double>(overlap) >
        config.objects.max_taken_share * static_cast<double>(s.vertices.size())) {
      continue;
    }
    Segment kept = s;
    if (overlap > 0) {
      std::vector<std::int32_t> rest;
      rest.reserve(s.vertices.size() - overlap);
      for (std::int32_t v : s.vertices) {
        if (!taken[static_cast<std::size_t>(v)]) rest.push_back(v);
      }
      kept = describeSegment(mesh, std::move(rest), s.scale);
    }
    for (std::int32_t v : kept.vertices) taken[static_cast<std::size_t>(v)] = 1;
    chosen[i] = 1;
    Hypothesis h{std::move(kept),       candidates.measures[i], scores[i],
                 candidates.context[i], object_scores[i],       objects.size() + 1};
    objects.push_back(std::move(h));
  }
  // The alternatives: what suppression keeps that is neither an object nor, by suppression's own
  // measure, a near copy of one (a candidate that outscores an object it overlaps at IoU above
  // max_iou suppresses it, and would list it again), by score.
  const std::size_t object_count = objects.size();
  for (std::size_t i : suppressOverlaps(candidates.segments, scores, config.max_iou)) {
    if (chosen[i]) continue;
    const Segment& s = candidates.segments[i];
    bool copy = false;
    for (std::size_t k = 0; k < object_count && !copy; ++k) {
      const std::vector<std::int32_t>& o = objects[k].segment.vertices;
      if (s.vertices.back() < o.front() || o.back() < s.vertices.front()) continue;
      copy = vertexIoU(s.vertices, o) > config.max_iou;
    }
    if (copy) continue;
    objects.push_back(
        {s, candidates.measures[i], scores[i], candidates.context[i], object_scores[i], 0});
  }
  return objects;
}

}  // namespace objscan::discovery
