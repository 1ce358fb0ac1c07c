#include "objscan/discovery/context.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "connected_regions.h"
#include "ground.h"
#include "objscan/discovery/shape_measures.h"
#include "plane_tests.h"
#include "point_index.h"

namespace objscan::discovery {

namespace {

/// A support seen from its free side (SupportPlane::up_sign): its normal turned there, and
/// heights over its own surface (SupportPlane::height, which a fused table bends away from its
/// plane) counted up from it.
struct UpPlane {
  Eigen::Vector3f up;
  const SupportPlane* support;
  float height(const Eigen::Vector3f& p) const { return support->up_sign * support->height(p); }
};

std::vector<UpPlane> orientedPlanes(const Supports& supports) {
  std::vector<UpPlane> planes;
  for (const SupportPlane& p : supports.planes) planes.push_back({p.up(), &p});
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

/// Which candidates hold each vertex: what a candidate resting on a surface may rest on.
class VertexSegments {
 public:
  VertexSegments(const std::vector<Segment>& segments, std::size_t vertex_count)
      : start_(vertex_count + 1, 0) {
    for (const Segment& s : segments) {
      for (std::int32_t v : s.vertices) ++start_[static_cast<std::size_t>(v) + 1];
    }
    std::partial_sum(start_.begin(), start_.end(), start_.begin());
    segment_.resize(start_.back());
    std::vector<std::size_t> next(start_.begin(), start_.end() - 1);
    for (std::size_t j = 0; j < segments.size(); ++j) {
      for (std::int32_t v : segments[j].vertices) {
        segment_[next[static_cast<std::size_t>(v)]++] = static_cast<std::uint32_t>(j);
      }
    }
  }

  /// Whether `surface` (sorted) belongs to a candidate that stands (on a support or a surface)
  /// and holds at least kMinSurfaceUnder of it and at most a tenth of `own` (sorted; one
  /// holding the stacked candidate too is not under it). `hits` is scratch.
  bool holds(const std::vector<Segment>& segments, const std::vector<SegmentContext>& context,
             const std::vector<std::int32_t>& surface, const std::vector<std::int32_t>& own,
             std::vector<std::uint32_t>* hits) const {
    hits->clear();
    for (std::int32_t v : surface) {
      const std::size_t at = static_cast<std::size_t>(v);
      hits->insert(hits->end(), segment_.begin() + static_cast<std::ptrdiff_t>(start_[at]),
                   segment_.begin() + static_cast<std::ptrdiff_t>(start_[at + 1]));
    }
    std::sort(hits->begin(), hits->end());
    for (std::size_t a = 0; a < hits->size();) {
      std::size_t b = a;
      while (b < hits->size() && (*hits)[b] == (*hits)[a]) ++b;
      const std::uint32_t j = (*hits)[a];
      if (b - a >= kMinSurfaceUnder &&
          sharedVertexCount(segments[j].vertices, own) * 10 <= own.size()) {
        if (context[j].footing == Footing::kSupport || context[j].footing == Footing::kOnSurface) {
          return true;
        }
      }
      a = b;
    }
    return false;
  }

 private:
  std::vector<std::size_t> start_;
  std::vector<std::uint32_t> segment_;
};


/// A level surface around a candidate's foot counts as broad, holding it up without a standing
/// candidate of its own (a counter or a board no support plane found), when its vertices in the
/// ring kBroadRingM wide around the candidate's footprint cover at least kBroadCover of the ring.
constexpr float kBroadRingM = 0.03f;
constexpr double kBroadCover = 0.25;

/// The farthest of `vertices` from `centre` along a plane whose normal is `up`.
float farthestAlong(const TriangleMesh& mesh, const std::vector<std::int32_t>& vertices,
                    const Eigen::Vector3f& up, const Eigen::Vector3f& centre) {
  float farthest = 0.0f;
  for (std::int32_t v : vertices) {
    farthest =
        std::max(farthest, alongPlane(up, mesh.positions[static_cast<std::size_t>(v)] - centre));
  }
  return farthest;
}

bool broadLevelSurface(const TriangleMesh& mesh, const PointIndex& all_index, const UpPlane& plane,
                       const Segment& s, const std::vector<std::int32_t>& surface, float gap,
                       double mean_edge_m, float min_cos) {
  if (surface.empty() || !(mean_edge_m > 0.0)) return false;
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  float height = 0.0f;
  for (std::int32_t v : surface) {
    centre += mesh.positions[static_cast<std::size_t>(v)];
    height += plane.height(mesh.positions[static_cast<std::size_t>(v)]);
  }
  centre /= static_cast<float>(surface.size());
  height /= static_cast<float>(surface.size());
  auto across = [&](const Eigen::Vector3f& p) { return alongPlane(plane.up, p - centre); };
  const float radius = farthestAlong(mesh, s.vertices, plane.up, centre);
  std::vector<std::pair<std::uint32_t, float>> found;
  all_index.within(centre - (plane.height(centre) - height) * plane.up, radius + kBroadRingM,
                   &found);
  std::size_t in_ring = 0;
  for (const auto& [point, distance_sq] : found) {
    const Eigen::Vector3f& p = mesh.positions[point];
    if (plane.up.dot(mesh.normals[point]) < min_cos) continue;
    if (std::abs(plane.height(p) - height) > 0.5f * gap || across(p) <= radius) continue;
    if (contains(s.vertices, static_cast<std::int32_t>(point))) continue;
    ++in_ring;
  }
  const double ring_area = M_PI * (std::pow(radius + kBroadRingM, 2.0) - std::pow(radius, 2.0));
  const double vertex_area = std::sqrt(3.0) / 2.0 * mean_edge_m * mean_edge_m;
  return static_cast<double>(in_ring) >= kBroadCover * ring_area / vertex_area;
}

/// A candidate resting on a surface makes a storey of its own only when it is at least this
/// share of its region as it is (before the cut): a box on a box, not a crumb on a leaf. Chosen
/// on the synthetic tuning views (seeds 3101-3106) and mOSD learn's stacked views (learn17-24):
/// docs/discovery.md, "Single views of clutter".
constexpr double kMinStoreyShare = 0.25;

/// How many rings of mesh neighbours a resting candidate's storey reaches past its own vertices
/// (shareOfStoreys): a segment often leaves a thin strip of its object's side out.
constexpr int kStoreyRings = 4;

/// Each candidate's share of region (SegmentContext::share_of_region) once the regions off the
/// supports are cut where a candidate rests on a surface (footing kOnSurface) that belongs to
/// another candidate that stands (`on_standing`: a box on a box, not a part of an object on
/// another part of it) and is at least kMinStoreyShare of its region. Its storey is its
/// vertices and the vertices off the supports within kStoreyRings rings of them that do not face
/// up (cosine to `plane`'s up under `min_cos`) and lie no lower than half a gap under its lowest:
/// a strip of its side its segment left out, not the surface it rests on nor the sides of what
/// holds it. The graph's edges from the storey's foot (its vertices at most `foot_top` over
/// `plane`) to vertices outside it are left out. What a storey takes in beyond its candidate
/// (the crease where it meets what holds it, a strip of its side) counts for no candidate and
/// no region. The cuts of all storeys apply together, so two overlapping candidates that both
/// make storeys (a segment and the same box short of a strip) cut through each other's edges too.
/// Once a view has a storey, every candidate's share is measured this way; a candidate left with
/// no vertex counted keeps its share as it was. Without one, shares stay as they were (the two
/// agree where nothing is cut).
void shareOfStoreys(const TriangleMesh& mesh, const MeshGraph& graph,
                    const std::vector<std::uint8_t>& off_support, const UpPlane& plane,
                    float min_cos, const std::vector<Segment>& segments,
                    const std::vector<float>& foot_top, const std::vector<float>& gaps,
                    const std::vector<std::uint8_t>& on_standing,
                    std::vector<SegmentContext>* context) {
  const auto storey_of = [&](std::size_t i) {
    return (*context)[i].footing == Footing::kOnSurface && on_standing[i] &&
           (*context)[i].share_of_region >= kMinStoreyShare;
  };
  bool any_storey = false;
  for (std::size_t i = 0; i < segments.size() && !any_storey; ++i) any_storey = storey_of(i);
  if (!any_storey) return;
  const std::size_t n = off_support.size();
  const VertexEdges by_vertex = vertexEdges(graph);
  const std::vector<std::size_t>& start = by_vertex.offsets;
  const std::vector<std::int32_t>& at = by_vertex.edges;
  const auto other = [&](std::int32_t k, std::int32_t v) {
    const MeshEdge& e = graph.edges[static_cast<std::size_t>(k)];
    return e.a == v ? e.b : e.a;
  };
  std::vector<std::uint8_t> cut(graph.edges.size(), 0);
  // The vertices a storey took in beyond its candidate (the crease where it meets its holder, a
  // strip of its side): counted for no candidate and no region.
  std::vector<std::uint8_t> contact(n, 0);
  std::vector<std::int32_t> storey, ring, next_ring;
  bool any = false;
  for (std::size_t i = 0; i < segments.size(); ++i) {
    if (!storey_of(i)) continue;
    const float lowest_kept = foot_top[i] - 1.5f * gaps[i];  // half a gap under its lowest
    storey = segments[i].vertices;
    ring = storey;
    for (int r = 0; r < kStoreyRings && !ring.empty(); ++r) {
      next_ring.clear();
      for (std::int32_t v : ring) {
        for (std::size_t k = start[static_cast<std::size_t>(v)];
             k < start[static_cast<std::size_t>(v) + 1]; ++k) {
          const std::int32_t w = other(at[k], v);
          if (off_support[static_cast<std::size_t>(w)] &&
              plane.height(mesh.positions[static_cast<std::size_t>(w)]) >= lowest_kept &&
              plane.up.dot(mesh.normals[static_cast<std::size_t>(w)]) < min_cos) {
            next_ring.push_back(w);
          }
        }
      }
      std::sort(next_ring.begin(), next_ring.end());
      next_ring.erase(std::unique(next_ring.begin(), next_ring.end()), next_ring.end());
      ring.clear();
      std::set_difference(next_ring.begin(), next_ring.end(), storey.begin(), storey.end(),
                          std::back_inserter(ring));
      const std::size_t old_size = storey.size();
      storey.insert(storey.end(), ring.begin(), ring.end());
      std::inplace_merge(storey.begin(), storey.begin() + static_cast<std::ptrdiff_t>(old_size),
                         storey.end());
      for (std::int32_t v : ring) contact[static_cast<std::size_t>(v)] = 1;
    }
    for (std::int32_t v : storey) {
      if (plane.height(mesh.positions[static_cast<std::size_t>(v)]) > foot_top[i]) continue;
      for (std::size_t k = start[static_cast<std::size_t>(v)];
           k < start[static_cast<std::size_t>(v) + 1]; ++k) {
        if (!contains(storey, other(at[k], v))) {
          cut[static_cast<std::size_t>(at[k])] = 1;
          any = true;
        }
      }
    }
  }
  if (!any) return;
  MeshGraph storeys;
  storeys.vertex_count = graph.vertex_count;
  for (std::size_t k = 0; k < graph.edges.size(); ++k) {
    if (!cut[k]) storeys.edges.push_back(graph.edges[k]);
  }
  const std::vector<std::int32_t> region = connectedRegions(storeys, off_support);
  std::vector<std::size_t> region_size(n, 0);
  for (std::size_t v = 0; v < n; ++v) {
    if (off_support[v] && !contact[v]) ++region_size[static_cast<std::size_t>(region[v])];
  }
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, segments.size()),
      [&](const tbb::blocked_range<std::size_t>& range) {
        std::vector<std::int32_t> held;
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          held.clear();
          for (std::int32_t v : segments[i].vertices) {
            if (off_support[static_cast<std::size_t>(v)] && !contact[static_cast<std::size_t>(v)]) {
              held.push_back(region[static_cast<std::size_t>(v)]);
            }
          }
          if (held.empty()) continue;
          std::sort(held.begin(), held.end());
          std::size_t most = 0;
          std::int32_t main = held.front();
          for (std::size_t a = 0; a < held.size();) {
            std::size_t b = a;
            while (b < held.size() && held[b] == held[a]) ++b;
            if (b - a > most) most = b - a, main = held[a];
            a = b;
          }
          const double in = static_cast<double>(most);
          (*context)[i].share_of_region =
              in / static_cast<double>(region_size[static_cast<std::size_t>(main)]) *
              (in / static_cast<double>(held.size()));
        }
      });
}

