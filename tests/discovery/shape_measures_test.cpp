// Compactness, local and global convexity on shapes whose answers are known: a sphere is compact
// and convex; a flat sheet is neither; an L-shaped bracket is locally concave at its fold; a
// torus is not globally convex.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

#include "objscan/discovery/shape_measures.h"

namespace objscan::discovery {
namespace {

constexpr float kPi = static_cast<float>(M_PI);

/// A (u, v) grid of n x m vertices mapped through f, two triangles per cell, optionally wrapping
/// around in u and v; normals from the triangles (their winding sets the side).
TriangleMesh parametric(int n, int m, bool wrap_u, bool wrap_v,
                        const std::function<Eigen::Vector3f(float, float)>& f) {
  TriangleMesh mesh;
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < n; ++i) {
      mesh.positions.push_back(f(static_cast<float>(i) / static_cast<float>(wrap_u ? n : n - 1),
                                 static_cast<float>(j) / static_cast<float>(wrap_v ? m : m - 1)));
    }
  }
  const int cells_u = wrap_u ? n : n - 1, cells_v = wrap_v ? m : m - 1;
  for (int j = 0; j < cells_v; ++j) {
    for (int i = 0; i < cells_u; ++i) {
      const int a = j * n + i, b = j * n + (i + 1) % n;
      const int c = ((j + 1) % m) * n + (i + 1) % n, d = ((j + 1) % m) * n + i;
      mesh.triangles.emplace_back(a, b, c);
      mesh.triangles.emplace_back(a, c, d);
    }
  }
  mesh.computeNormals();
  return mesh;
}

/// A sphere of radius r: latitude rings between the poles, closed by two pole vertices.
TriangleMesh sphere(float r) {
  const int n = 48, m = 24;
  TriangleMesh mesh = parametric(n, m, true, false, [&](float u, float v) {
    const float theta = kPi * (0.02f + 0.96f * v), phi = 2.0f * kPi * u;
    return Eigen::Vector3f(r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi),
                           r * std::cos(theta));
  });
  const int north = static_cast<int>(mesh.positions.size()), south = north + 1;
  mesh.positions.emplace_back(0, 0, r);
  mesh.positions.emplace_back(0, 0, -r);
  for (int i = 0; i < n; ++i) {
    mesh.triangles.emplace_back(north, (i + 1) % n, i);
    mesh.triangles.emplace_back(south, (m - 1) * n + i, (m - 1) * n + (i + 1) % n);
  }
  for (Eigen::Vector3i& t : mesh.triangles) std::swap(t[1], t[2]);  // outward
  mesh.computeNormals();
  return mesh;
}

TriangleMesh sheet(float side) {
  return parametric(30, 30, false, false,
                    [&](float u, float v) { return Eigen::Vector3f(side * u, side * v, 0.0f); });
}

/// Two 10 x 10 cm plates meeting at a right angle along the y axis; `inside` winds the triangles
/// so that the normals face into the L (the fold is then concave), otherwise away from it.
TriangleMesh bracket(bool inside) {
  TriangleMesh mesh = parametric(41, 21, false, false, [](float u, float v) {
    const float s = 0.2f * u;  // 0..0.1 along the floor plate, 0.1..0.2 up the wall plate
    return s <= 0.1f ? Eigen::Vector3f(0.1f - s, 0.1f * v, 0.0f)
                     : Eigen::Vector3f(0.0f, 0.1f * v, s - 0.1f);
  });
  if (inside) {
    for (Eigen::Vector3i& t : mesh.triangles) std::swap(t[1], t[2]);
    mesh.computeNormals();
  }
  return mesh;
}

TriangleMesh torus(float big, float small) {
  return parametric(64, 32, true, true, [&](float u, float v) {
    const float a = 2.0f * kPi * u, b = 2.0f * kPi * v;
    return Eigen::Vector3f((big + small * std::cos(b)) * std::cos(a),
                           (big + small * std::cos(b)) * std::sin(a), small * std::sin(b));
  });
}

