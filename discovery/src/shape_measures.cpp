#include "objscan/discovery/shape_measures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>

#include <tbb/parallel_for.h>
#include <Eigen/Geometry>

#include "point_index.h"

extern "C" {
#include <libqhull_r/qhull_ra.h>
}

namespace objscan::discovery {

namespace {

struct Ball {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  double r2 = 0.0;
  /// With a relative tolerance: the points that define a ball lie on it up to rounding.
  bool contains(const Eigen::Vector3d& p) const {
    return (p - c).squaredNorm() <= r2 * (1.0 + 1e-10) + 1e-18;
  }
};

Ball through(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d c = 0.5 * (a + b);
  return {c, (a - c).squaredNorm()};
}

/// The smallest ball with a, b, c on its surface (their circumcircle's); for (nearly) collinear
/// points, the smallest ball through the two farthest apart, which holds the third.
Ball through(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, n = ab.cross(ac);
  const double n2 = n.squaredNorm();
  if (n2 <= 1e-24 * ab.squaredNorm() * ac.squaredNorm()) {
    Ball best = through(a, b);
    for (const Ball& x : {through(a, c), through(b, c)}) {
      if (x.r2 > best.r2) best = x;
    }
    return best;
  }
  const Eigen::Vector3d centre =
      a + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) / (2.0 * n2);
  return {centre, (a - centre).squaredNorm()};
}

/// The ball with a, b, c, d on its surface; for (nearly) coplanar points, the smallest of the
/// balls through three of them that holds the fourth.
Ball through(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
             const Eigen::Vector3d& d) {
  Eigen::Matrix3d m;
  m.row(0) = (b - a).transpose();
  m.row(1) = (c - a).transpose();
  m.row(2) = (d - a).transpose();
  const double det = m.determinant();
  const double scale = m.row(0).norm() * m.row(1).norm() * m.row(2).norm();
  if (std::abs(det) <= 1e-12 * scale) {
    Ball best;
    best.r2 = std::numeric_limits<double>::infinity();
    const Eigen::Vector3d p[4] = {a, b, c, d};
    for (int skip = 0; skip < 4; ++skip) {
      Eigen::Vector3d q[3];
      for (int i = 0, k = 0; i < 4; ++i) {
        if (i != skip) q[k++] = p[i];
      }
      const Ball x = through(q[0], q[1], q[2]);
      if (x.contains(p[skip]) && x.r2 < best.r2) best = x;
    }
    return best;
  }
  const Eigen::Vector3d rhs(0.5 * m.row(0).squaredNorm(), 0.5 * m.row(1).squaredNorm(),
                            0.5 * m.row(2).squaredNorm());
  const Eigen::Vector3d centre = a + m.partialPivLu().solve(rhs);
  return {centre, (a - centre).squaredNorm()};
}

/// Distances from points to the surface of their convex hull, by Qhull (reentrant C API).
/// Returns false when Qhull finds no full-dimensional hull (flat or too few points).
bool hullDistances(const std::vector<double>& xyz, std::vector<double>* distances) {
  const int n = static_cast<int>(xyz.size() / 3);
  if (n < 4) return false;
  qhT qh_storage;
  qhT* qh = &qh_storage;
  QHULL_LIB_CHECK
  qh_zero(qh, nullptr);
  // Qt: triangulated output. Qhull reports a flat input on its error stream: discarded.
  char options[] = "qhull Qt";
  std::FILE* sink = std::fopen("/dev/null", "w");
  const int error =
      qh_new_qhull(qh, 3, n, const_cast<double*>(xyz.data()), False, options, nullptr, sink);
  bool ok = error == 0;
  if (ok) {
    // Inside a convex polytope, the distance to its surface is the distance to the nearest facet
    // plane (outward normals: n . p + offset <= 0 inside). Planes and points as separate
    // coordinate arrays, points in chunks that stay in cache: the inner loop is an element-wise
    // minimum, which the compiler vectorises.
    std::vector<double> nx, ny, nz, offset;
    facetT* facet;
    FORALLfacets {
      nx.push_back(facet->normal[0]);
      ny.push_back(facet->normal[1]);
      nz.push_back(facet->normal[2]);
      offset.push_back(facet->offset);
    }
    const auto count = static_cast<std::size_t>(n);
    std::vector<double> x(count), y(count), z(count);
    for (std::size_t i = 0; i < count; ++i) {
      x[i] = xyz[3 * i];
      y[i] = xyz[3 * i + 1];
      z[i] = xyz[3 * i + 2];
    }
    distances->assign(count, std::numeric_limits<double>::infinity());
    double* d = distances->data();
    constexpr std::size_t kChunk = 512;
    for (std::size_t begin = 0; begin < count; begin += kChunk) {
      const std::size_t end = std::min(count, begin + kChunk);
      for (std::size_t f = 0; f < nx.size(); ++f) {
        const double a = nx[f], b = ny[f], c = nz[f], o = offset[f];
        for (std::size_t i = begin; i < end; ++i) {
          const double e = -(a * x[i] + b * y[i] + c * z[i] + o);
          d[i] = e < d[i] ? e : d[i];
        }
      }
    }
    for (std::size_t i = 0; i < count; ++i) d[i] = std::max(0.0, d[i]);
  }
  qh_freeqhull(qh, !qh_ALL);
  int curlong = 0, totlong = 0;
  qh_memfreeshort(qh, &curlong, &totlong);
  if (sink) std::fclose(sink);
  return ok;
}

}  // namespace

