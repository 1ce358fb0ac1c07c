#include "objscan/discovery/supports.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include <Eigen/Eigenvalues>

// PCL's templates are compiled here, with this build's flags, rather than taken precompiled
// from libpcl_sample_consensus: Eigen allocates differently under AddressSanitizer (it no longer
// trusts malloc's alignment), so an Eigen vector that the precompiled library allocates cannot
// be freed by this code in the sanitizer build.
#define PCL_NO_PRECOMPILE
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/sac_model_plane.h>

#include "connected_regions.h"
#include "plane_tests.h"

namespace objscan::discovery {

namespace {

/// Planes are fitted to at most this many vertices: a plane holding a few percent of a scene
/// still has hundreds of them, and each hypothesis stays cheap.
constexpr std::size_t kMaxFitPoints = 5000;

/// A plane n . p + offset = 0 and how many of the fitted vertices agree with it.
struct PlaneHypothesis {
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();
  float offset = 0.0f;
  std::size_t support = 0;
};

/// RANSAC with one vertex per hypothesis: a vertex and its normal propose a plane, which scores
/// the vertices of `sample` within `distance` of it whose `normals` lie within the angle whose
/// cosine is `min_cos`. Written here because PCL's plane models (the former fit) draw three
/// points, which must all fall on one plane: for a shelf board holding a few percent of what is
/// left, that takes tens of thousands of draws (with 200, PCL's RANSAC missed two boards of a
/// shelf's three in synthetic scene 2002; with 2000, the support stage took 10 times longer), while
/// one vertex with its normal takes tens. Deterministic: the draws are seeded with `seed`.
PlaneHypothesis bestPlane(const TriangleMesh& mesh, const std::vector<Eigen::Vector3f>& normals,
                          const pcl::Indices& sample, float distance, float min_cos, int hypotheses,
                          unsigned seed) {
  std::minstd_rand draw(seed);
  PlaneHypothesis best;
  for (int h = 0; h < hypotheses; ++h) {
    const auto v = static_cast<std::size_t>(sample[draw() % sample.size()]);
    const float length = normals[v].norm();
    if (!(length > 0.0f)) continue;
    const Eigen::Vector3f normal = normals[v] / length;
    const float offset = -normal.dot(mesh.positions[v]);
    std::size_t support = 0;
    for (const pcl::index_t i : sample) {
      const auto u = static_cast<std::size_t>(i);
      support += onPlane(normal, offset, mesh.positions[u], normals[u], distance, min_cos);
    }
    if (support > best.support) best = {normal, offset, support};
  }
  return best;
}

/// A support's surface is fitted only when its vertices spread at least this far (standard
/// deviation) across its narrowest direction; a table 30 cm deep spreads 8.7 cm.
constexpr double kMinSurfaceSpreadM = 0.05;

/// Fits `plane`'s surface (SupportPlane::surface) to the vertices `member` marks: least squares,
/// heights over the plane as a quadratic in the plane's coordinates.
void fitSurface(const TriangleMesh& mesh, const std::vector<std::uint8_t>& member,
                SupportPlane& plane) {
  const Eigen::Vector3f& n = plane.normal;
  Eigen::Index least = 0;
  n.cwiseAbs().minCoeff(&least);
  plane.axis_u = n.cross(Eigen::Vector3f::Unit(least)).normalized();
  plane.axis_v = n.cross(plane.axis_u);
  double su = 0.0, sv = 0.0;
  std::size_t count = 0;
  float min_u = std::numeric_limits<float>::infinity(), min_v = min_u;
  float max_u = -min_u, max_v = -min_u;
  for (std::size_t v = 0; v < member.size(); ++v) {
    if (!member[v]) continue;
    const float u = plane.axis_u.dot(mesh.positions[v]);
    const float w = plane.axis_v.dot(mesh.positions[v]);
    su += u;
    sv += w;
    min_u = std::min(min_u, u);
    max_u = std::max(max_u, u);
    min_v = std::min(min_v, w);
    max_v = std::max(max_v, w);
    ++count;
  }
  if (count < 6) return;
  plane.centre_u = static_cast<float>(su / static_cast<double>(count));
  plane.centre_v = static_cast<float>(sv / static_cast<double>(count));
  plane.reach_u = {min_u - plane.centre_u, max_u - plane.centre_u};
  plane.reach_v = {min_v - plane.centre_v, max_v - plane.centre_v};
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
  for (std::size_t v = 0; v < member.size(); ++v) {
    if (!member[v]) continue;
    const Eigen::Vector3f& p = mesh.positions[v];
    const double u = plane.axis_u.dot(p) - plane.centre_u;
    const double w = plane.axis_v.dot(p) - plane.centre_v;
    Eigen::Matrix<double, 6, 1> row;
    row << 1.0, u, w, u * u, u * w, w * w;
    ata.noalias() += row * row.transpose();
    atb.noalias() += row * static_cast<double>(plane.planeHeight(p));
  }
  // A support narrow in some direction (a long board seen edge-on, a strip of table between
  // things) fixes no bend across it: its square terms would be noise, and they grow fast beside
  // it. It stays flat. The spread of u and v about the centre is in the normal equations already.
  const Eigen::Matrix2d spread = ata.block<2, 2>(1, 1) / static_cast<double>(count);
  const double narrowest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread).eigenvalues()(0);
  if (!(narrowest >= kMinSurfaceSpreadM * kMinSurfaceSpreadM)) return;
  const Eigen::Matrix<double, 6, 1> c = ata.ldlt().solve(atb);
  if (!c.allFinite()) return;
  plane.surface = c.cast<float>();
  plane.curved = true;
}

}  // namespace