Segment whole(const TriangleMesh& mesh) {
  std::vector<std::int32_t> v(mesh.positions.size());
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<std::int32_t>(i);
  return describeSegment(mesh, v);
}

/// The vertices of `mesh` for which `inside` holds, as a segment.
Segment part(const TriangleMesh& mesh, const std::function<bool(const Eigen::Vector3f&)>& inside) {
  std::vector<std::int32_t> v;
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    if (inside(mesh.positions[i])) v.push_back(static_cast<std::int32_t>(i));
  }
  return describeSegment(mesh, v);
}

/// `mesh` with every vertex moved by up to `amount` along each axis (fixed seed) and its normals
/// recomputed: no two distances tie by accident.
TriangleMesh jittered(TriangleMesh mesh, float amount) {
  std::mt19937 random(11);
  std::uniform_real_distribution<float> offset(-amount, amount);
  for (Eigen::Vector3f& p : mesh.positions)
    p += Eigen::Vector3f(offset(random), offset(random), offset(random));
  mesh.computeNormals();
  return mesh;
}

TEST(SmallestEnclosingSphere, OfKnownPointSets) {
  // The 8 corners of a cube of side 2: radius sqrt(3) about the centre.
  std::vector<Eigen::Vector3d> cube;
  for (int i = 0; i < 8; ++i) cube.emplace_back(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 5 : 3);
  Sphere s = smallestEnclosingSphere(cube);
  EXPECT_NEAR(s.radius, std::sqrt(3.0), 1e-9);
  EXPECT_TRUE(s.centre.isApprox(Eigen::Vector3d(0, 0, 4), 1e-9));
  // An obtuse triangle: the sphere spans its longest side, not its circumcircle.
  s = smallestEnclosingSphere({{0, 0, 0}, {4, 0, 0}, {2, 0.5, 0}});
  EXPECT_NEAR(s.radius, 2.0, 1e-9);
  // Many coplanar points on a circle, and its centre.
  std::vector<Eigen::Vector3d> ring{{0, 0, 0}};
  for (int k = 0; k < 100; ++k) ring.emplace_back(std::cos(0.1 * k), std::sin(0.1 * k), 0);
  EXPECT_NEAR(smallestEnclosingSphere(ring).radius, 1.0, 1e-9);
  EXPECT_THROW(smallestEnclosingSphere({}), std::invalid_argument);
}

TEST(ShapeMeasures, CompactnessOfASphereAndASheet) {
  const TriangleMesh ball = sphere(0.05f);
  // The polyhedron's area falls short of the sphere's by under 1 %.
  EXPECT_NEAR(compactness(ball, whole(ball)), 1.0, 0.01);
  const TriangleMesh flat = sheet(0.2f);
  EXPECT_NEAR(compactness(flat, whole(flat)), 1.0 / (2.0 * M_PI), 1e-4);
}

TEST(ShapeMeasures, LocalConvexityOfASphereASheetAndABracket) {
  const TriangleMesh ball = sphere(0.05f);
  ASSERT_GT(ball.normals[0].dot(ball.positions[0]), 0.0f);  // outward
  const MeshGraph g = buildMeshGraph(ball);
  EXPECT_DOUBLE_EQ(localConvexity(g, vertexEdges(g), whole(ball)), 1.0);
  const TriangleMesh flat = sheet(0.2f);
  const MeshGraph gf = buildMeshGraph(flat);
  EXPECT_DOUBLE_EQ(localConvexity(gf, vertexEdges(gf), whole(flat)), 0.0);
  // The fold's edges (and their neighbours' tilted normals) are concave seen from inside the L
  // and convex seen from outside; the flat rest is neither.
  const TriangleMesh in_l = bracket(true), out_l = bracket(false);
  ASSERT_GT(in_l.normals[0].z(), 0.0f);  // the floor plate's normals point up, into the L
  const MeshGraph gi = buildMeshGraph(in_l), go = buildMeshGraph(out_l);
  EXPECT_DOUBLE_EQ(localConvexity(gi, vertexEdges(gi), whole(in_l)), 0.0);
  const double outside = localConvexity(go, vertexEdges(go), whole(out_l));
  EXPECT_GT(outside, 0.0);
  EXPECT_LT(outside, 0.1);
}

