#include "objscan/discovery/context.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "connected_regions.h"
#include "plane_tests.h"
#include "point_index.h"

namespace objscan::discovery {

namespace {

/// A support plane turned so that its normal points to the free side, where the things standing
/// on it are: the side its own vertices' normals face (fused and single-view normals point out of
/// the surface, towards where the camera was).
struct UpPlane {
  Eigen::Vector3f up;
  float offset;
  float height(const Eigen::Vector3f& p) const { return up.dot(p) + offset; }
};

/// A support vertex belongs to a plane's own surface (for its orientation) within this distance
/// of it: twice the supports' band (SupportConfig::distance_m).
constexpr float kOwnSurfaceM = 0.02f;

std::vector<UpPlane> orientedPlanes(const TriangleMesh& mesh, const Supports& supports) {
  std::vector<UpPlane> planes;
  for (const SupportPlane& p : supports.planes) {
    double facing = 0.0;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      if (!supports.on_support[v]) continue;
      if (std::abs(p.normal.dot(mesh.positions[v]) + p.offset) > kOwnSurfaceM) continue;
      facing += p.normal.dot(mesh.normals[v]);
    }
    planes.push_back(facing >= 0.0 ? UpPlane{p.normal, p.offset} : UpPlane{-p.normal, -p.offset});
  }
  return planes;
}

/// The ground among `planes` (supports' `planes`, turned): the largest whose free side lies
/// within `up_hint_deg` of the camera's up (a small slope nearer the hint does not outvote the
/// floor or the table); -1 without a hint or with none near it.
int groundPlane(const std::vector<UpPlane>& planes, const std::vector<SupportPlane>& supports,
                const ContextConfig& config) {
  if (!config.view_up) return -1;
  const Eigen::Vector3f hint = config.view_up->normalized();
  const float min_cos = cosOfDegrees(config.up_hint_deg);
  int ground = -1;
  for (std::size_t k = 0; k < planes.size(); ++k) {
    if (planes[k].up.dot(hint) < min_cos) continue;
    if (ground < 0 ||
        supports[k].vertex_count > supports[static_cast<std::size_t>(ground)].vertex_count) {
      ground = static_cast<int>(k);
    }
  }
  return ground;
}

bool contains(const std::vector<std::int32_t>& sorted, std::int32_t v) {
  return std::binary_search(sorted.begin(), sorted.end(), v);
}

/// How far from a candidate's foot the support's own vertices may begin: the rounded fold where
/// an object meets its support goes with the object (SupportConfig::max_angle_deg), about a
/// voxel or two wide.
constexpr float kSupportSearchM = 0.02f;

/// A surface faces up when its normal lies within this angle of the support's (the support
/// regions' own tolerance, SupportConfig::max_angle_deg).
constexpr float kUpFacingDeg = 25.0f;
/// ... and holds a candidate up when at least this many of its vertices lie under the foot.
constexpr std::size_t kMinSurfaceUnder = 5;

/// A candidate reaches up to a support over it (Footing::kUnder) when its highest vertex lies at
/// most kUnderM under that support's plane (a table top's thickness and its frame), and the
/// support covers its top: vertices of the support within kCoverM of the points right over it.
constexpr float kUnderM = 0.15f;
constexpr float kCoverM = 0.03f;

/// The support's noise is measured over its vertices this close to a candidate's foot.
constexpr float kNoiseRadiusM = 0.05f;

/// What the first pass finds of one candidate.
struct Lowest {
  int plane = -1;       ///< the plane it is measured against (under it), -1 without one
  float height = 0.0f;  ///< its lowest vertex's height above that plane
};

/// How far a candidate's foot reaches above its lowest point, and how far from it what holds it
/// up may lie: the config's gap, or gap_edges of its own mean edge length.
float footGap(const ContextConfig& config, const SegmentContext& c) {
  return std::max(config.gap_m, config.gap_edges * static_cast<float>(c.mean_edge_m));
}

/// The vertices of `vertices` whose heights over `plane` lie in [min_height, max_height].
std::vector<std::int32_t> verticesBetween(const TriangleMesh& mesh,
                                          const std::vector<std::int32_t>& vertices,
                                          const UpPlane& plane, float min_height,
                                          float max_height) {
  std::vector<std::int32_t> out;
  for (std::int32_t v : vertices) {
    const float h = plane.height(mesh.positions[static_cast<std::size_t>(v)]);
    if (h >= min_height && h <= max_height) out.push_back(v);
  }
  return out;
}

/// A candidate's foot: its vertices at most `max_height` over `plane`.
std::vector<std::int32_t> footOf(const TriangleMesh& mesh,
                                 const std::vector<std::int32_t>& vertices, const UpPlane& plane,
                                 float max_height) {
  return verticesBetween(mesh, vertices, plane, -std::numeric_limits<float>::infinity(),
                         max_height);
}

/// Every k-th index of a list of `size`, so that at most `most` are visited.
std::size_t strideFor(std::size_t size, std::size_t most) {
  return std::max<std::size_t>(1, (size + most - 1) / most);
}

}  // namespace