Sphere smallestEnclosingSphere(std::vector<Eigen::Vector3d> p) {
  if (p.empty()) throw std::invalid_argument("the smallest enclosing sphere of no points");
  // A fixed seed: the same segment always gets the same sphere.
  std::mt19937 random(12345);
  std::shuffle(p.begin(), p.end(), random);
  Ball b{p[0], 0.0};
  for (std::size_t i = 1; i < p.size(); ++i) {
    if (b.contains(p[i])) continue;
    b = {p[i], 0.0};
    for (std::size_t j = 0; j < i; ++j) {
      if (b.contains(p[j])) continue;
      b = through(p[i], p[j]);
      for (std::size_t k = 0; k < j; ++k) {
        if (b.contains(p[k])) continue;
        b = through(p[i], p[j], p[k]);
        for (std::size_t l = 0; l < k; ++l) {
          if (!b.contains(p[l])) b = through(p[i], p[j], p[k], p[l]);
        }
      }
    }
  }
  return {b.c, std::sqrt(b.r2)};
}

VertexEdges vertexEdges(const MeshGraph& graph) {
  VertexEdges out;
  out.offsets.assign(graph.vertex_count + 1, 0);
  for (const MeshEdge& e : graph.edges) {
    ++out.offsets[static_cast<std::size_t>(e.a) + 1];
    ++out.offsets[static_cast<std::size_t>(e.b) + 1];
  }
  std::partial_sum(out.offsets.begin(), out.offsets.end(), out.offsets.begin());
  out.edges.resize(out.offsets.back());
  std::vector<std::size_t> fill(out.offsets.begin(), out.offsets.end() - 1);
  for (std::size_t e = 0; e < graph.edges.size(); ++e) {
    out.edges[fill[static_cast<std::size_t>(graph.edges[e].a)]++] = static_cast<std::int32_t>(e);
    out.edges[fill[static_cast<std::size_t>(graph.edges[e].b)]++] = static_cast<std::int32_t>(e);
  }
  return out;
}

VertexTriangles vertexTriangles(const TriangleMesh& mesh) {
  VertexTriangles out;
  out.offsets.assign(mesh.positions.size() + 1, 0);
  const auto smallest = [](const Eigen::Vector3i& t) {
    return static_cast<std::size_t>(std::min({t[0], t[1], t[2]}));
  };
  for (const Eigen::Vector3i& t : mesh.triangles) ++out.offsets[smallest(t) + 1];
  std::partial_sum(out.offsets.begin(), out.offsets.end(), out.offsets.begin());
  out.triangles.resize(mesh.triangles.size());
  std::vector<std::size_t> fill(out.offsets.begin(), out.offsets.end() - 1);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    out.triangles[fill[smallest(mesh.triangles[t])]++] = static_cast<std::int32_t>(t);
  }
  return out;
}

namespace {

/// A segment's vertices (increasing) as a mask over the index range they span: membership in
/// constant time, for the cost of one byte per index in that range.
class Members {
 public:
  explicit Members(const std::vector<std::int32_t>& vertices)
      : first_(vertices.empty() ? 0 : vertices.front()),
        mask_(vertices.empty() ? 0 : static_cast<std::size_t>(vertices.back() - first_) + 1, 0) {
    for (std::int32_t v : vertices) mask_[static_cast<std::size_t>(v - first_)] = 1;
  }
  bool contains(std::int32_t v) const {
    const auto i = static_cast<std::size_t>(v - first_);  // wraps round below first_
    return i < mask_.size() && mask_[i] != 0;
  }

 private:
  std::int32_t first_;
  std::vector<std::uint8_t> mask_;
};

}  // namespace

