#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/mesh_graph.h"

/// Support surfaces: an objscan extension of the paper's segmentation, on by default (off with
/// `--paper-segmentation`).
///
/// On fused meshes, Eq. 1 alone often joins an object to the table it stands on: TSDF fusion
/// rounds the fold where they meet into several edges of moderate weight, while FH's threshold
/// for a large, slightly noisy table grows with its internal difference. On the 30 synthetic test
/// scenes, 47 of the 85 objects missed at IoU 0.7 had their best segment, at every scale, be the
/// support with the object attached. So the large planes of the scene (tables, shelf boards,
/// walls, the floor) are found first, and every mesh edge between a vertex on such a plane and
/// one off it is cut: segmentation never crosses it.
namespace objscan::discovery {

struct SupportConfig {
  bool enabled = true;
  /// A vertex lies on a support within this distance of its plane, then of its own surface
  /// (SupportPlane::surface): about two voxels of KinFu's 3 m / 512 volume, as fused surfaces
  /// are that noisy. Lower, and a table's noise is cut from it.
  float distance_m = 0.01f;
  /// ... with its normal (SupportConfig::max_angle_deg) averaged with its neighbours' over this
  /// many rings of mesh edges first. 0 on fused meshes, whose normals come from the TSDF's
  /// gradient over several voxels; single views (DiscoveredScene's configOf) take
  /// single_view_normal_rings: a pixel's own normal there scatters by tens of degrees (at 0.6 m a
  /// table's vertex normals lay a median 35 degrees from its plane in a synthetic view), so a far
  /// or tilted table broke into pieces too small to be a support and stayed in the scene as a huge
  /// flat "object". 2 was chosen on synthetic views (docs/discovery.md, "Single views of
  /// clutter").
  int normal_rings = 0;
  int single_view_normal_rings = 2;
  /// ... and with its normal within this angle of the plane's: the rounded fold at an object's
  /// foot then goes with the object, not with the support.
  float max_angle_deg = 25.0f;
  /// A support is a connected region of plane vertices with at least this many vertices at the
  /// paper's density (scaled as min_size is): 3000 vertices are about 0.09 m^2, larger than the
  /// top of any object the paper's scenes hold (a keyboard's is about 0.07 m^2).
  std::size_t min_vertices = 3000;
  /// Segmentation merges a segment smaller than m_size into a neighbour, but never across a cut:
  /// an object that the cuts leave on its own stays a segment, however small. It is a candidate
  /// from this many vertices at the paper's density (scaled as min_size is): about 2 cm^2 of
  /// surface, what a camera sees of a 1.6 cm marble or dice (chosen on the hard synthetic tuning
  /// views, docs/discovery.md "Small objects' floor"; 20, the former value, about 7 cm^2, left
  /// out objects under 3 cm, and 100 before it missed occluded parts of 130 to 600 vertices on
  /// mosd_learn). Without supports, m_size is the only floor.
  std::size_t min_cut_off_size = 6;
  /// Planes looked for, largest first: a room's floor and walls, a table, and a shelf's boards
  /// and sides (6, the former value, left the lowest board of a three-board shelf unfound).
  int max_planes = 10;
  /// Small candidates standing on a support are offered twice: as segmented, and without their
  /// foot (their vertices within `foot_fold_m` of a support's surface whose normals lie within
  /// `foot_fold_deg` of its), when that removes at least a tenth of them. Fusion rounds the fold
  /// where a small object meets its table into a band of 2-12 mm whose normals lean about 34
  /// degrees from up, which the support (25 degrees) leaves to the object: a dice of 68 fused
  /// vertices came with 31 of the table. Only for candidates of at most `foot_trim_vertices` at
  /// the paper's density (scaled as min_size): a large object's bottom ring is its own. Off for
  /// single views (SceneInput::single_view), which fusion did not round. Chosen on hard
  /// synthetic seeds 3101-3106 (docs/discovery.md, "Small objects' feet").
  bool trim_feet = true;
  float foot_fold_m = 0.008f;
  float foot_fold_deg = 50.0f;
  std::size_t foot_trim_vertices = 250;
  /// Things standing on level tops that are no supports (a box's lid, a book: too small to be
  /// support planes), offered as candidates of their own: on fused meshes with the camera's up,
  /// the level tops (connected vertices off the supports whose normals lie within top_level_deg
  /// of up, at least top_min_vertices at the paper's density, their heights within
  /// top_flatness_m RMS) are cut from the rest, the mesh is segmented again at every scale, and
  /// the segments that touch a top and lie over it join the candidates. Segmentation otherwise
  /// joins a marble on a box to the box: it is smaller than m_size. Chosen on hard synthetic
  /// seeds (docs/discovery.md, "Things on level tops").
  bool level_tops = true;
  float top_level_deg = 15.0f;
  std::size_t top_min_vertices = 30;
  float top_flatness_m = 0.003f;
  /// Plane hypotheses tried per plane, one vertex and its normal each: a plane holding 2 % of
  /// the vertices left is missed with probability 0.98^300 < 0.3 %.
  int ransac_iterations = 300;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// A support's own vertices, for which way it faces (SupportPlane::up_sign) and for what lies on
/// it: those on a support within this distance of its surface, twice the supports' band
/// (SupportConfig::distance_m).
inline constexpr float kOwnSurfaceM = 0.02f;

struct SupportPlane {
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();  ///< unit length
  float offset = 0.0f;                                ///< normal . p + offset = 0 on the plane
  std::size_t vertex_count = 0;                       ///< vertices of its support regions
  /// +1 when the free side, where the things standing on the support are, lies along `normal`,
  /// -1 when it lies the other way: the side its own vertices' normals face (fused and
  /// single-view normals point out of the surface, towards where the camera was).
  float up_sign = 1.0f;

