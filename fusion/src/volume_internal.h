#pragma once

// The TSDF volume's storage, shared by integration, raycasting and meshing.

#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <optional>
#include <type_traits>
#include <vector>

#include <tsl/robin_map.h>
#include <Eigen/Core>

#include "grid_math.h"
#include "objscan/fusion/tsdf_volume.h"

namespace objscan::fusion {

/// A voxel as stored: the signed distance in 1/32767ths of the truncation distance and the
/// number of observations (capped at VolumeConfig::max_weight), 4 bytes. Integration, raycasting
/// and meshing read only these; 16 of them share a cache line (a Voxel of floats was 12 bytes, and
/// the raycast's time went mostly to waiting for memory).
struct PackedVoxel {
  std::int16_t tsdf_q = kTsdfScale;
  std::uint16_t weight = 0;

  static constexpr std::int16_t kTsdfScale = 32767;
  static constexpr float kTsdfUnit = 1.0f / static_cast<float>(kTsdfScale);

  float tsdf() const { return static_cast<float>(tsdf_q) * kTsdfUnit; }
  bool observed() const { return weight != 0; }
  /// t in [-1, 1] to the nearest step (a step is 1 um at a 3 cm truncation).
  static std::int16_t quantize(float t) {
    return static_cast<std::int16_t>(t * static_cast<float>(kTsdfScale) + (t < 0.0f ? -0.5f : 0.5f));
  }
};
static_assert(sizeof(PackedVoxel) == 4);

/// A voxel's colour, apart from its distance: only integration near the surface and meshing read
/// it, so the raycast's and the integration's cache lines hold distances only.
struct VoxelColor {
  std::uint8_t r = 0, g = 0, b = 0;
  std::uint8_t weight = 0;  ///< observations within the truncation band, capped at 255
};

struct alignas(64) VoxelBlock {
  std::array<PackedVoxel, kBlockVoxels> voxels{};
  std::array<VoxelColor, kBlockVoxels> colors{};
  Eigen::Vector3i index = Eigen::Vector3i::Zero();  ///< block coordinates (global voxel / 8)

  /// Voxel i (localIndex) as the public type.
  Voxel voxel(std::size_t i) const {
    const PackedVoxel& v = voxels[i];
    const VoxelColor& c = colors[i];
    return Voxel{v.tsdf(), static_cast<float>(v.weight), c.r, c.g, c.b, c.weight};
  }
};

/// Block coordinates pack into 21 bits each (+-2^20 blocks: +-4900 km at 5.9 mm voxels).
inline constexpr int kBlockCoordLimit = 1 << 20;

inline bool blockInRange(const Eigen::Vector3i& b) {
  return (b.array() > -kBlockCoordLimit).all() && (b.array() < kBlockCoordLimit).all();
}

inline std::uint64_t blockKey(const Eigen::Vector3i& b) {
  const auto part = [](int c) {
    return static_cast<std::uint64_t>(c + kBlockCoordLimit) & ((1u << 21) - 1);
  };
  return (part(b.x()) << 42) | (part(b.y()) << 21) | part(b.z());
}

/// The packed key's bits are mostly the low bits of z: mix them before the power-of-two table
/// (the finaliser of MurmurHash3).
struct BlockKeyHash {
  std::size_t operator()(std::uint64_t k) const {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return static_cast<std::size_t>(k);
  }
};

/// Block holding global voxel g (floor division by 8; >> on negative ints is arithmetic in C++20).
inline Eigen::Vector3i blockOf(const Eigen::Vector3i& g) {
  return {g.x() >> 3, g.y() >> 3, g.z() >> 3};
}

inline int localIndex(int x, int y, int z) { return x + kBlockSide * (y + kBlockSide * z); }

inline int localIndex(const Eigen::Vector3i& g) {
  return localIndex(g.x() & 7, g.y() & 7, g.z() & 7);
}

struct TsdfVolume::Impl {
  float voxel_size_m = 0.0f;
  float truncation_m = 0.0f;
  bool has_colors = false;  ///< some integrated frame had colour
  tsl::robin_map<std::uint64_t, std::int32_t, BlockKeyHash> map;
  std::deque<VoxelBlock> blocks;  ///< a deque: blocks never move once allocated
  /// blocks[i].index, contiguous: the raycast projects every block each frame, and reading the
  /// index from each 4 kB block was a cache miss per block.
  std::vector<Eigen::Vector3i> block_indices;

