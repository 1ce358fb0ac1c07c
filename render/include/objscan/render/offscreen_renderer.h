#pragma once

#include <memory>
#include <opencv2/core/mat.hpp>

#include "objscan/core/intrinsics.h"
#include "objscan/core/pose.h"
#include "objscan/core/triangle_mesh.h"

namespace objscan::render {

/// What a pinhole camera sees of a mesh, pixel by pixel, without any sensor effects.
struct RenderedView {
  cv::Mat depth_m;    ///< CV_32FC1: z of the visible surface in the camera frame; 0 = nothing hit
  cv::Mat color_rgb;  ///< CV_8UC3: vertex colour, Lambert-shaded by a light at the camera
  cv::Mat label;      ///< CV_32SC1: the surface's TriangleMesh::labels value (0 if none/no hit)
  /// CV_32FC1: |cos| of the angle between the surface normal and the viewing ray (1 = facing
  /// the camera, 0 = grazing or nothing hit), from the exact geometric normal.
  cv::Mat cos_incidence;
};

/// Off-screen OpenGL rendering through OSMesa (Mesa's llvmpipe on the CPU: no display, no GPU).
///
/// Depth is exact up to float rounding: the camera-frame z is interpolated perspective-correctly
/// across each (planar) triangle, not read back from the non-linear depth buffer. Pixel (u, v)
/// samples the ray through u = fx x/z + cx, v = fy y/z + cy at integer u, v, the convention of
/// objscan::Intrinsics. Not thread-safe: one renderer per thread (OSMesa contexts are bound to
/// the thread that made them current); several renderers may exist at once.
class OffscreenRenderer {
 public:
  /// near_m/far_m clip the view. Throws std::runtime_error if OSMesa cannot create an OpenGL 3.3
  /// core context; std::invalid_argument for bad intrinsics or clip planes.
  explicit OffscreenRenderer(const Intrinsics& intrinsics, float near_m = 0.1f,
                             float far_m = 20.0f);
  ~OffscreenRenderer();
  OffscreenRenderer(const OffscreenRenderer&) = delete;
  OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

  /// Uploads the scene (world frame W) once; later render() calls reuse it. Vertices without
  /// colours are drawn light grey, without labels as 0. Throws std::invalid_argument if
  /// mesh.validate() fails.
  void setMesh(const TriangleMesh& mesh_W);

  /// Renders the uploaded mesh from the camera pose T_W_C (camera frame: x right, y down,
  /// z forward).
  RenderedView render(const Pose& T_W_C);

  const Intrinsics& intrinsics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace objscan::render