  /// The support's own surface: its height over the plane, a quadratic in the coordinates along
  /// `axis_u` and `axis_v` less `centre_u` and `centre_v` (coefficients of 1, u, v, u^2, uv, v^2),
  /// fitted to the support's vertices. A fused table is not flat: the sensor's fixed depth error
  /// bends it by several millimetres (real fusions lie 3-7 mm off their fitted plane), which is
  /// most of the supports' 1 cm band, and a far floor or wall by centimetres. Beyond the box
  /// (along u and v) of the vertices it was fitted to, it goes on along its tangent at the box's
  /// edge (a quadratic would climb ever faster). Not `curved` (the plane itself) when the
  /// support spreads less than 5 cm (standard deviation) across its narrowest direction, which
  /// fixes no bend.
  Eigen::Vector3f axis_u = Eigen::Vector3f::UnitX();
  Eigen::Vector3f axis_v = Eigen::Vector3f::UnitY();
  float centre_u = 0.0f, centre_v = 0.0f;
  /// The least and greatest u and v, less the centre, of the vertices it was fitted to.
  Eigen::Vector2f reach_u = Eigen::Vector2f::Zero(), reach_v = Eigen::Vector2f::Zero();
  Eigen::Matrix<float, 6, 1> surface = Eigen::Matrix<float, 6, 1>::Zero();
  bool curved = false;

  /// The height of `p` over the plane: normal . p + offset.
  float planeHeight(const Eigen::Vector3f& p) const { return normal.dot(p) + offset; }
  /// The height of `p` over the support's own surface (over the plane when not `curved`).
  float height(const Eigen::Vector3f& p) const;
  /// The normal turned to the free side (`up_sign`).
  Eigen::Vector3f up() const { return up_sign * normal; }
};

struct Supports {
  std::vector<SupportPlane> planes;
  /// Per mesh vertex: 1 when it belongs to a support region or to a fold.
  std::vector<std::uint8_t> on_support;
  /// Vertices within the distance of two or more supports (each's plane or surface) whatever
  /// their normals: the rounded fold where a shelf board meets its wall. Supports too; not in
  /// any plane's count.
  std::size_t fold_vertices = 0;
};

/// The support regions of `mesh`, whose graph is `graph`: planes found by RANSAC on at most
/// 5,000 of the vertices not yet on a plane (each hypothesis one vertex with its normal, seeded so
/// that a mesh always gives the same planes; then refitted to its inliers by least squares,
/// PCL's), largest first; on each, the vertices
/// within `distance_m` whose normals agree, grouped into connected regions over the mesh's edges;
/// the regions of at least `min_vertices` (already scaled to the mesh's density) are supports.
/// Their own surface is then fitted (SupportPlane::surface) and the same is done again against
/// it. Then the vertices near two supports (folds) join them, and each support's free side is
/// found (SupportPlane::up_sign).
/// `mesh` must have normals (std::invalid_argument otherwise).
Supports findSupports(const TriangleMesh& mesh, const MeshGraph& graph, const SupportConfig& config,
                      std::size_t min_vertices);

/// Gives every edge between a support vertex and another an infinite weight, which segmentation
/// never crosses (segmentGraph). Returns how many edges were cut. Throws std::invalid_argument
/// when `on_support` does not have one entry per vertex of the graph.
std::size_t cutAtSupports(MeshGraph& graph, const std::vector<std::uint8_t>& on_support);

}  // namespace objscan::discovery