/// How high over a candidate's top surface floating over it counts (SegmentContext::covered_share):
/// a plant's leaves hang over its pot up to a few tens of centimetres.
constexpr float kCoverHeightM = 0.3f;
/// The ball searched holds that cylinder with this to spare (a support's own surface bends).
constexpr float kCoverMarginM = 0.01f;

/// SegmentContext::covered_share of each candidate that stands on a support (ContextConfig::
/// judge_cover): the vertices of the regions off the supports that touch none, but for its own
/// (`region`: the connected regions of the vertices off them), lying over its top by at most
/// kCoverHeightM and no further from its middle along the plane it stands on than its own farthest
/// vertex.
void measureCover(const TriangleMesh& mesh, const MeshGraph& graph, const Supports& supports,
                  const std::vector<std::int32_t>& region, const std::vector<Segment>& segments,
                  const std::vector<UpPlane>& planes, const std::vector<Lowest>& lowest,
                  std::vector<SegmentContext>& out) {
  const std::size_t n = mesh.positions.size();
  std::vector<std::uint8_t> touches(n, 0);  // per region
  for (const MeshEdge& e : graph.edges) {
    const std::size_t a = static_cast<std::size_t>(e.a), b = static_cast<std::size_t>(e.b);
    if (supports.on_support[a] != supports.on_support[b]) {
      touches[static_cast<std::size_t>(region[supports.on_support[a] ? b : a])] = 1;
    }
  }
  std::vector<Eigen::Vector3f> floating;
  std::vector<std::int32_t> floating_region;
  for (std::size_t v = 0; v < n; ++v) {
    if (!supports.on_support[v] && !touches[static_cast<std::size_t>(region[v])]) {
      floating.push_back(mesh.positions[v]);
      floating_region.push_back(region[v]);
    }
  }
  if (floating.empty()) {
    for (SegmentContext& c : out) {
      if (c.footing == Footing::kSupport) c.covered_share = 0.0;
    }
    return;
  }
  const PointIndex index(floating);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, segments.size()),
      [&](const tbb::blocked_range<std::size_t>& range) {
        std::vector<std::pair<std::uint32_t, float>> found;
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          SegmentContext& c = out[i];
          if (c.footing != Footing::kSupport || lowest[i].plane < 0) continue;
          const UpPlane& plane = planes[static_cast<std::size_t>(lowest[i].plane)];
          const std::vector<std::int32_t>& vertices = segments[i].vertices;
          const Eigen::Vector3f& middle = segments[i].centroid;
          const float reach = farthestAlong(mesh, vertices, plane.up, middle);
          const float top = static_cast<float>(c.rise_m);
          // Its own regions off the supports: a part of it floats over none of it.
          std::vector<std::int32_t> own;
          for (std::int32_t v : vertices) {
            const std::size_t u = static_cast<std::size_t>(v);
            if (!supports.on_support[u] &&
                std::find(own.begin(), own.end(), region[u]) == own.end()) {
              own.push_back(region[u]);
            }
          }
          // The cylinder over its top, in the ball round the cylinder's middle. A bent support's
          // height is not the plane's: the ball grows by how much the bend changes under it.
          const auto bend = [&](const Eigen::Vector3f& p) {
            return plane.height(p) - plane.up.dot(p);
          };
          float bend_change = 0.0f;
          for (std::int32_t v : vertices) {
            bend_change = std::max(
                bend_change,
                std::abs(bend(mesh.positions[static_cast<std::size_t>(v)]) - bend(middle)));
          }
          const float half = 0.5f * kCoverHeightM;
          const Eigen::Vector3f centre = middle + (top + half - plane.height(middle)) * plane.up;
          index.within(centre, std::hypot(reach, half + bend_change) + kCoverMarginM, &found);
          std::size_t over = 0;
          for (const auto& [point, distance_sq] : found) {
            if (std::find(own.begin(), own.end(), floating_region[point]) != own.end()) continue;
            const Eigen::Vector3f& p = floating[point];
            const float h = plane.height(p);
            over +=
                h > top && h <= top + kCoverHeightM && alongPlane(plane.up, p - middle) <= reach;
          }
          c.covered_share = static_cast<double>(over) / static_cast<double>(vertices.size());
        }
      });
}

}  // namespace