  const VoxelBlock* find(const Eigen::Vector3i& b) const {
    if (!blockInRange(b)) return nullptr;
    const auto it = map.find(blockKey(b));
    return it == map.end() ? nullptr : &blocks[static_cast<std::size_t>(it->second)];
  }
};

// A snapshot of the volume is a copy of its Impl: keep every member a plain copyable value (no
// pointers into the blocks).
static_assert(std::is_copy_constructible_v<TsdfVolume::Impl>);

/// Voxel look-ups along a path (a ray, a block's neighbourhood), remembering the last block.
/// One per thread.
class VoxelReader {
 public:
  explicit VoxelReader(const TsdfVolume::Impl& volume) : volume_(volume) {}

  /// The voxel at global index g, or nullptr when its block is not allocated.
  const PackedVoxel* get(const Eigen::Vector3i& g) {
    const VoxelBlock* b = block(blockOf(g));
    return b ? &b->voxels[static_cast<std::size_t>(localIndex(g))] : nullptr;
  }

  /// The colour of the voxel at global index g, or nullptr when its block is not allocated.
  const VoxelColor* color(const Eigen::Vector3i& g) {
    const VoxelBlock* b = block(blockOf(g));
    return b ? &b->colors[static_cast<std::size_t>(localIndex(g))] : nullptr;
  }

  /// The block with coordinates b, or nullptr. A hash-map look-up costs tens of nanoseconds;
  /// neighbouring rays and cells keep meeting the same few blocks, so the answers (absent blocks
  /// too) are kept in a small direct-mapped cache.
  const VoxelBlock* block(const Eigen::Vector3i& b) {
    const unsigned slot =
        (static_cast<unsigned>(b.x()) * 73856093u ^ static_cast<unsigned>(b.y()) * 19349663u ^
         static_cast<unsigned>(b.z()) * 83492791u) &
        (kCacheSlots - 1);
    Entry& e = cache_[slot];
    if (!e.valid || e.index != b) e = Entry{b, volume_.find(b), true};
    return e.block;
  }

  /// Trilinear interpolation at grid coordinates q (= p / voxel size) of the signed distance in
  /// truncation units, and, when asked, its gradient (per voxel) within the cell; false when one
  /// of the 8 voxels around q was never observed.
  bool sample(const Eigen::Vector3f& q, float* value, Eigen::Vector3f* gradient = nullptr) {
    const int x0 = floorToInt(q.x()), y0 = floorToInt(q.y()), z0 = floorToInt(q.z());
    const float tx = q.x() - static_cast<float>(x0), ty = q.y() - static_cast<float>(y0),
                tz = q.z() - static_cast<float>(z0);
    float c[8];
    if ((x0 & 7) != 7 && (y0 & 7) != 7 && (z0 & 7) != 7) {
      // All 8 voxels in one block (343 of 512 cells): one block look-up.
      const VoxelBlock* b = block(blockOf(Eigen::Vector3i(x0, y0, z0)));
      if (!b) return false;
      const PackedVoxel* v0 =
          &b->voxels[static_cast<std::size_t>(localIndex(x0 & 7, y0 & 7, z0 & 7))];
      for (int i = 0; i < 8; ++i) {
        const PackedVoxel& v =
            v0[(i & 1) + kBlockSide * ((i >> 1) & 1) + kBlockSide * kBlockSide * ((i >> 2) & 1)];
        if (!v.observed()) return false;
        c[i] = v.tsdf();
      }
    } else {
      for (int i = 0; i < 8; ++i) {
        const PackedVoxel* v =
            get(Eigen::Vector3i(x0 + (i & 1), y0 + ((i >> 1) & 1), z0 + ((i >> 2) & 1)));
        if (!v || !v->observed()) return false;
        c[i] = v->tsdf();
      }
    }
    const float x00 = c[0] + tx * (c[1] - c[0]), x10 = c[2] + tx * (c[3] - c[2]);
    const float x01 = c[4] + tx * (c[5] - c[4]), x11 = c[6] + tx * (c[7] - c[6]);
    const float y0v = x00 + ty * (x10 - x00), y1v = x01 + ty * (x11 - x01);
    *value = y0v + tz * (y1v - y0v);
    if (gradient) {
      const float gx0 = (c[1] - c[0]) + ty * ((c[3] - c[2]) - (c[1] - c[0]));
      const float gx1 = (c[5] - c[4]) + ty * ((c[7] - c[6]) - (c[5] - c[4]));
      *gradient = Eigen::Vector3f(gx0 + tz * (gx1 - gx0),
                                  (x10 - x00) + tz * ((x11 - x01) - (x10 - x00)), y1v - y0v);
    }
    return true;
  }

 private:
  static constexpr unsigned kCacheSlots = 64;
  struct Entry {
    Eigen::Vector3i index = Eigen::Vector3i::Zero();
    const VoxelBlock* block = nullptr;
    bool valid = false;
  };
  const TsdfVolume::Impl& volume_;
  std::array<Entry, kCacheSlots> cache_{};
};

}  // namespace objscan::fusion