float SupportPlane::height(const Eigen::Vector3f& p) const {
  const float over_plane = planeHeight(p);
  if (!curved) return over_plane;
  // Beyond the box of the vertices it was fitted to, the surface goes on along its tangent at the
  // box's edge: it follows the bend's slope there, but does not climb as the square would.
  const float u = axis_u.dot(p) - centre_u;
  const float w = axis_v.dot(p) - centre_v;
  const float uc = std::clamp(u, reach_u.x(), reach_u.y());
  const float wc = std::clamp(w, reach_v.x(), reach_v.y());
  const float bend = surface[0] + surface[1] * uc + surface[2] * wc + surface[3] * uc * uc +
                     surface[4] * uc * wc + surface[5] * wc * wc +
                     (surface[1] + 2.0f * surface[3] * uc + surface[4] * wc) * (u - uc) +
                     (surface[2] + surface[4] * uc + 2.0f * surface[5] * wc) * (w - wc);
  return over_plane - bend;
}

void SupportConfig::validate() const {
  if (!(distance_m > 0.0f) || !std::isfinite(distance_m)) {
    throw std::invalid_argument("the support distance must be a positive number of metres");
  }
  if (!(max_angle_deg > 0.0f && max_angle_deg < 90.0f)) {
    throw std::invalid_argument("the support normal angle must lie between 0 and 90 degrees");
  }
  if (min_vertices < 3) throw std::invalid_argument("a support needs at least 3 vertices");
  if (min_cut_off_size < 1) throw std::invalid_argument("min_cut_off_size must be at least 1");
  if (!(foot_fold_m >= 0.0f) || !std::isfinite(foot_fold_m) ||
      !(foot_fold_deg >= 0.0f && foot_fold_deg <= 90.0f)) {
    throw std::invalid_argument("the foot's fold must be a distance >= 0 and an angle in [0, 90]");
  }
  if (!(top_level_deg >= 0.0f && top_level_deg <= 90.0f) || !(top_flatness_m >= 0.0f) ||
      !std::isfinite(top_flatness_m) || top_min_vertices < 1) {
    throw std::invalid_argument(
        "level tops need an angle in [0, 90], a flatness >= 0 and at least 1 vertex");
  }
  if (max_planes < 0 || ransac_iterations < 1) {
    throw std::invalid_argument("supports need max_planes >= 0 and at least 1 RANSAC iteration");
  }
  if (normal_rings < 0 || normal_rings > 100 || single_view_normal_rings < 0 ||
      single_view_normal_rings > 100) {
    throw std::invalid_argument("supports' normal rings must lie in 0..100");
  }
}