double compactness(const TriangleMesh& mesh, const Segment& segment) {
  return compactness(mesh, vertexTriangles(mesh), segment);
}

double compactness(const TriangleMesh& mesh, const VertexTriangles& by_vertex,
                   const Segment& segment) {
  if (by_vertex.offsets.size() != mesh.positions.size() + 1) {
    throw std::invalid_argument("compactness: the triangle index was built for another mesh");
  }
  const Members in(segment.vertices);
  std::vector<Eigen::Vector3d> points;
  points.reserve(segment.vertices.size());
  double area = 0.0;
  for (std::int32_t v : segment.vertices) {
    const auto vi = static_cast<std::size_t>(v);
    points.push_back(mesh.positions[vi].cast<double>());
    // The triangles whose smallest vertex is v: each of the segment's triangles once.
    for (std::size_t k = by_vertex.offsets[vi]; k < by_vertex.offsets[vi + 1]; ++k) {
      const Eigen::Vector3i& t = mesh.triangles[static_cast<std::size_t>(by_vertex.triangles[k])];
      if (!in.contains(t[0]) || !in.contains(t[1]) || !in.contains(t[2])) continue;
      const Eigen::Vector3d a = mesh.positions[static_cast<std::size_t>(t[0])].cast<double>();
      const Eigen::Vector3d b = mesh.positions[static_cast<std::size_t>(t[1])].cast<double>();
      const Eigen::Vector3d c = mesh.positions[static_cast<std::size_t>(t[2])].cast<double>();
      area += 0.5 * (b - a).cross(c - a).norm();
    }
  }
  const Sphere s = smallestEnclosingSphere(std::move(points));
  return s.radius > 0.0 ? area / (4.0 * M_PI * s.radius * s.radius) : 0.0;
}

double localConvexity(const MeshGraph& graph, const VertexEdges& by_vertex,
                      const Segment& segment) {
  const Members in(segment.vertices);
  std::size_t edges = 0, convex = 0;
  for (std::int32_t v : segment.vertices) {
    const auto vi = static_cast<std::size_t>(v);
    for (std::size_t k = by_vertex.offsets[vi]; k < by_vertex.offsets[vi + 1]; ++k) {
      const MeshEdge& e = graph.edges[static_cast<std::size_t>(by_vertex.edges[k])];
      // Each edge once: from its smaller end, when the larger one is in the segment too.
      if (e.a != v || !in.contains(e.b)) continue;
      ++edges;
      convex += e.convex ? 1 : 0;
    }
  }
  return edges > 0 ? static_cast<double>(convex) / static_cast<double>(edges) : 0.0;
}

double hullDistance(const TriangleMesh& mesh, const Segment& segment) {
  std::vector<double> xyz;
  xyz.reserve(3 * segment.vertices.size());
  for (std::int32_t v : segment.vertices) {
    const Eigen::Vector3f& p = mesh.positions[static_cast<std::size_t>(v)];
    // Relative to the centroid: Qhull's precision is relative to the coordinates' magnitude.
    for (int k = 0; k < 3; ++k) xyz.push_back(static_cast<double>(p[k] - segment.centroid[k]));
  }
  std::vector<double> d;
  if (!hullDistances(xyz, &d)) return 0.0;
  return std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
}

namespace {

struct OrientedPoints {
  std::vector<Eigen::Vector3f> p;  ///< relative to the segment's centroid
  std::vector<Eigen::Vector3f> n;
};

OrientedPoints orientedPoints(const TriangleMesh& mesh, const Segment& segment) {
  if (!mesh.hasNormals()) throw std::invalid_argument("the mesh has no vertex normals");
  OrientedPoints out;
  out.p.reserve(segment.vertices.size());
  out.n.reserve(segment.vertices.size());
  for (std::int32_t v : segment.vertices) {
    out.p.push_back(mesh.positions[static_cast<std::size_t>(v)] - segment.centroid);
    out.n.push_back(mesh.normals[static_cast<std::size_t>(v)]);
  }
  return out;
}

/// Symmetry and smoothness average over at most this many vertices of a segment: every
/// sampleStride(n)-th of its n.
constexpr std::size_t kMeasureSample = 4000;
std::size_t sampleStride(std::size_t n) {
  return std::max<std::size_t>(1, (n + kMeasureSample - 1) / kMeasureSample);
}

/// The angular bin, 0 .. bins - 1, of the direction d in the tangent frame (t1, t2).
int angularBin(const Eigen::Vector3f& d, const Eigen::Vector3f& t1, const Eigen::Vector3f& t2,
               int bins) {
  const float angle = std::atan2(d.dot(t2), d.dot(t1));  // (-pi, pi]
  const int bin = static_cast<int>((angle + static_cast<float>(M_PI)) /
                                   (2.0f * static_cast<float>(M_PI)) * static_cast<float>(bins));
  return std::clamp(bin, 0, bins - 1);
}

}  // namespace

