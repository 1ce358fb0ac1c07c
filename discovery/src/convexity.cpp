#include "objscan/discovery/convexity.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include <tbb/parallel_for.h>
#include <Eigen/Eigenvalues>

#include "disjoint_sets.h"

namespace objscan::discovery {

void ConvexityConfig::validate() const {
  if (!enabled) return;
  if (patch_sizes_m.empty() || tolerances_deg.empty()) {
    throw std::invalid_argument("convexity segmentation needs a patch size and a tolerance");
  }
  for (float s : patch_sizes_m) {
    if (!(s > 0.0f) || !std::isfinite(s)) {
      throw std::invalid_argument("convexity patch sizes must be positive");
    }
  }
  for (float t : tolerances_deg) {
    if (!(t >= 0.0f && t < 90.0f)) {
      throw std::invalid_argument("convexity tolerances must lie in [0, 90) degrees");
    }
  }
  if (!(crease_deg >= 0.0f && crease_deg < 90.0f)) {
    throw std::invalid_argument("the convexity crease angle must lie in [0, 90) degrees");
  }
  if (min_patch_vertices < 3) {
    throw std::invalid_argument("a convexity patch needs at least 3 vertices to fit a normal");
  }
  for (float c : colour_limits) {
    if (!(c > 0.0f) || !std::isfinite(c)) {
      throw std::invalid_argument("convexity colour limits must be positive");
    }
  }
  if (!(colour_lightness_weight >= 0.0f) || !std::isfinite(colour_lightness_weight)) {
    throw std::invalid_argument("the convexity colour lightness weight must be >= 0");
  }
}

namespace {

/// Patches of one size: each vertex's patch, and each patch's centroid, fitted normal and size.
struct Patches {
  std::vector<std::int32_t> of_vertex;  ///< -1 for an excluded vertex
  std::vector<Eigen::Vector3f> centroid, normal;
  /// Mean colour in L*a*b* (L* scaled by the lightness weight); empty for a mesh without colours.
  std::vector<Eigen::Vector3f> colour;
  std::vector<float> colour_spread;
  std::vector<std::int32_t> size;
  /// Neighbouring patches (a < b) and how many mesh edges off creases join them (a patch too
  /// small to fit a normal goes with the neighbour of most such edges, never across a crease).
  std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
  std::vector<std::int32_t> pair_edges;
};

std::int64_t cellKey(const Eigen::Vector3f& p, float size) {
  const auto c = [&](float x) {
    // Clamped before the cast (a far-away vertex must not overflow it): 21 bits each.
    const float cell = std::clamp(std::floor(x / size), -1.0e6f, 1.0e6f);
    return static_cast<std::int64_t>(cell) & 0x1fffff;
  };
  return (c(p.x()) << 42) | (c(p.y()) << 21) | c(p.z());
}

/// Each vertex's colour in CIE L*a*b* (sRGB, D65 white; CIE 1976), L* times lightness_weight.
/// Written out rather than through OpenCV's cvtColor, whose own thread pool would escape the
/// single idle-priority thread that the live page's online discovery runs on; the formula is the
/// standard one, with OpenCV's constants, and 8-bit channels need only a 256-entry table.
std::vector<Eigen::Vector3f> vertexColours(const TriangleMesh& mesh, float lightness_weight) {
  std::array<float, 256> linear{};
  for (int i = 0; i < 256; ++i) {
    const float c = static_cast<float>(i) / 255.0f;
    linear[static_cast<std::size_t>(i)] =
        c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
  }
  const auto f = [](float t) { return t > 0.008856f ? std::cbrt(t) : 7.787f * t + 16.0f / 116.0f; };
  std::vector<Eigen::Vector3f> out(mesh.colors.size());
  for (std::size_t v = 0; v < out.size(); ++v) {
    const Rgb8& c = mesh.colors[v];
    const float r = linear[c.x()], g = linear[c.y()], b = linear[c.z()];
    const float x = (0.412453f * r + 0.357580f * g + 0.180423f * b) / 0.950456f;
    const float y = 0.212671f * r + 0.715160f * g + 0.072169f * b;
    const float z = (0.019334f * r + 0.119193f * g + 0.950227f * b) / 1.088754f;
    const float l = y > 0.008856f ? 116.0f * std::cbrt(y) - 16.0f : 903.3f * y;
    out[v] = Eigen::Vector3f(l * lightness_weight, 500.0f * (f(x) - f(y)), 200.0f * (f(y) - f(z)));
  }
  return out;
}

/// Each patch's mean colour and colour spread (the RMS distance of its vertices' colours from the
/// mean), from the vertices' colours (vertexColours).
void patchColours(const std::vector<Eigen::Vector3f>& colours, Patches& p) {
  const std::size_t m = p.size.size();
  std::vector<Eigen::Vector3d> sum(m, Eigen::Vector3d::Zero());
  std::vector<double> square(m, 0.0);
  for (std::size_t v = 0; v < p.of_vertex.size(); ++v) {
    if (p.of_vertex[v] < 0) continue;
    const auto k = static_cast<std::size_t>(p.of_vertex[v]);
    const Eigen::Vector3d c = colours[v].cast<double>();
    sum[k] += c;
    square[k] += c.squaredNorm();
  }
  p.colour.resize(m);
  p.colour_spread.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    const double count = std::max(p.size[k], 1);
    const Eigen::Vector3d mean = sum[k] / count;
    p.colour[k] = mean.cast<float>();
    p.colour_spread[k] =
        static_cast<float>(std::sqrt(std::max(0.0, square[k] / count - mean.squaredNorm())));
  }
}

Patches makePatches(const TriangleMesh& mesh, const MeshGraph& graph,
                    const std::vector<std::uint8_t>& excluded, float size, int min_vertices,
                    float crease_deg, const std::vector<Eigen::Vector3f>& colours) {
  const std::size_t n = mesh.positions.size();
  const auto out = [&](std::size_t v) { return !excluded.empty() && excluded[v] != 0; };
  std::vector<std::int64_t> cell(n);
  for (std::size_t v = 0; v < n; ++v) cell[v] = cellKey(mesh.positions[v], size);
  // The connected pieces of each cell, not joined across a sharp concave crease. Normals are
  // compared by direction (a mesh file's own need not be unit length); a zero one makes no crease.
  const float crease_cos = std::cos(crease_deg * static_cast<float>(M_PI) / 180.0f);
  const auto crease = [&](std::size_t a, std::size_t b) {
    if (!(crease_deg > 0.0f)) return false;
    const Eigen::Vector3f& na = mesh.normals[a];
    const Eigen::Vector3f& nb = mesh.normals[b];
    const float lengths = na.norm() * nb.norm();
    return lengths > 0.0f && na.dot(nb) < crease_cos * lengths &&
           (na / na.norm() - nb / nb.norm()).dot(mesh.positions[a] - mesh.positions[b]) < 0.0f;
  };
  DisjointSets sets(n);
  for (const MeshEdge& e : graph.edges) {
    const auto a = static_cast<std::size_t>(e.a), b = static_cast<std::size_t>(e.b);
    if (out(a) || out(b) || cell[a] != cell[b] || crease(a, b)) continue;
    const std::int32_t ra = sets.find(e.a), rb = sets.find(e.b);
    if (ra != rb) sets.attach(std::max(ra, rb), std::min(ra, rb));
  }
  Patches p;
  p.of_vertex.assign(n, -1);
  std::vector<std::int32_t> patch_of_root(n, -1);
  for (std::size_t v = 0; v < n; ++v) {
    if (out(v)) continue;
    const auto root = static_cast<std::size_t>(sets.find(static_cast<std::int32_t>(v)));
    if (patch_of_root[root] < 0) {
      patch_of_root[root] = static_cast<std::int32_t>(p.size.size());
      p.size.push_back(0);
    }
    p.of_vertex[v] = patch_of_root[root];
    ++p.size[static_cast<std::size_t>(p.of_vertex[v])];
  }
  const std::size_t m = p.size.size();
  // Centroids, then the scatter about them; the normal is the scatter's least direction, turned
  // to the side the vertex normals face.
  std::vector<Eigen::Vector3d> sum(m, Eigen::Vector3d::Zero()),
      normal_sum(m, Eigen::Vector3d::Zero());
  for (std::size_t v = 0; v < n; ++v) {
    if (p.of_vertex[v] < 0) continue;
    const auto k = static_cast<std::size_t>(p.of_vertex[v]);
    sum[k] += mesh.positions[v].cast<double>();
    normal_sum[k] += mesh.normals[v].cast<double>();
  }
  p.centroid.resize(m);
  for (std::size_t k = 0; k < m; ++k) p.centroid[k] = (sum[k] / p.size[k]).cast<float>();
  std::vector<Eigen::Matrix3d> scatter(m, Eigen::Matrix3d::Zero());
  for (std::size_t v = 0; v < n; ++v) {
    if (p.of_vertex[v] < 0) continue;
    const auto k = static_cast<std::size_t>(p.of_vertex[v]);
    const Eigen::Vector3d d = (mesh.positions[v] - p.centroid[k]).cast<double>();
    scatter[k] += d * d.transpose();
  }
  p.normal.assign(m, Eigen::Vector3f::Zero());
  tbb::parallel_for(std::size_t{0}, m, [&](std::size_t k) {
    Eigen::Vector3d normal = normal_sum[k];
    if (p.size[k] >= min_vertices) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter[k]);
      normal = solver.eigenvectors().col(0);
      if (normal.dot(normal_sum[k]) < 0.0) normal = -normal;
    }
    if (normal.norm() > 0.0) p.normal[k] = normal.normalized().cast<float>();
  });
  if (!colours.empty()) patchColours(colours, p);
  // Neighbouring patches, with their shared edge counts (edges on creases not counted).
  std::unordered_map<std::uint64_t, std::int32_t> index;
  for (const MeshEdge& e : graph.edges) {
    const std::int32_t a = p.of_vertex[static_cast<std::size_t>(e.a)];
    const std::int32_t b = p.of_vertex[static_cast<std::size_t>(e.b)];
    if (a < 0 || b < 0 || a == b) continue;
    const auto lo = std::min(a, b), hi = std::max(a, b);
    const std::uint64_t key =
        (static_cast<std::uint64_t>(lo) << 32) | static_cast<std::uint32_t>(hi);
    const auto [it, added] = index.emplace(key, static_cast<std::int32_t>(p.pairs.size()));
    if (added) {
      p.pairs.emplace_back(lo, hi);
      p.pair_edges.push_back(0);
    }
    if (!crease(static_cast<std::size_t>(e.a), static_cast<std::size_t>(e.b))) {
      ++p.pair_edges[static_cast<std::size_t>(it->second)];
    }
  }
  return p;
}