const char* toString(Footing footing) {
  switch (footing) {
    case Footing::kSupport:
      return "support";
    case Footing::kOnSurface:
      return "surface";
    case Footing::kPatch:
      return "patch";
    case Footing::kUnder:
      return "under";
    case Footing::kNone:
      break;
  }
  return "none";
}

void ContextConfig::validate() const {
  if (!(gap_m >= 0.0f) || !std::isfinite(gap_m) || !(gap_edges >= 0.0f) ||
      !std::isfinite(gap_edges)) {
    throw std::invalid_argument("the context's gap must be a finite number >= 0");
  }
  if (!(min_rise_noises >= 0.0) || !std::isfinite(min_rise_noises) || !(min_rise_m >= 0.0) ||
      !std::isfinite(min_rise_m)) {
    throw std::invalid_argument("the context's least rise must be a finite number >= 0");
  }
  if (!(below_m >= 0.0f) || !std::isfinite(below_m)) {
    throw std::invalid_argument("the context's depth below a support must be a finite number >= 0");
  }
  if (view_up && (!view_up->allFinite() || !(view_up->norm() > 0.0f))) {
    throw std::invalid_argument("the camera's up must be a finite, non-zero direction");
  }
  if (!(up_hint_deg >= 0.0f && up_hint_deg <= 90.0f) ||
      !(level_deg >= 0.0f && level_deg <= 90.0f)) {
    throw std::invalid_argument("the context's angles to up must lie in [0, 90] degrees");
  }
}