double symmetry(const TriangleMesh& mesh, const Segment& segment, float beta) {
  const OrientedPoints pts = orientedPoints(mesh, segment);
  const float lambda_sum = segment.eigenvalues.sum();
  if (!(lambda_sum > 0.0f)) return 0.0;
  const PointIndex index(pts.p);
  const std::size_t n = pts.p.size();
  const std::size_t stride = sampleStride(n);
  double total = 0.0;
  for (int d = 0; d < 3; ++d) {
    const float r = segment.extents[d];
    if (!(r > 0.0f)) continue;
    const Eigen::Vector3f a = segment.axes.col(d);
    // O(MC, C): each mirrored vertex against the original's nearest. It equals O(C, MC), since
    // |p - M q| = |M p - q| and n . M n' = M n . n' (M is a reflection), so the nearest mirrored
    // vertex to p is the mirror of the nearest original vertex to M p.
    // The mean over at most kMeasureSample evenly spaced vertices: on a dense single view (a
    // segment of 30,000 vertices) the mean of every vertex costs ten times as much and moves by
    // less than its noise.
    double sum = 0.0;
    std::size_t queries = 0;
    for (std::size_t i = 0; i < n; i += stride) {
      ++queries;
      const Eigen::Vector3f q = pts.p[i] - 2.0f * pts.p[i].dot(a) * a;
      const Eigen::Vector3f nq = pts.n[i] - 2.0f * pts.n[i].dot(a) * a;
      const std::uint32_t j = index.nearest(q);
      sum += (q - pts.p[j]).norm() / r + beta * (1.0f - nq.dot(pts.n[j]));
    }
    const double both = 2.0 * sum / static_cast<double>(queries);
    total += static_cast<double>(segment.eigenvalues[d] / lambda_sum) * both;
  }
  return total;
}

std::vector<std::int32_t> smoothnessSample(const std::vector<std::int32_t>& vertices) {
  const std::size_t stride = sampleStride(vertices.size());
  if (stride == 1) return vertices;
  std::vector<std::int32_t> sample;
  sample.reserve(vertices.size() / stride + 1);
  for (std::size_t i = 0; i < vertices.size(); i += stride) sample.push_back(vertices[i]);
  return sample;
}

