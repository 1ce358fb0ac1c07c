#include "objscan/fusion/marching_cubes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "objscan/core/progress.h"

#include "volume_internal.h"

namespace objscan::fusion {

namespace {

// --- The case table ------------------------------------------------------------------------------
// Corner c of a cube sits at offset (c & 1, (c >> 1) & 1, (c >> 2) & 1). Edge e joins the corners
// kEdgeCorners[e]; edges 0-3 run along x, 4-7 along y, 8-11 along z.
constexpr int kEdgeCorners[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                     {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

Eigen::Vector3f cornerOffset(int c) {
  return Eigen::Vector3f(static_cast<float>(c & 1), static_cast<float>((c >> 1) & 1),
                         static_cast<float>((c >> 2) & 1));
}

int edgeBetween(int a, int b) {
  for (int e = 0; e < 12; ++e) {
    if ((kEdgeCorners[e][0] == a && kEdgeCorners[e][1] == b) ||
        (kEdgeCorners[e][0] == b && kEdgeCorners[e][1] == a)) {
      return e;
    }
  }
  return -1;
}

using Triangle = std::array<std::uint8_t, 3>;  // edges

/// Triangles (as edges) for each of the 256 sign patterns (bit c set: corner c is inside, i.e.
/// negative). Built from the faces: on each face, walked counter-clockwise as seen from outside
/// the cube, every crossing from outside to inside is joined to the next crossing from inside to
/// outside. That separates the inside corners of an ambiguous face (two diagonal corners inside)
/// the same way from both cubes sharing it, so neighbouring cubes agree and the surface is closed.
/// Each crossing edge then starts one face segment and ends another; following them gives the
/// polygons, fanned into triangles. All polygons wind the same way; the winding is flipped once
/// so that triangles are counter-clockwise seen from outside (the positive side).
struct CaseTable {
  std::array<std::vector<Triangle>, 256> triangles;

  CaseTable() {
    // The six faces, each as its corners in counter-clockwise order around the outward normal.
    std::vector<std::array<int, 4>> faces;
    for (int axis = 0; axis < 3; ++axis) {
      for (int side = 0; side < 2; ++side) {
        Eigen::Vector3f normal = Eigen::Vector3f::Zero();
        normal[axis] = side ? 1.0f : -1.0f;
        const Eigen::Vector3f a = normal.unitOrthogonal(), b = normal.cross(a);
        std::array<int, 4> corners{};
        int k = 0;
        for (int c = 0; c < 8; ++c) {
          if (((c >> axis) & 1) == side) corners[static_cast<std::size_t>(k++)] = c;
        }
        const Eigen::Vector3f centre = Eigen::Vector3f::Constant(0.5f);
        std::sort(corners.begin(), corners.end(), [&](int x, int y) {
          const Eigen::Vector3f dx = cornerOffset(x) - centre, dy = cornerOffset(y) - centre;
          return std::atan2(dx.dot(b), dx.dot(a)) < std::atan2(dy.dot(b), dy.dot(a));
        });
        faces.push_back(corners);
      }
    }
    for (int pattern = 0; pattern < 256; ++pattern) {
      const auto inside = [&](int c) { return ((pattern >> c) & 1) != 0; };
      std::array<int, 12> next;
      next.fill(-1);
      for (const std::array<int, 4>& face : faces) {
        for (int j = 0; j < 4; ++j) {
          const int from = face[static_cast<std::size_t>(j)];
          const int to = face[static_cast<std::size_t>((j + 1) % 4)];
          if (inside(from) || !inside(to)) continue;  // not an outside-to-inside crossing
          for (int k = 1; k < 4; ++k) {
            const int a = face[static_cast<std::size_t>((j + k) % 4)];
            const int b = face[static_cast<std::size_t>((j + k + 1) % 4)];
            if (inside(a) && !inside(b)) {
              next[static_cast<std::size_t>(edgeBetween(from, to))] = edgeBetween(a, b);
              break;
            }
          }
        }
      }
      std::array<bool, 12> used{};
      for (int start = 0; start < 12; ++start) {
        if (next[static_cast<std::size_t>(start)] < 0 || used[static_cast<std::size_t>(start)]) {
          continue;
        }
        std::vector<int> loop;
        for (int e = start; !used[static_cast<std::size_t>(e)];
             e = next[static_cast<std::size_t>(e)]) {
          used[static_cast<std::size_t>(e)] = true;
          loop.push_back(e);
        }
        for (std::size_t k = 1; k + 1 < loop.size(); ++k) {
          triangles[static_cast<std::size_t>(pattern)].push_back(
              {static_cast<std::uint8_t>(loop[0]), static_cast<std::uint8_t>(loop[k]),
               static_cast<std::uint8_t>(loop[k + 1])});
        }
      }
    }
    // Corner 0 alone inside: the outward side faces (1, 1, 1).
    const auto midpoint = [](int e) -> Eigen::Vector3f {
      return 0.5f * (cornerOffset(kEdgeCorners[e][0]) + cornerOffset(kEdgeCorners[e][1]));
    };
    const Triangle& t = triangles[1].front();
    const Eigen::Vector3f n =
        (midpoint(t[1]) - midpoint(t[0])).cross(midpoint(t[2]) - midpoint(t[0]));
    if (n.dot(Eigen::Vector3f::Ones()) < 0.0f) {
      for (auto& list : triangles) {
        for (Triangle& tri : list) std::swap(tri[1], tri[2]);
      }
    }
  }
};

const CaseTable& caseTable() {
  static const CaseTable table;
  return table;
}

// --- Extraction ----------------------------------------------------------------------------------

/// A block and the 7 blocks on its +x, +y, +z sides (index = x + 2y + 4z), any of them null.
struct Neighbourhood {
  std::array<const VoxelBlock*, 8> blocks{};
  std::array<std::int32_t, 8> numbers{};  ///< index of each block in the volume, -1 if none

  /// The voxel at local coordinates (x, y, z), each in 0 .. 8 (8 reaches into a neighbour).
  const PackedVoxel* voxel(int x, int y, int z, std::int32_t* number = nullptr) const {
    const int n = (x >> 3) + 2 * (y >> 3) + 4 * (z >> 3);
    const VoxelBlock* b = blocks[static_cast<std::size_t>(n)];
    if (number) *number = numbers[static_cast<std::size_t>(n)];
    return b ? &b->voxels[static_cast<std::size_t>(localIndex(x & 7, y & 7, z & 7))] : nullptr;
  }

  /// The colour of the voxel at local coordinates (x, y, z); its block must exist.
  const VoxelColor& color(int x, int y, int z) const {
    const int n = (x >> 3) + 2 * (y >> 3) + 4 * (z >> 3);
    return blocks[static_cast<std::size_t>(n)]
        ->colors[static_cast<std::size_t>(localIndex(x & 7, y & 7, z & 7))];
  }
};

bool observed(const PackedVoxel* v) { return v && v->observed(); }

/// Interpolation parameter of the zero crossing between two distances of opposite sign, kept off
/// the end points so that vertices of different edges never coincide.
float crossing(float f0, float f1) { return std::clamp(f0 / (f0 - f1), 1e-3f, 1.0f - 1e-3f); }

}  // namespace

TriangleMesh extractMesh(const TsdfVolume& volume_in, const std::string& progress_label) {
  const TsdfVolume::Impl& volume = volume_in.impl();
  const CaseTable& table = caseTable();
  const std::size_t block_count = volume.blocks.size();
  ProgressBar progress(progress_label, 2 * block_count);
  const float voxel = volume.voxel_size_m;

  const auto neighbourhood = [&](std::size_t i) {
    Neighbourhood n;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3i b =
          volume.blocks[i].index + Eigen::Vector3i(k & 1, (k >> 1) & 1, (k >> 2) & 1);
      const auto it = blockInRange(b) ? volume.map.find(blockKey(b)) : volume.map.end();
      n.blocks[static_cast<std::size_t>(k)] =
          it == volume.map.end() ? nullptr : &volume.blocks[static_cast<std::size_t>(it->second)];
      n.numbers[static_cast<std::size_t>(k)] = it == volume.map.end() ? -1 : it->second;
    }
    return n;
  };

  // Pass 1: a vertex on every edge (voxel, +axis) with a sign change; the edge belongs to the
  // block of its first voxel.
  struct BlockVertices {
    std::vector<std::int32_t> edge_vertex;  ///< per (voxel, axis): local vertex number or -1
    std::vector<Eigen::Vector3f> positions;
    std::vector<Rgb8> colors;
    std::vector<float> weights;
  };
  std::vector<BlockVertices> per_block(block_count);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, block_count),
      [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          const Neighbourhood n = neighbourhood(i);
          BlockVertices& out = per_block[i];
          const Eigen::Vector3i g0 = volume.blocks[i].index * kBlockSide;
          for (int z = 0; z < kBlockSide; ++z) {
            for (int y = 0; y < kBlockSide; ++y) {
              for (int x = 0; x < kBlockSide; ++x) {
                const PackedVoxel* v0 = n.voxel(x, y, z);
                if (!observed(v0)) continue;
                for (int axis = 0; axis < 3; ++axis) {
                  const int x1 = x + (axis == 0), y1 = y + (axis == 1), z1 = z + (axis == 2);
                  const PackedVoxel* v1 = n.voxel(x1, y1, z1);
                  if (!observed(v1) || (v0->tsdf_q < 0) == (v1->tsdf_q < 0)) continue;
                  if (out.edge_vertex.empty()) out.edge_vertex.assign(kBlockVoxels * 3, -1);
                  const float t = crossing(v0->tsdf(), v1->tsdf());
                  Eigen::Vector3f p = (g0 + Eigen::Vector3i(x, y, z)).cast<float>();
                  p[axis] += t;
                  out.edge_vertex[static_cast<std::size_t>(localIndex(x, y, z) * 3 + axis)] =
                      static_cast<std::int32_t>(out.positions.size());
                  out.positions.push_back(p * voxel);
                  const auto lerp = [t](std::uint8_t a, std::uint8_t b) {
                    return static_cast<std::uint8_t>(static_cast<float>(a) +
                                                     t * (static_cast<float>(b) - a) + 0.5f);
                  };
                  const VoxelColor& c0 = n.color(x, y, z);
                  const VoxelColor& c1 = n.color(x1, y1, z1);
                  out.colors.push_back(
                      Rgb8(lerp(c0.r, c1.r), lerp(c0.g, c1.g), lerp(c0.b, c1.b)));
                  // Both voxels were observed: the weight is at least 1.
                  const auto w0 = static_cast<float>(v0->weight);
                  const auto w1 = static_cast<float>(v1->weight);
                  out.weights.push_back(w0 + t * (w1 - w0));
                }
              }
            }
          }
        }
        progress.advance(r.size());
      });
  std::vector<std::int32_t> first_vertex(block_count + 1, 0);
  for (std::size_t i = 0; i < block_count; ++i) {
    first_vertex[i + 1] =
        first_vertex[i] + static_cast<std::int32_t>(per_block[i].positions.size());
  }

  // Pass 2: triangles of every cube whose corners were all observed.
  std::vector<std::vector<Eigen::Vector3i>> triangles(block_count);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, block_count),
      [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          const Neighbourhood n = neighbourhood(i);
          for (int z = 0; z < kBlockSide; ++z) {
            for (int y = 0; y < kBlockSide; ++y) {
              for (int x = 0; x < kBlockSide; ++x) {
                int pattern = 0;
                bool complete = true;
                for (int c = 0; c < 8 && complete; ++c) {
                  const PackedVoxel* v =
                      n.voxel(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1));
                  complete = observed(v);
                  if (complete && v->tsdf_q < 0) pattern |= 1 << c;
                }
                if (!complete || pattern == 0 || pattern == 255) continue;
                for (const Triangle& tri : table.triangles[static_cast<std::size_t>(pattern)]) {
                  Eigen::Vector3i ids;
                  for (int k = 0; k < 3; ++k) {
                    const int e = tri[static_cast<std::size_t>(k)];
                    const int c = kEdgeCorners[e][0];
                    const int ox = x + (c & 1), oy = y + ((c >> 1) & 1), oz = z + ((c >> 2) & 1);
                    std::int32_t number = -1;
                    n.voxel(ox, oy, oz, &number);
                    const BlockVertices& owner = per_block[static_cast<std::size_t>(number)];
                    const int axis = e / 4;
                    ids[k] = first_vertex[static_cast<std::size_t>(number)] +
                             owner.edge_vertex[static_cast<std::size_t>(
                                 localIndex(ox & 7, oy & 7, oz & 7) * 3 + axis)];
                  }
                  if (ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2]) {
                    triangles[i].push_back(ids);
                  }
                }
              }
            }
          }
        }
        progress.advance(r.size());
      });

  TriangleMesh mesh;
  mesh.positions.reserve(static_cast<std::size_t>(first_vertex.back()));
  mesh.colors.reserve(mesh.positions.capacity());
  mesh.weights.reserve(mesh.positions.capacity());
  for (const BlockVertices& b : per_block) {
    mesh.positions.insert(mesh.positions.end(), b.positions.begin(), b.positions.end());
    mesh.colors.insert(mesh.colors.end(), b.colors.begin(), b.colors.end());
    mesh.weights.insert(mesh.weights.end(), b.weights.begin(), b.weights.end());
  }
  for (const auto& list : triangles) {
    for (const Eigen::Vector3i& t : list) {
      const Eigen::Vector3f& a = mesh.positions[static_cast<std::size_t>(t[0])];
      const Eigen::Vector3f& b = mesh.positions[static_cast<std::size_t>(t[1])];
      const Eigen::Vector3f& c = mesh.positions[static_cast<std::size_t>(t[2])];
      if ((b - a).cross(c - a).squaredNorm() > 0.0f) mesh.triangles.push_back(t);
    }
  }
  // Vertices no triangle uses (an edge vertex whose cubes all had an unobserved corner) go.
  std::vector<std::int32_t> remap(mesh.positions.size(), -1);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) remap[static_cast<std::size_t>(t[k])] = 0;
  }
  std::int32_t kept = 0;
  for (std::size_t v = 0; v < remap.size(); ++v) {
    if (remap[v] < 0) continue;
    remap[v] = kept;
    mesh.positions[static_cast<std::size_t>(kept)] = mesh.positions[v];
    mesh.colors[static_cast<std::size_t>(kept)] = mesh.colors[v];
    mesh.weights[static_cast<std::size_t>(kept)] = mesh.weights[v];
    ++kept;
  }
  mesh.positions.resize(static_cast<std::size_t>(kept));
  mesh.colors.resize(static_cast<std::size_t>(kept));
  mesh.weights.resize(static_cast<std::size_t>(kept));
  for (Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) t[k] = remap[static_cast<std::size_t>(t[k])];
  }
  if (!volume.has_colors) mesh.colors.clear();
  mesh.computeNormals();
  return mesh;
}

}  // namespace objscan::fusion