Supports findSupports(const TriangleMesh& mesh, const MeshGraph& graph, const SupportConfig& config,
                      std::size_t min_vertices) {
  config.validate();
  if (!mesh.hasNormals()) {
    throw std::invalid_argument("the mesh has no vertex normals, which supports need");
  }
  if (graph.vertex_count != mesh.positions.size()) {
    throw std::invalid_argument("findSupports needs the graph of this mesh");
  }
  const std::size_t n = mesh.positions.size();
  Supports out;
  out.on_support.assign(n, 0);
  min_vertices = std::max<std::size_t>(min_vertices, 3);
  if (n < min_vertices) return out;

  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->reserve(n);
  for (const Eigen::Vector3f& p : mesh.positions) cloud->push_back({p.x(), p.y(), p.z()});
  const float min_cos = cosOfDegrees(config.max_angle_deg);
  // Vertices on a plane found already (within the distance, whatever their normals): later
  // planes are fitted to the rest, so that no plane is found twice.
  std::vector<std::uint8_t> taken(n, 0);
  std::vector<std::uint8_t> on_plane(n, 0);
  std::vector<std::uint8_t> near_this(n, 0);  // taken by this plane
  // The normals the planes are judged by: the mesh's, or averaged over config.normal_rings rings
  // of neighbours (a single view's own per-pixel normals scatter by tens of degrees).
  std::vector<Eigen::Vector3f> averaged;
  if (config.normal_rings > 0) averaged = mesh.normals;
  for (int r = 0; r < config.normal_rings; ++r) {
    std::vector<Eigen::Vector3f> sum = averaged;
    for (const MeshEdge& e : graph.edges) {
      sum[static_cast<std::size_t>(e.a)] += averaged[static_cast<std::size_t>(e.b)];
      sum[static_cast<std::size_t>(e.b)] += averaged[static_cast<std::size_t>(e.a)];
    }
    for (std::size_t v = 0; v < n; ++v) {
      const float length = sum[v].norm();
      averaged[v] = length > 0.0f ? Eigen::Vector3f(sum[v] / length) : Eigen::Vector3f::Zero();
    }
  }
  const std::vector<Eigen::Vector3f>& normals = config.normal_rings > 0 ? averaged : mesh.normals;
  for (int k = 0; k < config.max_planes; ++k) {
    std::size_t remaining = 0;
    for (std::size_t v = 0; v < n; ++v) remaining += taken[v] ? 0 : 1;
    if (remaining < min_vertices) break;
    const std::size_t stride = (remaining + kMaxFitPoints - 1) / kMaxFitPoints;
    pcl::Indices sample;
    sample.reserve(remaining / stride + 1);
    for (std::size_t v = 0, seen = 0; v < n; ++v) {
      if (!taken[v] && seen++ % stride == 0) sample.push_back(static_cast<pcl::index_t>(v));
    }
    const PlaneHypothesis best = bestPlane(mesh, normals, sample, config.distance_m, min_cos,
                                           config.ransac_iterations, 1u + static_cast<unsigned>(k));
    if (best.support < 3) break;
    // Refitted by least squares (PCL's) to the sampled vertices near the best hypothesis.
    pcl::Indices inliers;
    for (const pcl::index_t i : sample) {
      const auto u = static_cast<std::size_t>(i);
      if (std::abs(best.normal.dot(mesh.positions[u]) + best.offset) <= config.distance_m) {
        inliers.push_back(i);
      }
    }
    auto model = std::make_shared<pcl::SampleConsensusModelPlane<pcl::PointXYZ>>(cloud, sample);
    Eigen::VectorXf coefficients(4), refined;
    coefficients << best.normal, best.offset;
    model->optimizeModelCoefficients(inliers, coefficients, refined);
    Eigen::Vector3f normal = refined.head<3>();
    const float length = normal.norm();
    if (!(length > 0.0f) || !std::isfinite(length)) break;
    normal /= length;
    const float offset = refined[3] / length;

    std::size_t near = 0;
    std::fill(on_plane.begin(), on_plane.end(), 0);
    std::fill(near_this.begin(), near_this.end(), 0);
    for (std::size_t v = 0; v < n; ++v) {
      if (taken[v] || std::abs(normal.dot(mesh.positions[v]) + offset) > config.distance_m) {
        continue;
      }
      taken[v] = 1;
      near_this[v] = 1;
      ++near;
      if (std::abs(normal.dot(normals[v])) >= min_cos) on_plane[v] = 1;
    }
    // The largest plane left is smaller than a support: so is every later one.
    if (near < min_vertices) break;
    SupportPlane plane;
    plane.normal = normal;
    plane.offset = offset;
    // The support regions: the connected regions of plane vertices large enough. Measured once
    // against the plane; then, with the regions' own surface measured (SupportPlane::surface),
    // again against that surface, within the same band: a bent table's vertices are all its own,
    // and what stands on it is cut at the same height over it everywhere.
    std::vector<std::uint8_t> member(n, 0);
    const auto measureRegions = [&] {
      const std::vector<std::int32_t> region = connectedRegions(graph, on_plane);
      std::vector<std::size_t> size(n, 0);
      for (std::size_t v = 0; v < n; ++v) size[static_cast<std::size_t>(region[v])] += on_plane[v];
      plane.vertex_count = 0;
      for (std::size_t v = 0; v < n; ++v) {
        member[v] = on_plane[v] && size[static_cast<std::size_t>(region[v])] >= min_vertices;
        plane.vertex_count += member[v];
      }
    };
    measureRegions();
    if (plane.vertex_count == 0) continue;
    fitSurface(mesh, member, plane);
    if (plane.curved) {
      for (std::size_t v = 0; v < n; ++v) {
        if (taken[v] && !near_this[v]) continue;  // an earlier plane's
        const bool near_surface = std::abs(plane.height(mesh.positions[v])) <= config.distance_m;
        if (!near_surface) {
          on_plane[v] = 0;
          continue;
        }
        taken[v] = 1;
        on_plane[v] = std::abs(normal.dot(normals[v])) >= min_cos;
      }
      measureRegions();
    }
    for (std::size_t v = 0; v < n; ++v) out.on_support[v] |= member[v];
    if (plane.vertex_count > 0) out.planes.push_back(std::move(plane));
  }
  // Where two supports meet (a shelf board and the wall behind it), fusion rounds the fold, and
  // its vertices, tilted away from both planes, belong to neither. Left so, the fold would be a
  // long strip joining everything that stands along it; it is a support too.
  if (out.planes.size() >= 2) {
    for (std::size_t v = 0; v < n; ++v) {
      if (out.on_support[v]) continue;
      int near_planes = 0;
      for (const SupportPlane& p : out.planes) {
        near_planes += std::min(std::abs(p.planeHeight(mesh.positions[v])),
                                std::abs(p.height(mesh.positions[v]))) <= config.distance_m;
      }
      if (near_planes >= 2) {
        out.on_support[v] = 1;
        ++out.fold_vertices;
      }
    }
  }
  for (SupportPlane& p : out.planes) {
    double facing = 0.0;
    for (std::size_t v = 0; v < n; ++v) {
      if (!out.on_support[v]) continue;
      if (std::abs(p.height(mesh.positions[v])) > kOwnSurfaceM) continue;
      facing += p.normal.dot(mesh.normals[v]);
    }
    p.up_sign = facing >= 0.0 ? 1.0f : -1.0f;
  }
  return out;
}

std::size_t cutAtSupports(MeshGraph& graph, const std::vector<std::uint8_t>& on_support) {
  if (on_support.size() != graph.vertex_count) {
    throw std::invalid_argument("cutAtSupports needs one entry per vertex of the graph");
  }
  std::size_t cut = 0;
  for (MeshEdge& e : graph.edges) {
    if (on_support[static_cast<std::size_t>(e.a)] != on_support[static_cast<std::size_t>(e.b)]) {
      e.weight = std::numeric_limits<float>::infinity();
      ++cut;
    }
  }
  return cut;
}

}  // namespace objscan::discovery