TangentNeighbours tangentNeighbours(const TriangleMesh& mesh,
                                    const std::vector<std::int32_t>& vertices, float radius_m,
                                    int bins, const std::vector<std::int32_t>* queries) {
  if (!(radius_m > 0.0f) || bins < 2 || bins > 255) {
    throw std::invalid_argument(
        "smoothness needs a positive radius and between 2 and 255 angular bins");
  }
  if (!mesh.hasNormals()) throw std::invalid_argument("the mesh has no vertex normals");
  TangentNeighbours out;
  out.radius_m = radius_m;
  out.bins = bins;
  out.indexed.assign(mesh.positions.size(), 0);
  std::vector<Eigen::Vector3f> points;
  points.reserve(vertices.size());
  // Each vertex's place among the points (-1: not one), to find a query's own point.
  std::vector<std::int32_t> point_of(mesh.positions.size(), -1);
  for (std::int32_t v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= mesh.positions.size()) {
      throw std::invalid_argument("smoothness: vertex " + std::to_string(v) +
                                  " is not in the mesh");
    }
    if (!points.empty() && v <= vertices[points.size() - 1]) {
      throw std::invalid_argument("smoothness: the vertices must be given in increasing order");
    }
    point_of[static_cast<std::size_t>(v)] = static_cast<std::int32_t>(points.size());
    out.indexed[static_cast<std::size_t>(v)] = 1;
    points.push_back(mesh.positions[static_cast<std::size_t>(v)]);
  }
  const std::vector<std::int32_t>& asked = queries ? *queries : vertices;
  for (std::size_t i = 0; i < asked.size(); ++i) {
    const std::int32_t v = asked[i];
    if (v < 0 || static_cast<std::size_t>(v) >= mesh.positions.size() ||
        point_of[static_cast<std::size_t>(v)] < 0) {
      throw std::invalid_argument("smoothness: query vertex " + std::to_string(v) +
                                  " is not among the vertices");
    }
    if (i > 0 && v <= asked[i - 1]) {
      throw std::invalid_argument("smoothness: the queries must be given in increasing order");
    }
    out.indexed[static_cast<std::size_t>(v)] = 2;
  }
  const PointIndex index(points);
  // Blocks of queries in parallel, each writing its own rows; joined in order afterwards.
  struct Block {
    std::vector<std::uint32_t> counts;
    std::vector<std::int32_t> neighbours;
    std::vector<std::uint8_t> bin;
  };
  constexpr std::size_t kBlock = 2048;
  std::vector<Block> blocks((asked.size() + kBlock - 1) / kBlock);
  tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t b) {
    Block& block = blocks[b];
    std::vector<std::pair<std::uint32_t, float>> found;
    const std::size_t end = std::min(asked.size(), (b + 1) * kBlock);
    for (std::size_t q = b * kBlock; q < end; ++q) {
      const auto v = static_cast<std::size_t>(asked[q]);
      const auto i = static_cast<std::uint32_t>(point_of[v]);
      const Eigen::Vector3f& n = mesh.normals[v];
      // A tangent frame (t1, t2) at the vertex.
      const Eigen::Vector3f helper =
          std::abs(n.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
      const Eigen::Vector3f t1 = n.cross(helper).normalized();
      const Eigen::Vector3f t2 = n.cross(t1);
      index.within(points[i], radius_m, &found);
      std::uint32_t count = 0;
      for (const auto& [j, distance_sq] : found) {
        if (j == i) continue;
        block.neighbours.push_back(vertices[j]);
        block.bin.push_back(
            static_cast<std::uint8_t>(angularBin(points[j] - points[i], t1, t2, bins)));
        ++count;
      }
      block.counts.push_back(count);
    }
  });
  out.offsets.assign(mesh.positions.size() + 1, 0);
  std::size_t i = 0;
  for (const Block& block : blocks) {
    for (std::uint32_t count : block.counts) {
      out.offsets[static_cast<std::size_t>(asked[i++]) + 1] = count;
    }
  }
  std::partial_sum(out.offsets.begin(), out.offsets.end(), out.offsets.begin());
  out.neighbours.reserve(out.offsets.back());
  out.bin.reserve(out.offsets.back());
  for (const Block& block : blocks) {
    out.neighbours.insert(out.neighbours.end(), block.neighbours.begin(), block.neighbours.end());
    out.bin.insert(out.bin.end(), block.bin.begin(), block.bin.end());
  }
  return out;
}

double smoothness(const TriangleMesh& mesh, const Segment& segment, float radius_m, int bins) {
  const std::vector<std::int32_t> sample = smoothnessSample(segment.vertices);
  return smoothness(tangentNeighbours(mesh, segment.vertices, radius_m, bins, &sample), segment);
}

double smoothness(const TangentNeighbours& neighbours, const Segment& segment) {
  const Members in(segment.vertices);
  std::vector<int> histogram(static_cast<std::size_t>(neighbours.bins));
  const double log_bins = std::log(static_cast<double>(neighbours.bins));
  double sum = 0.0;
  // Every vertex must be among the look-ups' (a neighbour left out would be silently missed),
  // and every vertex of the sample looked up.
  for (std::int32_t v : segment.vertices) {
    const auto vi = static_cast<std::size_t>(v);
    if (vi >= neighbours.indexed.size() || !neighbours.indexed[vi]) {
      throw std::invalid_argument("smoothness: vertex " + std::to_string(v) +
                                  " is not among the vertices its look-ups were built for");
    }
  }
  const std::vector<std::int32_t> sample = smoothnessSample(segment.vertices);
  for (std::int32_t v : sample) {
    const auto vi = static_cast<std::size_t>(v);
    if (neighbours.indexed[vi] != 2) {
      throw std::invalid_argument("smoothness: vertex " + std::to_string(v) + " was not looked up");
    }
    std::fill(histogram.begin(), histogram.end(), 0);
    int count = 0;
    for (std::size_t k = neighbours.offsets[vi]; k < neighbours.offsets[vi + 1]; ++k) {
      if (!in.contains(neighbours.neighbours[k])) continue;
      ++histogram[neighbours.bin[k]];
      ++count;
    }
    double entropy = 0.0;
    for (int c : histogram) {
      if (c == 0) continue;
      const double q = static_cast<double>(c) / count;
      entropy -= q * std::log(q);
    }
    sum += entropy / log_bins;
  }
  return sum / static_cast<double>(sample.size());
}

}  // namespace objscan::discovery