/// Whether patches a and b meet convexly, or flat within the tolerance (cos_tolerance: the
/// cosine of the tolerance angle).
bool joined(const Patches& p, std::size_t a, std::size_t b, float cos_tolerance) {
  const Eigen::Vector3f& na = p.normal[a];
  const Eigen::Vector3f& nb = p.normal[b];
  if (na.dot(nb) >= cos_tolerance) return true;
  return (na - nb).dot(p.centroid[a] - p.centroid[b]) > 0.0f;
}

/// Whether two plain patches meet at a colour edge: their colours differ by more than `limit`, and
/// neither's colour spreads by more than it. A print on a box (text, a picture) makes patches
/// that are far from plain at the sensor's resolution, so it is not cut into pieces; a lid of one
/// colour on a jar of another is.
bool colourEdge(const Patches& p, std::size_t a, std::size_t b, float limit) {
  return (p.colour[a] - p.colour[b]).norm() > limit &&
         std::max(p.colour_spread[a], p.colour_spread[b]) <= limit;
}

/// With a colour limit (> 0), patches that meet at a colour edge stay apart.
Segmentation segmentPatches(const Patches& p, float tolerance_deg, int min_vertices,
                            float colour_limit) {
  const std::size_t m = p.size.size();
  DisjointSets sets(m);
  const auto unite = [&](std::size_t a, std::size_t b) {
    const std::int32_t ra = sets.find(static_cast<std::int32_t>(a));
    const std::int32_t rb = sets.find(static_cast<std::int32_t>(b));
    if (ra != rb) sets.attach(std::max(ra, rb), std::min(ra, rb));
  };
  // A patch too small to fit a normal goes with the neighbour it shares the most edges with.
  std::vector<std::int32_t> best(m, -1), best_edges(m, 0);
  for (std::size_t i = 0; i < p.pairs.size(); ++i) {
    const auto [a, b] = p.pairs[i];
    for (const auto& [self, other] : {std::pair{a, b}, std::pair{b, a}}) {
      const auto s = static_cast<std::size_t>(self);
      if (p.size[s] < min_vertices && p.pair_edges[i] > best_edges[s]) {
        best_edges[s] = p.pair_edges[i];
        best[s] = other;
      }
    }
  }
  for (std::size_t k = 0; k < m; ++k) {
    if (best[k] >= 0) unite(k, static_cast<std::size_t>(best[k]));
  }
  const float cos_tolerance = std::cos(tolerance_deg * static_cast<float>(M_PI) / 180.0f);
  for (const auto& [a, b] : p.pairs) {
    const auto sa = static_cast<std::size_t>(a), sb = static_cast<std::size_t>(b);
    if (p.size[sa] < min_vertices || p.size[sb] < min_vertices) continue;
    if (colour_limit > 0.0f && colourEdge(p, sa, sb, colour_limit)) continue;
    if (joined(p, sa, sb, cos_tolerance)) unite(sa, sb);
  }
  Segmentation s;
  s.scale = 0.0f;
  s.labels.assign(p.of_vertex.size(), -1);
  std::vector<std::int32_t> label_of_root(m, -1);
  for (std::size_t v = 0; v < p.of_vertex.size(); ++v) {
    if (p.of_vertex[v] < 0) {
      s.labels[v] = static_cast<std::int32_t>(s.segment_count++);  // excluded: alone
      continue;
    }
    const auto root = static_cast<std::size_t>(sets.find(p.of_vertex[v]));
    if (label_of_root[root] < 0) label_of_root[root] = static_cast<std::int32_t>(s.segment_count++);
    s.labels[v] = label_of_root[root];
  }
  return s;
}

}  // namespace