std::vector<SegmentContext> segmentContexts(const TriangleMesh& mesh, const MeshGraph& graph,
                                            const Supports& supports,
                                            const std::vector<Segment>& segments,
                                            const ContextConfig& config) {
  config.validate();
  const std::size_t n = mesh.positions.size();
  if (!mesh.hasNormals()) throw std::invalid_argument("segmentContexts needs the mesh's normals");
  if (supports.on_support.size() != n || graph.vertex_count != n) {
    throw std::invalid_argument(
        "segmentContexts needs a graph and one support flag per mesh vertex");
  }
  for (const Segment& s : segments) {
    if (s.vertices.empty() || s.vertices.front() < 0 ||
        static_cast<std::size_t>(s.vertices.back()) >= n) {
      throw std::invalid_argument("a segment indexes outside the mesh");
    }
  }
  const std::vector<UpPlane> planes = orientedPlanes(mesh, supports);
  // The planes that hold candidates up: those level with the ground when the camera's up finds
  // one, else all.
  const int ground = groundPlane(planes, supports.planes, config);
  std::vector<bool> holds(planes.size(), true);
  if (ground >= 0) {
    const float min_level_cos = cosOfDegrees(config.level_deg);
    for (std::size_t k = 0; k < planes.size(); ++k) {
      holds[k] = static_cast<int>(k) == ground ||
                 planes[k].up.dot(planes[static_cast<std::size_t>(ground)].up) >= min_level_cos;
    }
  }

  // The mesh off the supports in connected regions, and how many vertices each holds.
  std::vector<std::uint8_t> off_support(n);
  for (std::size_t v = 0; v < n; ++v) off_support[v] = !supports.on_support[v];
  const std::vector<std::int32_t> region = connectedRegions(graph, off_support);
  std::vector<std::size_t> region_size(n, 0);
  for (std::size_t v = 0; v < n; ++v) {
    if (off_support[v]) ++region_size[static_cast<std::size_t>(region[v])];
  }
  // Mean edge length around each vertex: a candidate's noise scale is the mean over its own.
  std::vector<float> edge_sum(n, 0.0f);
  std::vector<std::uint16_t> edge_count(n, 0);
  for (const MeshEdge& e : graph.edges) {
    const float length = (mesh.positions[static_cast<std::size_t>(e.a)] -
                          mesh.positions[static_cast<std::size_t>(e.b)])
                             .norm();
    for (std::int32_t v : {e.a, e.b}) {
      edge_sum[static_cast<std::size_t>(v)] += length;
      if (edge_count[static_cast<std::size_t>(v)] < 0xffff)
        ++edge_count[static_cast<std::size_t>(v)];
    }
  }
  // The scene's median vertex weight: a candidate's observation is its mean over this.
  double median_weight = std::numeric_limits<double>::quiet_NaN();
  if (mesh.hasWeights()) {
    std::vector<float> w = mesh.weights;
    std::nth_element(w.begin(), w.begin() + static_cast<std::ptrdiff_t>(w.size() / 2), w.end());
    if (w[w.size() / 2] > 0.0f) median_weight = w[w.size() / 2];
  }
  std::vector<Eigen::Vector3f> support_points;
  std::vector<std::size_t> support_vertex;
  for (std::size_t v = 0; v < n; ++v) {
    if (!supports.on_support[v]) continue;
    support_points.push_back(mesh.positions[v]);
    support_vertex.push_back(v);
  }
  const float min_cos = cosOfDegrees(kUpFacingDeg);
  const PointIndex support_index(support_points);

  // Whether a candidate standing on plane `k` reaches up to another holding plane over it: its
  // top within kUnderM under that plane, which covers it (the plane's own surface, facing as it
  // does: not a wall's vertices or a fold near that height).
  auto reachesUp = [&](const Segment& s, std::size_t k) {
    std::vector<std::pair<std::uint32_t, float>> near;
    for (std::size_t j = 0; j < planes.size(); ++j) {
      if (j == k || !holds[j] || planes[j].up.dot(planes[k].up) < min_cos) continue;
      float top = -std::numeric_limits<float>::infinity();
      for (std::int32_t v : s.vertices) {
        top = std::max(top, planes[j].height(mesh.positions[static_cast<std::size_t>(v)]));
      }
      if (top < -kUnderM || top > config.below_m) continue;
      const std::vector<std::int32_t> crown =
          verticesBetween(mesh, s.vertices, planes[j], top - kCoverM, top);
      const std::size_t stride = strideFor(crown.size(), 64);
      for (std::size_t f = 0; f < crown.size(); f += stride) {
        const Eigen::Vector3f& p = mesh.positions[static_cast<std::size_t>(crown[f])];
        support_index.within(p - planes[j].height(p) * planes[j].up, kCoverM, &near);
        for (const auto& [point, distance_sq] : near) {
          if (std::abs(planes[j].height(support_points[point])) <= kOwnSurfaceM &&
              planes[j].up.dot(mesh.normals[support_vertex[point]]) >= min_cos) {
            return true;
          }
        }
      }
    }
    return false;
  };

  std::vector<SegmentContext> out(segments.size());
  std::vector<Lowest> lowest(segments.size());
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, segments.size()),
      [&](const tbb::blocked_range<std::size_t>& range) {
        std::vector<std::pair<std::uint32_t, float>> found;
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          const Segment& s = segments[i];
          SegmentContext& c = out[i];
          double edges = 0.0, count = 0.0;
          std::size_t in_region = 0;
          std::int32_t own_region = -1;
          for (std::int32_t v : s.vertices) {
            edges += edge_sum[static_cast<std::size_t>(v)];
            count += edge_count[static_cast<std::size_t>(v)];
            if (own_region < 0 && !supports.on_support[static_cast<std::size_t>(v)]) {
              own_region = region[static_cast<std::size_t>(v)];
            }
          }
          c.mean_edge_m = count > 0.0 ? edges / count : 0.0;
          if (std::isfinite(median_weight)) {
            double weight = 0.0;
            for (std::int32_t v : s.vertices) weight += mesh.weights[static_cast<std::size_t>(v)];
            c.observation = weight / static_cast<double>(s.vertices.size()) / median_weight;
          }
          for (std::int32_t v : s.vertices) {
            in_region += region[static_cast<std::size_t>(v)] == own_region &&
                         !supports.on_support[static_cast<std::size_t>(v)];
          }
          if (own_region >= 0) {
            c.share_of_region =
                static_cast<double>(in_region) /
                static_cast<double>(region_size[static_cast<std::size_t>(own_region)]);
          }
          const float gap = footGap(config, c);
          // Against each plane: the lowest vertex; the candidate stands on the first plane whose
          // support is right under that vertex, else it is measured against the nearest plane it
          // lies above.
          Lowest& low = lowest[i];
          for (std::size_t k = 0; k < planes.size(); ++k) {
            float min_height = std::numeric_limits<float>::infinity(), rise = 0.0f;
            for (std::int32_t v : s.vertices) {
              const float h = planes[k].height(mesh.positions[static_cast<std::size_t>(v)]);
              min_height = std::min(min_height, h);
              rise = std::max(rise, h);
            }
            if (!holds[k] || min_height < -config.below_m) continue;  // a wall; through, under
            // Its foot: vertices within the gap of the plane (at most 64, spread evenly); it stands
            // when one of them has the support's surface near (the support, not a hole's floor).
            bool on = false;
            std::vector<std::int32_t> foot;
            if (min_height <= gap && !support_points.empty()) {
              foot = footOf(mesh, s.vertices, planes[k], gap);
              const std::size_t stride = strideFor(foot.size(), 64);
              for (std::size_t f = 0; !on && f < foot.size(); f += stride) {
                support_index.within(mesh.positions[static_cast<std::size_t>(foot[f])],
                                     gap + kSupportSearchM, &found);
                on = !found.empty();
              }
            }
            if (on) {
              c.footing = Footing::kSupport;
              low = {static_cast<int>(k), min_height};
              // How far it rises over the support, against the support's own noise around its foot
              // (the RMS height of the support's vertices within kNoiseRadiusM of a few foot
              // vertices): a patch of a noisy table cut off by the support's 1 cm band rises no
              // more than the table's noise.
              double sum_sq = 0.0;
              std::size_t count_sq = 0;
              const std::size_t every = strideFor(foot.size(), 8);
              for (std::size_t f = 0; f < foot.size(); f += every) {
                support_index.within(mesh.positions[static_cast<std::size_t>(foot[f])],
                                     kNoiseRadiusM, &found);
                for (const auto& [point, distance_sq] : found) {
                  // This plane's own surface: not a wall's beside it, whose heights are not noise.
                  if (planes[k].up.dot(mesh.normals[support_vertex[point]]) < min_cos) continue;
                  const double h = planes[k].height(support_points[point]);
                  sum_sq += h * h;
                  ++count_sq;
                }
              }
              c.rise_m = rise;
              c.support_noise_m =
                  count_sq ? std::sqrt(sum_sq / static_cast<double>(count_sq)) : 0.0;
              if (rise <
                  std::max<double>(config.min_rise_m, config.min_rise_noises * c.support_noise_m)) {
                c.footing = Footing::kPatch;
              } else if (reachesUp(s, k)) {
                c.footing = Footing::kUnder;
              }
              break;
            }
            if (low.plane < 0 || min_height < low.height) {
              low = {static_cast<int>(k), min_height};
            }
          }
          if (low.plane >= 0) c.height_m = low.height;
        }
      });

  // Stacks and boards too small to be supports: a candidate whose foot rests on a surface that
  // faces up (as its support's plane does), level with or under the foot and not its own, stands
  // on that: a box on a box, a can on a shelf board that no support plane holds.
  // Up is the ground's normal or, without one, that of the plane most candidates stand on (a
  // table, the floor, a shelf board): a candidate's own lowest plane may be the wall it leans on.
  std::vector<std::size_t> standing(planes.size(), 0);
  for (std::size_t i = 0; i < segments.size(); ++i) {
    if (out[i].footing == Footing::kSupport || out[i].footing == Footing::kPatch ||
        out[i].footing == Footing::kUnder) {
      ++standing[static_cast<std::size_t>(lowest[i].plane)];
    }
  }
  if (ground >= 0) standing[static_cast<std::size_t>(ground)] = segments.size() + 1;
  if (planes.empty() || *std::max_element(standing.begin(), standing.end()) == 0) return out;
  const UpPlane& plane = planes[static_cast<std::size_t>(
      std::max_element(standing.begin(), standing.end()) - standing.begin())];
  const PointIndex all_index(mesh.positions);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, segments.size()),
      [&](const tbb::blocked_range<std::size_t>& range) {
        std::vector<std::pair<std::uint32_t, float>> found;
        std::vector<std::int32_t> under;
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          SegmentContext& c = out[i];
          if (c.footing != Footing::kNone || lowest[i].plane < 0) continue;
          const Segment& s = segments[i];
          float lowest_height = std::numeric_limits<float>::infinity();
          for (std::int32_t v : s.vertices) {
            lowest_height =
                std::min(lowest_height, plane.height(mesh.positions[static_cast<std::size_t>(v)]));
          }
          const float gap = footGap(config, c);
          // Its foot: the vertices within the gap of its lowest, at most 64 of them spread evenly.
          const std::vector<std::int32_t> foot =
              footOf(mesh, s.vertices, plane, lowest_height + gap);
          const std::size_t stride = strideFor(foot.size(), 64);
          under.clear();
          for (std::size_t f = 0; f < foot.size(); f += stride) {
            const Eigen::Vector3f& p = mesh.positions[static_cast<std::size_t>(foot[f])];
            const float foot_height = plane.height(p);
            all_index.within(p, gap, &found);
            for (const auto& [u, distance_sq] : found) {
              const std::int32_t v = static_cast<std::int32_t>(u);
              if (contains(s.vertices, v)) continue;
              if (plane.up.dot(mesh.normals[u]) < min_cos) continue;
              if (plane.height(mesh.positions[u]) > foot_height + 0.5f * gap) continue;
              under.push_back(v);
            }
          }
          std::sort(under.begin(), under.end());
          under.erase(std::unique(under.begin(), under.end()), under.end());
          if (under.size() >= kMinSurfaceUnder) c.footing = Footing::kOnSurface;
        }
      });
  return out;
}

}  // namespace objscan::discovery
