#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "objscan/core/mesh_decimation.h"
#include "objscan/core/triangle_mesh.h"
#include "objscan/report/results.h"

/// The 3-D view of a scene mesh in a browser, shared by report.html (inlined) and objscan view
/// (served): three.js, objscan's view script, and the binary mesh they read.
namespace objscan::report {

/// three.js r111 and its OrbitControls, from Debian's libjs-three (MIT licence), and objscan's
/// mesh view (report/web/mesh_view.js, which defines `ObjscanMeshView`, preceded by the rank
/// colours of core/palette.h): classic scripts, to be loaded in this order. Compiled into objscan
/// at build time.
std::string_view threeJs();
std::string_view orbitControlsJs();
std::string_view meshViewJs();

/// A scene mesh as the view draws it.
struct ViewMesh {
  /// The mesh, decimated by clustering when it has more triangles than asked for.
  DecimatedMesh preview;
  /// Per preview vertex, the best (lowest) rank of the hypotheses on it; 0 for none.
  std::vector<std::uint16_t> ranks;
};

/// The view of `mesh` with at most `max_triangles` triangles, its vertices marked with the ranks
/// of those of `hypotheses` cut from scene `scene` (HypothesisRecord::scene), through their
/// vertex lists (ranks past 65,535 are not marked). Throws std::invalid_argument when a
/// hypothesis names a vertex outside the mesh.
ViewMesh viewMesh(const TriangleMesh& mesh, const std::vector<HypothesisRecord>& hypotheses,
                  const std::string& scene, std::size_t max_triangles);

/// The binary form mesh_view.js decodes (little-endian; sections 4-byte aligned):
///   "OSVM", uint32 version 1, uint32 vertices n, uint32 triangles t, uint32 flags (1: colours)
///   float32 x, y, z per vertex               (n × 12 bytes)
///   uint8 r, g, b, 255 per vertex            (n × 4 bytes, only with colours)
///   uint16 rank per vertex, 0 for none       (n × 2 bytes, padded to 4)
///   uint32 a, b, c per triangle              (t × 12 bytes)
std::string meshViewPayload(const ViewMesh& view);

/// The overview picture's camera (renders/overview_camera.json) as the view's starting camera, so
/// that the 3-D view opens on what the pictures show: JSON {"position": [x, y, z], "forward":
/// [..], "up": [..], "fov_y_deg": f}, world frame, metres; "null" when it is not finite.
std::string viewCameraJson(const OverviewCamera& camera);

/// The vertices of `vertices` (indices into the full mesh) as vertices of the preview, through
/// its DecimatedMesh::vertex_map: mapped, unused ones dropped, each once, increasing.
/// Out-of-range indices are dropped.
std::vector<std::uint32_t> previewVertices(const std::vector<std::int32_t>& vertex_map,
                                           const std::vector<std::int32_t>& vertices);

}  // namespace objscan::report