std::optional<Eigen::Vector3f> groundUp(const Supports& supports, const ContextConfig& config) {
  const std::vector<UpPlane> planes = orientedPlanes(supports);
  const int ground = groundPlane(planes, supports.planes, config);
  if (ground < 0) return std::nullopt;
  return planes[static_cast<std::size_t>(ground)].up;
}

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
  const std::vector<UpPlane> planes = orientedPlanes(supports);
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

  if (config.judge_cover) {
    measureCover(mesh, graph, supports, region, segments, planes, lowest, out);
  }

  // Stacks: a candidate whose foot rests on a surface that faces up (as its support's plane
  // does), level with or under the foot and not its own, stands on that when the surface belongs
  // to a candidate that stands itself: a box on a box, a can on a book. A leaf resting on a leaf
  // rests on something that stands on nothing.
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
  // The surface under each candidate that stands on no support (sorted vertex indices), and its
  // foot where it has such a surface.
  std::vector<std::vector<std::int32_t>> under(segments.size());
  std::vector<float> foot_top(segments.size(), 0.0f), gaps(segments.size(), 0.0f);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, segments.size()),
      [&](const tbb::blocked_range<std::size_t>& range) {
        std::vector<std::pair<std::uint32_t, float>> found;
        for (std::size_t i = range.begin(); i < range.end(); ++i) {
          if (out[i].footing != Footing::kNone || lowest[i].plane < 0) continue;
          const Segment& s = segments[i];
          float lowest_height = std::numeric_limits<float>::infinity();
          for (std::int32_t v : s.vertices) {
            lowest_height =
                std::min(lowest_height, plane.height(mesh.positions[static_cast<std::size_t>(v)]));
          }
          const float gap = footGap(config, out[i]);
          // Its foot: the vertices within the gap of its lowest, at most 64 of them spread evenly.
          const std::vector<std::int32_t> foot =
              footOf(mesh, s.vertices, plane, lowest_height + gap);
          const std::size_t stride = strideFor(foot.size(), 64);
          std::vector<std::int32_t>& u = under[i];
          for (std::size_t f = 0; f < foot.size(); f += stride) {
            const Eigen::Vector3f& p = mesh.positions[static_cast<std::size_t>(foot[f])];
            const float foot_height = plane.height(p);
            all_index.within(p, gap, &found);
            for (const auto& [point, distance_sq] : found) {
              const std::int32_t v = static_cast<std::int32_t>(point);
              if (contains(s.vertices, v)) continue;
              if (plane.up.dot(mesh.normals[point]) < min_cos) continue;
              if (plane.height(mesh.positions[point]) > foot_height + 0.5f * gap) continue;
              u.push_back(v);
            }
          }
          std::sort(u.begin(), u.end());
          u.erase(std::unique(u.begin(), u.end()), u.end());
          if (u.size() < kMinSurfaceUnder) {
            u.clear();
            continue;
          }
          foot_top[i] = lowest_height + gap;
          gaps[i] = gap;
          if (!config.stacks_need_standing_holder) out[i].footing = Footing::kOnSurface;
        }
      });
  const VertexSegments holders(segments, n);
  // Which of the candidates resting on a surface rest on another candidate that stands.
  const auto onStanding = [&] {
    std::vector<std::uint8_t> on(segments.size(), 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, segments.size()),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                        std::vector<std::uint32_t> hits;
                        for (std::size_t i = range.begin(); i < range.end(); ++i) {
                          on[i] =
                              out[i].footing == Footing::kOnSurface && !under[i].empty() &&
                              holders.holds(segments, out, under[i], segments[i].vertices, &hits);
                        }
                      });
    return on;
  };
  // Where stacks need a standing holder (fused meshes; a single view's candidates with a surface
  // under them rest on it already), twice: what stands on a support holds a stack's second
  // storey, which holds its third. Whether a candidate's surface is broad, once it is asked (-1
  // before): the same each storey.
  std::vector<std::int8_t> broad(segments.size(), -1);
  for (int storey = 0; config.stacks_need_standing_holder && storey < 2; ++storey) {
    std::vector<std::uint8_t> held(segments.size(), 0);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, segments.size()),
        [&](const tbb::blocked_range<std::size_t>& range) {
          std::vector<std::uint32_t> hits;
          for (std::size_t i = range.begin(); i < range.end(); ++i) {
            if (out[i].footing != Footing::kNone || under[i].empty()) continue;
            if (holders.holds(segments, out, under[i], segments[i].vertices, &hits)) {
              held[i] = 1;
              continue;
            }
            if (broad[i] < 0) {
              broad[i] = broadLevelSurface(mesh, all_index, plane, segments[i], under[i],
                                           footGap(config, out[i]), out[i].mean_edge_m, min_cos);
            }
            held[i] = static_cast<std::uint8_t>(broad[i]);
          }
        });
    bool changed = false;
    for (std::size_t i = 0; i < segments.size(); ++i) {
      if (!held[i]) continue;
      out[i].footing = Footing::kOnSurface;
      changed = true;
    }
    if (!changed) break;
  }
  if (config.split_regions_at_stacks) {
    shareOfStoreys(mesh, graph, off_support, plane, min_cos, segments, foot_top, gaps, onStanding(),
                   &out);
  }
  return out;
}

}  // namespace objscan::discovery