TEST(ShapeMeasures, GlobalConvexityOfASphereASheetAndATorus) {
  const TriangleMesh ball = sphere(0.05f);
  EXPECT_LT(hullDistance(ball, whole(ball)), 1e-6);
  const TriangleMesh flat = sheet(0.2f);
  EXPECT_EQ(hullDistance(flat, whole(flat)), 0.0);  // flat: no 3D hull, no distance
  // A torus's outer half (cos b > 0) lies on its hull; a point of the inner half is nearest the
  // flat cap over the hole, r (1 - |sin b|) away. Over vertices uniform in (a, b) the mean is
  // r (1 - 2 / pi) / 2: 3.6 mm for r = 2 cm.
  const TriangleMesh ring = torus(0.06f, 0.02f);
  EXPECT_NEAR(hullDistance(ring, whole(ring)), 0.02 * (1.0 - 2.0 / M_PI) / 2.0, 2e-4);
}

TEST(ShapeMeasures, SymmetryOfASphereAndOfALopsidedShape) {
  const TriangleMesh ball = sphere(0.05f);
  const double round = symmetry(ball, whole(ball));
  // Its mirror images coincide with it up to the sampling (vertices 3-6 mm apart on a 5 cm
  // sphere): a few hundredths.
  EXPECT_LT(round, 0.05);
  // A sheet bent up along one edge only (a J in profile): no mirror plane maps it onto itself.
  const TriangleMesh hook = parametric(40, 20, false, false, [](float u, float v) {
    const float x = 0.2f * u;
    return Eigen::Vector3f(x, 0.08f * v,
                           x > 0.15f ? 2.0f * (x - 0.15f) * (x - 0.15f) * 40.0f : 0.0f);
  });
  EXPECT_GT(symmetry(hook, whole(hook)), 4.0 * round);
}

