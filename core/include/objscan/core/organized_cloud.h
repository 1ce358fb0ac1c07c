#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "objscan/core/intrinsics.h"
#include "objscan/core/rgbd_frame.h"
#include "objscan/core/triangle_mesh.h"

/// A camera's point cloud on its pixel grid (an "organized" cloud, as PCL calls it), the PCD files
/// that store one, and the mesh made by joining neighbouring pixels: how a single view becomes a
/// scene for discovery.
namespace objscan {

/// One point per pixel, row by row, in the camera frame (z forward, metres); a pixel without a
/// reading holds NaN. An unorganized cloud (a PCD with HEIGHT 1 and its NaNs removed) has height 1
/// until placeOnPixelGrid puts it back.
struct OrganizedCloud {
  int width = 0;
  int height = 0;
  std::vector<Eigen::Vector3f> points_C;  ///< width * height
  std::vector<Rgb8> colors;               ///< per pixel, or empty
  /// Per pixel, or empty: the PCD's `label` field as stored (mOSD's convention: 0 no reading,
  /// 1..9 the supporting surfaces, 10 k + p part p of object k).
  std::vector<std::uint32_t> labels;

  bool organized() const { return height > 1; }
  bool valid(std::size_t pixel) const { return std::isfinite(points_C[pixel].z()); }
  std::size_t validCount() const;
};

/// Reads a PCD file (format v0.5 to v0.7: DATA ascii, binary or binary_compressed) with the fields
/// x y z (float or double), optionally rgb or rgba (4 bytes, packed 0x00RRGGBB as PCL writes
/// them) and label (an unsigned or signed integer); other fields are skipped. A point with a
/// non-finite coordinate has no reading. The VIEWPOINT is ignored: the points stay in the frame
/// they are stored in. Throws InputError naming the file for a missing, truncated or corrupt file,
/// a header that does not say what it must, x y z missing, or a label field that is not an integer.
OrganizedCloud readPcd(const std::filesystem::path& path);

/// Writes `cloud` as a binary PCD v0.7 file, as readPcd reads them: fields x y z (float; NaN
/// where a pixel has no reading), then rgb (an unsigned integer, packed 0x00RRGGBB; PCL itself
/// writes the same bits as a float) when the cloud has colours and label (unsigned) when it has
/// labels; WIDTH x HEIGHT as the cloud's. Written to a temporary name and renamed. Throws
/// std::invalid_argument for an empty cloud, one larger than readPcd accepts, or colours or
/// labels that do not match the points; OutputError when the file cannot be written.
void writePcd(const std::filesystem::path& path, const OrganizedCloud& cloud);

/// The points of a depth frame (its intrinsics), with its colours.
OrganizedCloud cloudOfFrame(const RgbdFrame& frame);

/// An unorganized cloud put back on the pixel grid of `intrinsics` (the nearest point of each pixel
/// kept); colours and labels travel with their points. Points that project outside the image or
/// lie behind the camera are dropped. Throws std::invalid_argument for bad intrinsics.
OrganizedCloud placeOnPixelGrid(const OrganizedCloud& cloud, const Intrinsics& intrinsics);

/// The pinhole that projects an unorganized cloud's points onto integer pixels, when it came from
/// a camera's pixel grid (x / z and y / z then take values spaced by 1 / fx and 1 / fy): nothing
/// when the points do not fit one (too few, or not on a grid).
std::optional<Intrinsics> fitPinhole(const OrganizedCloud& cloud);

struct OrganizedMeshConfig {
  /// Two neighbouring pixels are joined unless the surface between them would run more steeply
  /// than this away from the camera: the depth step exceeds tan(angle) times a pixel's footprint
  /// (an occlusion boundary, or a "veil" point between two surfaces). PCL's OrganizedFastMesh
  /// tests the same angle between an edge and the viewing ray.
  float max_view_angle_deg = 80.0f;
  /// ... or the depth noise of a Kinect-like sensor, this many times its quantisation step
  /// (2.85e-3 z^2 m for a disparity of 1/8 pixel), whichever is larger.
  float noise_steps = 3.0f;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// The mesh of an organized cloud: a vertex per pixel with a reading (with its colour, and its
/// label when the cloud has labels, as TriangleMesh::labels hold it: see objectIdsOfLabels), each
/// 2 x 2 block of pixels split into two triangles along its shorter diagonal, a triangle kept when
/// its three edges join (OrganizedMeshConfig); normals from the triangles, facing the camera.
/// `pixel_of_vertex`, when given, receives each vertex's pixel index. Throws std::invalid_argument
/// for a cloud that is not organized or a bad config.
TriangleMesh meshOrganized(const OrganizedCloud& cloud, const OrganizedMeshConfig& config = {},
                           std::vector<std::int32_t>* pixel_of_vertex = nullptr);

/// Ground-truth object ids of stored labels, mOSD's convention: 0 (no reading) and 1..9 (supports)
/// are not objects (0); with `merge_parts`, 10 k + p is object k, else each part is an object of
/// its own (id 10 k + p).
std::int32_t objectIdOfLabel(std::uint32_t label, bool merge_parts = false);

}  // namespace objscan