std::vector<Segmentation> convexSegmentations(const TriangleMesh& mesh, const MeshGraph& graph,
                                              const std::vector<std::uint8_t>& excluded,
                                              const ConvexityConfig& config) {
  config.validate();
  if (!config.enabled) return {};
  if (!excluded.empty() && excluded.size() != mesh.positions.size()) {
    throw std::invalid_argument("convexSegmentations: one exclusion flag per vertex is needed");
  }
  if (!mesh.hasNormals()) throw std::invalid_argument("convexity segmentation needs normals");
  if (mesh.hasColors() && mesh.colors.size() != mesh.positions.size()) {
    throw std::invalid_argument("convexSegmentations: one colour per vertex is needed");
  }
  // Per patch size and tolerance: geometry alone (limit 0), then each colour limit.
  std::vector<float> limits = {0.0f};
  if (mesh.hasColors()) {
    limits.insert(limits.end(), config.colour_limits.begin(), config.colour_limits.end());
  }
  const std::vector<Eigen::Vector3f> colours =
      limits.size() > 1 ? vertexColours(mesh, config.colour_lightness_weight)
                        : std::vector<Eigen::Vector3f>{};
  const std::size_t per_size = config.tolerances_deg.size() * limits.size();
  std::vector<Segmentation> out(config.patch_sizes_m.size() * per_size);
  tbb::parallel_for(std::size_t{0}, config.patch_sizes_m.size(), [&](std::size_t i) {
    const Patches patches = makePatches(mesh, graph, excluded, config.patch_sizes_m[i],
                                        config.min_patch_vertices, config.crease_deg, colours);
    for (std::size_t j = 0; j < config.tolerances_deg.size(); ++j) {
      for (std::size_t c = 0; c < limits.size(); ++c) {
        out[i * per_size + j * limits.size() + c] =
            segmentPatches(patches, config.tolerances_deg[j], config.min_patch_vertices, limits[c]);
      }
    }
  });
  return out;
}

}  // namespace objscan::discovery
