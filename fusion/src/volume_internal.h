#pragma once

// The TSDF volume's storage, shared by integration, raycasting and meshing.

#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <optional>

#include <tsl/robin_map.h>
#include <Eigen/Core>

#include "objscan/fusion/tsdf_volume.h"

namespace objscan::fusion {

struct VoxelBlock {
  std::array<Voxel, kBlockVoxels> voxels{};
  Eigen::Vector3i index = Eigen::Vector3i::Zero();  ///< block coordinates (global voxel / 8)
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

  const VoxelBlock* find(const Eigen::Vector3i& b) const {
    if (!blockInRange(b)) return nullptr;
    const auto it = map.find(blockKey(b));
    return it == map.end() ? nullptr : &blocks[static_cast<std::size_t>(it->second)];
  }
};

/// Voxel look-ups along a path (a ray, a block's neighbourhood), remembering the last block.
/// One per thread.
class VoxelReader {
 public:
  explicit VoxelReader(const TsdfVolume::Impl& volume) : volume_(volume) {}

  /// The voxel at global index g, or nullptr when its block is not allocated.
  const Voxel* get(const Eigen::Vector3i& g) {
    const Eigen::Vector3i b = blockOf(g);
    if (!valid_ || b != cached_index_) {
      cached_ = volume_.find(b);
      cached_index_ = b;
      valid_ = true;
    }
    return cached_ ? &cached_->voxels[static_cast<std::size_t>(localIndex(g))] : nullptr;
  }

  /// Trilinear signed distance in truncation units at grid coordinates q (= p / voxel size);
  /// none when one of the 8 voxels is unobserved.
  std::optional<float> tsdf(const Eigen::Vector3f& q) {
    const Eigen::Vector3f f = q.array().floor();
    const Eigen::Vector3i g0 = f.cast<int>();
    const Eigen::Vector3f t = q - f;
    float corner[8];
    for (int i = 0; i < 8; ++i) {
      const Voxel* v = get(g0 + Eigen::Vector3i(i & 1, (i >> 1) & 1, (i >> 2) & 1));
      if (!v || v->weight <= 0.0f) return std::nullopt;
      corner[i] = v->tsdf;
    }
    const float x00 = corner[0] + t.x() * (corner[1] - corner[0]);
    const float x10 = corner[2] + t.x() * (corner[3] - corner[2]);
    const float x01 = corner[4] + t.x() * (corner[5] - corner[4]);
    const float x11 = corner[6] + t.x() * (corner[7] - corner[6]);
    const float y0 = x00 + t.y() * (x10 - x00);
    const float y1 = x01 + t.y() * (x11 - x01);
    return y0 + t.z() * (y1 - y0);
  }

 private:
  const TsdfVolume::Impl& volume_;
  const VoxelBlock* cached_ = nullptr;
  Eigen::Vector3i cached_index_ = Eigen::Vector3i::Zero();
  bool valid_ = false;
};

}  // namespace objscan::fusion
