#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace objscan {

using Rgb8 = Eigen::Matrix<std::uint8_t, 3, 1>;

/// An indexed triangle mesh. Positions in metres, in whatever frame the producer states (a fused
/// scene is in the world frame W). `normals`, `colors`, `labels`, `weights` and `ignore` are per
/// vertex and either empty or exactly as long as `positions`. Triangles are counter-clockwise
/// seen from outside (normal side).
struct TriangleMesh {
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> normals;  ///< unit length, or empty
  std::vector<Rgb8> colors;              ///< R, G, B, or empty
  /// Ground-truth object id per vertex (0 = not an object, e.g. the desk), or empty. Stored in
  /// PLY as the vertex property `object_id`.
  std::vector<std::int32_t> labels;
  /// The fusion weight at the vertex: how many observations the TSDF voxels there had (capped by
  /// the volume's max_weight), interpolated along the marching-cubes edge like the colour; or
  /// empty. Finite and >= 0. Stored in PLY as the vertex property `quality`, which MeshLab and
  /// CloudCompare read as a scalar field.
  std::vector<float> weights;
  /// Per vertex, 1 = not scored by evaluation (a hand-labelled mesh's unsure parts), 0 = scored;
  /// or empty. Stored in PLY as the vertex property `ignore` (uchar).
  std::vector<std::uint8_t> ignore;
  std::vector<Eigen::Vector3i> triangles;

  bool empty() const { return positions.empty(); }
  bool hasNormals() const { return !normals.empty(); }
  bool hasColors() const { return !colors.empty(); }
  bool hasLabels() const { return !labels.empty(); }
  bool hasWeights() const { return !weights.empty(); }
  bool hasIgnore() const { return !ignore.empty(); }

  /// Throws std::invalid_argument naming the first problem found: a NaN/infinite position or
  /// normal, a weight that is not a finite number >= 0, normals/colours/labels/weights/ignore
  /// flags whose count differs from the vertex count, a triangle index outside [0, vertex count),
  /// or a degenerate triangle (the same vertex twice).
  void validate() const;

  /// Axis-aligned bounds of the positions; empty box for an empty mesh.
  Eigen::AlignedBox3f bounds() const;

  /// Sets `normals` to the area-weighted mean of the adjacent triangles' normals (unit length;
  /// +z for a vertex no triangle uses).
  void computeNormals();

  /// Sum of triangle areas, m².
  double surfaceArea() const;

  /// The part of the mesh on `vertices` (increasing indices into it): those vertices with their
  /// normals, colours, labels, weights and ignore flags, renumbered in order, and the triangles
  /// whose three vertices are all among them. Throws std::invalid_argument for an index outside
  /// the mesh or out of order. A triangle with an index outside the mesh is in no subset.
  TriangleMesh subset(const std::vector<std::int32_t>& vertices) const;

  friend bool operator==(const TriangleMesh&, const TriangleMesh&) = default;
};

/// Many parts of one mesh (TriangleMesh::subset), each in time proportional to its own size
/// rather than to the whole mesh's: the triangles are indexed by their smallest vertex once.
/// Writing a scene's hundred objects went through the scene's every triangle a hundred times.
/// The mesh must outlive this and not change.
class MeshSubsets {
 public:
  /// Throws std::invalid_argument for a mesh of 2^32 triangles or more.
  explicit MeshSubsets(const TriangleMesh& mesh);
  MeshSubsets(TriangleMesh&&) = delete;  // it keeps a reference to the mesh
  /// The same as mesh.subset(vertices), triangles in the mesh's order. A triangle with an index
  /// outside the mesh is in no subset.
  TriangleMesh subset(const std::vector<std::int32_t>& vertices) const;

 private:
  const TriangleMesh& mesh_;
  std::vector<std::uint32_t> first_;      ///< per vertex, where its triangles begin in by_vertex_
  std::vector<std::uint32_t> by_vertex_;  ///< triangles by their smallest vertex, increasing
};

}  // namespace objscan
