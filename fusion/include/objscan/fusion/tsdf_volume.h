#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "objscan/core/intrinsics.h"
#include "objscan/core/pose.h"

/// A sparse truncated signed distance volume (Curless and Levoy 1996, as KinectFusion uses it):
/// voxels in blocks of 8x8x8, found through a hash map of block coordinates and allocated only
/// within the truncation band of observed surfaces, so memory grows with the surface seen, not
/// with the bounding box (the voxel hashing of Niessner et al. 2013).
namespace objscan::fusion {

struct VolumeConfig {
  /// Edge of a voxel. The paper's meshes came from KinectFusion's 3 m / 512 voxels; the same
  /// density keeps its size constants (m_size = 500 vertices) meaningful.
  float voxel_size_m = 3.0f / 512.0f;
  /// Signed distances are truncated to +-this; it must span at least 2 voxels. Nothing: 3 cm
  /// (KinectFusion's default; three standard deviations of a Kinect-type sensor's depth noise at
  /// 2.65 m), or 3 voxels when that is more. truncation() gives the value used.
  std::optional<float> truncation_m;
  /// How far behind a reading the volume is updated (its negative side), metres: 2 voxels to the
  /// truncation distance. Nothing: as deep as the truncation, as KinectFusion does.
  std::optional<float> behind_m;
  /// Without behind_m: update behind a reading as deep as three standard deviations of a
  /// structured-light sensor's depth noise at its depth (1.425e-3 z^2 m, the Kinect v1's,
  /// Khoshelham and Elberink 2012), at least 2 voxels and at most the truncation.
  bool behind_follows_noise = false;
  /// Free space seen beats solid inferred (the default). A reading marks the voxels down to the
  /// truncation distance behind its surface as solid; beyond the noise's band (three sigmas as
  /// above, at least 2 voxels) that is a guess. With this on, such a reading does not move a
  /// voxel that averages more than the band in front of a surface, and a reading that sees a voxel
  /// more than the band in front of its surface replaces a voxel that averages more than the band
  /// behind one (its weight starts again). The hollow of a bowl or a cup seen from outside and
  /// from above then stays hollow instead of holding a ghost wall, and a small object grows no
  /// tail of solid behind it; but a pixel beside a silhouette, or a frame tracked more than the
  /// band off, can carve into a surface the other frames saw. Off, the volume averages every
  /// reading as KinectFusion does. Where the band reaches the truncation (readings beyond 2.65 m
  /// at 3 cm) it never acts. docs/fusion.md, "Thin walls".
  bool carve_free_space = true;
  /// A voxel's weight (its number of observations) stops growing here, so the running average
  /// keeps adapting (KinectFusion caps it at 128 frames). 1 to 65535; a fraction is dropped.
  float max_weight = 128.0f;
  /// Block allocation looks at every n-th pixel in both directions: at 3 m a pixel covers 5 mm, so
  /// 4 pixels stay well under a block's 4.7 cm and no block in the band is missed.
  int allocation_stride_px = 4;
  /// The truncation distance used: truncation_m, or its default for this voxel size.
  float truncation() const;
  /// The depth of the band behind a reading at `depth_m` that is updated.
  float behindBand(float depth_m) const;
  /// Throws std::invalid_argument with a sentence naming the bad field.
  void validate() const;
};

/// One voxel as voxelAt returns it: truncated signed distance in units of the truncation distance
/// (-1 .. 1, positive in front of the surface; stored to 1/32767), its weight (observations, 0 =
/// never observed), and a colour averaged over the observations within the truncation band
/// (color_weight of them, capped at 255). The volume stores the distance and weight in 4 bytes
/// and the colour apart (fusion/src/volume_internal.h).
struct Voxel {
  float tsdf = 1.0f;
  float weight = 0.0f;
  std::uint8_t r = 0, g = 0, b = 0;
  std::uint8_t color_weight = 0;
};

/// Voxels along a block's edge.
inline constexpr int kBlockSide = 8;
inline constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;

/// The volume. Voxel (i, j, k) of the global grid sits at (i, j, k) * voxel_size_m in the world
/// frame W. Not thread-safe for writing; const methods may run concurrently.
class TsdfVolume {
 public:
  explicit TsdfVolume(const VolumeConfig& config);
  ~TsdfVolume();
  TsdfVolume(TsdfVolume&&) noexcept;
  TsdfVolume& operator=(TsdfVolume&&) noexcept;

  /// Integrates a depth image (CV_32FC1 metres, 0 = no reading; clip it first) with its colour
  /// (CV_8UC3 RGB of the same size, or empty) seen from T_W_C: allocates the blocks within the
  /// truncation band of the readings, then updates every voxel of those blocks that projects onto
  /// a reading and lies no deeper than the truncation behind it. The signed distance is measured
  /// along the optical axis (reading minus voxel depth), as KinectFusion does. Returns the number
  /// of blocks updated.
  std::size_t integrate(const cv::Mat& depth_m, const cv::Mat& color_rgb,
                        const Intrinsics& intrinsics, const Pose& T_W_C);

  /// Signed distance in metres at p_W by trilinear interpolation of the 8 voxels around it; none
  /// when one of them was never observed.
  std::optional<float> sdfAt(const Eigen::Vector3f& p_W) const;

  /// The voxel at global grid index g, or none when its block is not allocated.
  std::optional<Voxel> voxelAt(const Eigen::Vector3i& g) const;

  /// Copies blocks [first, first + max_blocks) of this volume into `copy`, a volume of the same
  /// config that only this function fills from this volume (blocks keep their positions, so
  /// blocks copied earlier are overwritten with their current contents); returns the index after
  /// the last block copied, blockCount() when done. A live preview copies a few blocks per frame
  /// instead of the whole volume at once, so that no frame waits for a large copy; the copy then
  /// mixes blocks of a few consecutive frames, which a preview can take. Throws
  /// std::invalid_argument when the voxel sizes differ.
  std::size_t copyBlocksInto(TsdfVolume& copy, std::size_t first, std::size_t max_blocks) const;

  std::size_t blockCount() const;
  /// Bytes held by the blocks and the hash map.
  std::size_t memoryBytes() const;
  const VolumeConfig& config() const { return config_; }

  struct Impl;  ///< defined in fusion/src/volume_internal.h, for raycasting and meshing
  const Impl& impl() const { return *impl_; }

 private:
  VolumeConfig config_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace objscan::fusion