TEST(ShapeMeasures, CompactnessAndLocalConvexityOfAPartCountOnlyItsOwnTrianglesAndEdges) {
  const TriangleMesh ball = jittered(sphere(0.05f), 5e-4f);
  const Segment cap = part(ball, [](const Eigen::Vector3f& p) { return p.z() > 0.01f; });
  // Brute force: every triangle of the mesh, kept when its three vertices are in the cap.
  const auto in = [&](std::int32_t v) {
    return std::binary_search(cap.vertices.begin(), cap.vertices.end(), v);
  };
  double area = 0.0;
  for (const Eigen::Vector3i& t : ball.triangles) {
    if (!in(t[0]) || !in(t[1]) || !in(t[2])) continue;
    const Eigen::Vector3d a = ball.positions[static_cast<std::size_t>(t[0])].cast<double>();
    const Eigen::Vector3d b = ball.positions[static_cast<std::size_t>(t[1])].cast<double>();
    const Eigen::Vector3d c = ball.positions[static_cast<std::size_t>(t[2])].cast<double>();
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  std::vector<Eigen::Vector3d> points;
  for (std::int32_t v : cap.vertices) {
    points.push_back(ball.positions[static_cast<std::size_t>(v)].cast<double>());
  }
  const double radius = smallestEnclosingSphere(points).radius;
  const double expected = area / (4.0 * M_PI * radius * radius);
  EXPECT_GT(expected, 0.1);
  // Summed in another order: equal up to rounding.
  EXPECT_NEAR(compactness(ball, cap), expected, 1e-12);
  EXPECT_NEAR(compactness(ball, vertexTriangles(ball), cap), expected, 1e-12);
  EXPECT_THROW(compactness(ball, vertexTriangles(sheet(0.1f)), cap), std::invalid_argument);

  const MeshGraph graph = buildMeshGraph(ball);
  std::size_t edges = 0, convex = 0;
  for (const MeshEdge& e : graph.edges) {
    if (!in(e.a) || !in(e.b)) continue;
    ++edges;
    convex += e.convex ? 1 : 0;
  }
  ASSERT_GT(edges, 0u);
  EXPECT_DOUBLE_EQ(localConvexity(graph, vertexEdges(graph), cap),
                   static_cast<double>(convex) / static_cast<double>(edges));
}

/// Symmetry as the paper writes it: for each axis, the segment's mirror image built explicitly,
/// and both one-sided overlaps found by brute force.
double referenceSymmetry(const TriangleMesh& mesh, const Segment& s, float beta) {
  std::vector<Eigen::Vector3f> p, n;
  for (std::int32_t v : s.vertices) {
    p.push_back(mesh.positions[static_cast<std::size_t>(v)] - s.centroid);
    n.push_back(mesh.normals[static_cast<std::size_t>(v)]);
  }
  const auto overlap =
      [&](const std::vector<Eigen::Vector3f>& p1, const std::vector<Eigen::Vector3f>& n1,
          const std::vector<Eigen::Vector3f>& p2, const std::vector<Eigen::Vector3f>& n2, float r) {
        double sum = 0.0;
        for (std::size_t i = 0; i < p1.size(); ++i) {
          std::size_t best = 0;
          float best_d = std::numeric_limits<float>::infinity();
          for (std::size_t j = 0; j < p2.size(); ++j) {
            const float d = (p1[i] - p2[j]).squaredNorm();
            if (d < best_d) {
              best_d = d;
              best = j;
            }
          }
          sum += std::sqrt(best_d) / r + beta * (1.0f - n1[i].dot(n2[best]));
        }
        return sum / static_cast<double>(p1.size());
      };
  const float lambda_sum = s.eigenvalues.sum();
  double total = 0.0;
  for (int d = 0; d < 3; ++d) {
    const Eigen::Vector3f a = s.axes.col(d);
    std::vector<Eigen::Vector3f> mp, mn;
    for (std::size_t i = 0; i < p.size(); ++i) {
      mp.push_back(p[i] - 2.0f * p[i].dot(a) * a);
      mn.push_back(n[i] - 2.0f * n[i].dot(a) * a);
    }
    const float r = s.extents[d];
    total += static_cast<double>(s.eigenvalues[d] / lambda_sum) *
             (overlap(p, n, mp, mn, r) + overlap(mp, mn, p, n, r));
  }
  return total;
}

TEST(ShapeMeasures, SymmetryEqualsBothSidesComputedByBruteForce) {
  // The lopsided hook, jittered: one side is computed and doubled, which must equal the two
  // sides found separately, up to float rounding of the distances.
  const TriangleMesh hook =
      jittered(parametric(40, 20, false, false,
                          [](float u, float v) {
                            const float x = 0.2f * u;
                            return Eigen::Vector3f(
                                x, 0.08f * v, x > 0.15f ? 80.0f * (x - 0.15f) * (x - 0.15f) : 0.0f);
                          }),
               1e-3f);
  const Segment all = whole(hook);
  const double expected = referenceSymmetry(hook, all, 0.2f);
  EXPECT_GT(expected, 0.1);
  EXPECT_NEAR(symmetry(hook, all, 0.2f), expected, 1e-5 * expected);
  const Segment half = part(hook, [](const Eigen::Vector3f& p) { return p.y() < 0.05f; });
  EXPECT_NEAR(symmetry(hook, half, 0.5f), referenceSymmetry(hook, half, 0.5f),
              1e-5 * referenceSymmetry(hook, half, 0.5f));
}

/// Smoothness by brute force: for each vertex of the segment's sample (of every vertex with
/// `sampled` false), every other vertex of the segment within the radius, binned by its direction
/// in the same tangent frame.
double referenceSmoothness(const TriangleMesh& mesh, const Segment& s, float radius, int bins,
                           bool sampled = true) {
  double sum = 0.0;
  const std::vector<std::int32_t> over = sampled ? smoothnessSample(s.vertices) : s.vertices;
  for (std::int32_t v : over) {
    const Eigen::Vector3f& p = mesh.positions[static_cast<std::size_t>(v)];
    const Eigen::Vector3f& n = mesh.normals[static_cast<std::size_t>(v)];
    const Eigen::Vector3f helper =
        std::abs(n.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
    const Eigen::Vector3f t1 = n.cross(helper).normalized(), t2 = n.cross(t1);
    std::vector<int> histogram(static_cast<std::size_t>(bins), 0);
    int count = 0;
    for (std::int32_t w : s.vertices) {
      const Eigen::Vector3f d = mesh.positions[static_cast<std::size_t>(w)] - p;
      if (w == v || !(d.squaredNorm() < radius * radius)) continue;
      const float angle = std::atan2(d.dot(t2), d.dot(t1));
      const int bin = std::clamp(
          static_cast<int>((angle + kPi) / (2.0f * kPi) * static_cast<float>(bins)), 0, bins - 1);
      ++histogram[static_cast<std::size_t>(bin)];
      ++count;
    }
    double entropy = 0.0;
    for (int c : histogram) {
      if (c > 0)
        entropy -= static_cast<double>(c) / count * std::log(static_cast<double>(c) / count);
    }
    sum += entropy / std::log(static_cast<double>(bins));
  }
  return sum / static_cast<double>(over.size());
}

TEST(ShapeMeasures, SmoothnessFromSharedSceneLookUpsEqualsBruteForcePerSegment) {
  const TriangleMesh ball = jittered(sphere(0.05f), 5e-4f);
  const Segment upper = part(ball, [](const Eigen::Vector3f& p) { return p.z() > 0.0f; });
  const Segment band = part(ball, [](const Eigen::Vector3f& p) { return std::abs(p.z()) < 0.02f; });
  // One set of look-ups for the whole scene serves both overlapping segments: the neighbours
  // outside a segment are left out of its histograms.
  const TangentNeighbours scene = tangentNeighbours(ball, whole(ball).vertices, 0.015f, 8);
  for (const Segment* s : {&upper, &band}) {
    const double expected = referenceSmoothness(ball, *s, 0.015f, 8);
    EXPECT_GT(expected, 0.3);
    EXPECT_NEAR(smoothness(scene, *s), expected, 1e-12);
    EXPECT_NEAR(smoothness(ball, *s, 0.015f, 8), expected, 1e-12);
  }
  // Look-ups built for the upper half know nothing of the band's lower vertices.
  const TangentNeighbours upper_only = tangentNeighbours(ball, upper.vertices, 0.015f, 8);
  EXPECT_NEAR(smoothness(upper_only, upper), smoothness(scene, upper), 1e-12);
  EXPECT_THROW(smoothness(upper_only, band), std::invalid_argument);
  EXPECT_THROW(tangentNeighbours(ball, upper.vertices, 0.015f, 256), std::invalid_argument);
  EXPECT_THROW(tangentNeighbours(ball, {-1}, 0.015f, 8), std::invalid_argument);
  EXPECT_THROW(tangentNeighbours(ball, {2, 1}, 0.015f, 8), std::invalid_argument);
}

TEST(ShapeMeasures, SmoothnessOfALargeSegmentAveragesOverItsSample) {
  // A wavy, jittered 25 cm sheet of 10,201 vertices, and two overlapping parts of it, each of more
  // than 4,000 vertices: each averages over every second or third of its vertices.
  const TriangleMesh sheet = jittered(
      parametric(101, 101, false, false,
                 [](float u, float v) {
                   return Eigen::Vector3f(0.25f * u, 0.25f * v,
                                          0.01f * std::sin(12.0f * u) * std::cos(9.0f * v));
                 }),
      5e-4f);
  const Segment all = whole(sheet);
  const Segment left = part(sheet, [](const Eigen::Vector3f& p) { return p.x() < 0.15f; });
  const Segment low = part(sheet, [](const Eigen::Vector3f& p) { return p.y() < 0.12f; });
  ASSERT_EQ(smoothnessSample(all.vertices).size(), 3401u);
  EXPECT_EQ(smoothnessSample(left.vertices).size(),
            (left.vertices.size() + 1) / 2);  // 4,001 to 8,000 vertices: every second
  const std::vector<std::int32_t> few(all.vertices.begin(), all.vertices.begin() + 4000);
  EXPECT_EQ(smoothnessSample(few), few);  // 4,000 or fewer: all of them
  // One set of look-ups for the scene, querying only the union of the parts' samples (a strict
  // subset of the vertices): each part's value is the brute-force mean over its sample.
  std::set<std::int32_t> asked;
  for (const Segment* s : {&left, &low}) {
    for (std::int32_t v : smoothnessSample(s->vertices)) asked.insert(v);
  }
  const std::vector<std::int32_t> queries(asked.begin(), asked.end());
  ASSERT_LT(queries.size(), all.vertices.size());
  const TangentNeighbours scene = tangentNeighbours(sheet, all.vertices, 0.01f, 8, &queries);
  for (const Segment* s : {&left, &low}) {
    const double expected = referenceSmoothness(sheet, *s, 0.01f, 8);
    EXPECT_GT(expected, 0.5);
    EXPECT_NEAR(smoothness(scene, *s), expected, 1e-12);
    EXPECT_NEAR(smoothness(sheet, *s, 0.01f, 8), expected, 1e-12);
    // The sample's mean is within 0.01 of the mean over every vertex.
    EXPECT_NEAR(expected, referenceSmoothness(sheet, *s, 0.01f, 8, false), 0.01);
  }
  // The whole sheet's sample was not all looked up; a part's vertices must all be among the
  // look-ups' (not only its sample), or a neighbour would be missed.
  EXPECT_THROW(smoothness(scene, all), std::invalid_argument);
  const std::vector<std::int32_t> left_sample = smoothnessSample(left.vertices);
  const TangentNeighbours sample_only =
      tangentNeighbours(sheet, left_sample, 0.01f, 8, &left_sample);
  EXPECT_THROW(smoothness(sample_only, left), std::invalid_argument);
  // A query must be one of the vertices, in increasing order.
  const std::vector<std::int32_t> outside = {0, 20000};
  EXPECT_THROW(tangentNeighbours(sheet, all.vertices, 0.01f, 8, &outside), std::invalid_argument);
  const std::vector<std::int32_t> backwards = {5, 3};
  EXPECT_THROW(tangentNeighbours(sheet, all.vertices, 0.01f, 8, &backwards), std::invalid_argument);
}

TEST(ShapeMeasures, SmoothnessOfASheetAndOfAThinStrip) {
  // A 20 cm sheet with vertices 2.5 mm apart: about 50 neighbours within 1 cm, all round.
  const TriangleMesh wide = parametric(81, 81, false, false, [](float u, float v) {
    return Eigen::Vector3f(0.2f * u, 0.2f * v, 0.0f);
  });
  EXPECT_GT(smoothness(wide, whole(wide)), 0.9);
  // A strip 2.5 mm wide (two vertex rows): neighbours ahead, behind and to one side.
  const TriangleMesh strip = parametric(81, 2, false, false, [](float u, float v) {
    return Eigen::Vector3f(0.2f * u, 0.0025f * v, 0.0f);
  });
  EXPECT_LT(smoothness(strip, whole(strip)), 0.75);
  // A wire (one row of vertices 3 mm apart, normals up): a vertex has b neighbours behind and a
  // ahead within 1 cm (up to 3 each way), in two opposite bins, so its entropy is that of the
  // split b : a, in units of log 8.
  TriangleMesh wire;
  const int n = 81;
  for (int i = 0; i < n; ++i) {
    wire.positions.emplace_back(0.003f * static_cast<float>(i), 0.0f, 0.0f);
    wire.normals.emplace_back(0.0f, 0.0f, 1.0f);
  }
  double expected = 0.0;
  for (int i = 0; i < n; ++i) {
    const double b = std::min(i, 3), a = std::min(n - 1 - i, 3);
    for (double share : {b / (a + b), a / (a + b)}) {
      if (share > 0.0) expected -= share * std::log(share) / std::log(8.0) / n;
    }
  }
  EXPECT_NEAR(smoothness(wire, whole(wire)), expected, 1e-9);
  EXPECT_THROW(smoothness(wide, whole(wide), 0.0f), std::invalid_argument);
}

}  // namespace
}  // namespace objscan::discovery
