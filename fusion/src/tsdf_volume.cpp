#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tsl/robin_set.h>

#include "grid_math.h"
#include "objscan/fusion/tsdf_volume.h"
#include "volume_internal.h"

namespace objscan::fusion {

namespace {

Eigen::Vector3i decodeBlockKey(std::uint64_t key) {
  const auto part = [&](int shift) {
    return static_cast<int>((key >> shift) & ((1u << 21) - 1)) - kBlockCoordLimit;
  };
  return {part(42), part(21), part(0)};
}

void checkImages(const cv::Mat& depth_m, const cv::Mat& color_rgb, const Intrinsics& in) {
  if (depth_m.type() != CV_32FC1) {
    throw std::invalid_argument("integrate: depth must be CV_32FC1 metres");
  }
  if (depth_m.cols != in.width_px || depth_m.rows != in.height_px) {
    throw std::invalid_argument("integrate: the depth image size differs from the intrinsics'");
  }
  if (!color_rgb.empty() && (color_rgb.type() != CV_8UC3 || color_rgb.size() != depth_m.size())) {
    throw std::invalid_argument("integrate: colour must be CV_8UC3 of the depth image's size");
  }
}

}  // namespace

float VolumeConfig::truncation() const {
  return truncation_m.value_or(std::max(0.03f, 3.0f * voxel_size_m));
}

void VolumeConfig::validate() const {
  if (!(std::isfinite(voxel_size_m) && voxel_size_m >= 0.001f && voxel_size_m <= 0.5f)) {
    throw std::invalid_argument("the voxel size must be between 1 mm and 50 cm");
  }
  const float truncation_used = truncation();
  if (!(std::isfinite(truncation_used) && truncation_used >= 2.0f * voxel_size_m &&
        truncation_used <= 1.0f)) {
    throw std::invalid_argument(
        "the truncation distance must span at least 2 voxels and be at most 1 m");
  }
  if (!(std::isfinite(max_weight) && max_weight >= 1.0f)) {
    throw std::invalid_argument("the maximum voxel weight must be at least 1");
  }
  if (allocation_stride_px < 1 || allocation_stride_px > 16) {
    throw std::invalid_argument("the allocation stride must be 1 to 16 pixels");
  }
}

TsdfVolume::TsdfVolume(const VolumeConfig& config) : config_(config), impl_(new Impl) {
  config_.validate();
  impl_->voxel_size_m = config_.voxel_size_m;
  impl_->truncation_m = config_.truncation();
}

TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

std::size_t TsdfVolume::blockCount() const { return impl_->blocks.size(); }

std::size_t TsdfVolume::copyBlocksInto(TsdfVolume& copy, std::size_t first,
                                       std::size_t max_blocks) const {
  if (copy.config_.voxel_size_m != config_.voxel_size_m) {
    throw std::invalid_argument("copyBlocksInto: the volumes' voxel sizes differ");
  }
  Impl& to = *copy.impl_;
  to.has_colors = to.has_colors || impl_->has_colors;
  first = std::min(first, to.blocks.size());  // never leave a gap in the copy's block order
  const std::size_t end = std::min(impl_->blocks.size(), first + max_blocks);
  for (std::size_t i = first; i < end; ++i) {
    const VoxelBlock& block = impl_->blocks[i];
    if (i < to.blocks.size()) {
      to.blocks[i] = block;
      continue;
    }
    // Blocks of the copy are appended in this volume's order, so index i is always the next one.
    to.blocks.push_back(block);
    to.map.emplace(blockKey(block.index), static_cast<std::int32_t>(i));
  }
  return std::max(first, end);
}

std::size_t TsdfVolume::memoryBytes() const {
  return impl_->blocks.size() * sizeof(VoxelBlock) +
         impl_->map.bucket_count() * (sizeof(std::uint64_t) + sizeof(std::int32_t) + 8);
}

std::optional<Voxel> TsdfVolume::voxelAt(const Eigen::Vector3i& g) const {
  const VoxelBlock* block = impl_->find(blockOf(g));
  if (!block) return std::nullopt;
  return block->voxels[static_cast<std::size_t>(localIndex(g))];
}

std::optional<float> TsdfVolume::sdfAt(const Eigen::Vector3f& p_W) const {
  VoxelReader reader(*impl_);
  float t = 0.0f;
  if (!reader.sample(p_W / impl_->voxel_size_m, &t)) return std::nullopt;
  return t * impl_->truncation_m;
}

std::size_t TsdfVolume::integrate(const cv::Mat& depth_m, const cv::Mat& color_rgb,
                                  const Intrinsics& in, const Pose& T_W_C) {
  checkImages(depth_m, color_rgb, in);
  Impl& volume = *impl_;
  const float voxel = volume.voxel_size_m;
  const float block_m = voxel * static_cast<float>(kBlockSide);
  const float trunc = volume.truncation_m;
  const float fx = static_cast<float>(in.fx_px), fy = static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  const Eigen::Matrix3f R_WC = T_W_C.linear();
  const Eigen::Vector3f t_WC = T_W_C.translation();

  // 1. The blocks within the truncation band of the readings, along each reading's ray.
  const int stride = config_.allocation_stride_px;
  using KeySet = tsl::robin_set<std::uint64_t, BlockKeyHash>;
  tbb::enumerable_thread_specific<KeySet> local_keys;
  const int sampled_rows = (depth_m.rows + stride - 1) / stride;
  tbb::parallel_for(
      tbb::blocked_range<int>(0, sampled_rows), [&](const tbb::blocked_range<int>& r) {
        KeySet& keys = local_keys.local();
        for (int row = r.begin(); row != r.end(); ++row) {
          const int v = row * stride;
          const float* d = depth_m.ptr<float>(v);
          for (int u = 0; u < depth_m.cols; u += stride) {
            const float z = d[u];
            if (!(z > 0.0f)) continue;
            const Eigen::Vector3f ray_C((static_cast<float>(u) - cx) / fx,
                                        (static_cast<float>(v) - cy) / fy, 1.0f);
            const Eigen::Vector3f dir_W = R_WC * ray_C;
            const float z0 = std::max(z - trunc, 1e-3f), z1 = z + trunc;
            // Samples half a block apart along the ray cannot step over a block.
            const int n = static_cast<int>(std::ceil((z1 - z0) * ray_C.norm() / (0.5f * block_m)));
            std::uint64_t last = ~0ULL;
            for (int k = 0; k <= n; ++k) {
              const float zk = z0 + (z1 - z0) * static_cast<float>(k) / static_cast<float>(n);
              const Eigen::Vector3f p = t_WC + zk * dir_W;
              const Eigen::Vector3i b(floorToInt(p.x() / block_m), floorToInt(p.y() / block_m),
                                      floorToInt(p.z() / block_m));
              if (!blockInRange(b)) continue;
              const std::uint64_t key = blockKey(b);
              if (key != last) keys.insert(key);
              last = key;
            }
          }
        }
      });
  // Two threads may have seen the same block: merge first, then allocate and collect each once
  // (a deque keeps earlier blocks in place while new ones are appended).
  KeySet merged;
  for (const KeySet& keys : local_keys) merged.insert(keys.begin(), keys.end());
  std::vector<VoxelBlock*> touched;
  touched.reserve(merged.size());
  for (const std::uint64_t key : merged) {
    auto [it, inserted] =
        volume.map.try_emplace(key, static_cast<std::int32_t>(volume.blocks.size()));
    if (inserted) {
      volume.blocks.emplace_back();
      volume.blocks.back().index = decodeBlockKey(key);
    }
    touched.push_back(&volume.blocks[static_cast<std::size_t>(it->second)]);
  }

  // 2. Update every voxel of those blocks that projects onto a reading.
  const Eigen::Matrix3f R_CW = R_WC.transpose();
  const Eigen::Vector3f t_CW = -(R_CW * t_WC);
  const Eigen::Vector3f step_x_C = R_CW.col(0) * voxel;
  const float max_weight = config_.max_weight;
  const float inv_trunc = 1.0f / trunc;
  const bool has_color = !color_rgb.empty();
  volume.has_colors = volume.has_colors || has_color;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, touched.size()),
      [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          VoxelBlock& block = *touched[i];
          const Eigen::Vector3i g0 = block.index * kBlockSide;
          for (int z = 0; z < kBlockSide; ++z) {
            for (int y = 0; y < kBlockSide; ++y) {
              const Eigen::Vector3f p_W = (g0 + Eigen::Vector3i(0, y, z)).cast<float>() * voxel;
              Eigen::Vector3f p_C = R_CW * p_W + t_CW;
              Voxel* row = &block.voxels[static_cast<std::size_t>(localIndex(0, y, z))];
              for (int x = 0; x < kBlockSide; ++x, p_C += step_x_C) {
                if (p_C.z() <= 0.0f) continue;
                const float inv_z = 1.0f / p_C.z();
                const int u = roundToInt(fx * p_C.x() * inv_z + cx);
                const int v = roundToInt(fy * p_C.y() * inv_z + cy);
                if (u < 0 || v < 0 || u >= depth_m.cols || v >= depth_m.rows) continue;
                const float d = depth_m.ptr<float>(v)[u];
                if (!(d > 0.0f)) continue;
                const float sdf = d - p_C.z();
                if (sdf < -trunc) continue;
                Voxel& vox = row[x];
                const float tsdf = std::min(1.0f, sdf * inv_trunc);
                const float w = vox.weight;
                const float w_new = std::min(w + 1.0f, max_weight);
                vox.tsdf = (vox.tsdf * w + tsdf) / (w + 1.0f);
                if (has_color && sdf < trunc) {
                  const auto* c = color_rgb.ptr<std::uint8_t>(v) + 3 * u;
                  const float cw = vox.color_weight;
                  const float inv = 1.0f / (cw + 1.0f);
                  // Rounded by +0.5 and truncation (the value is in [0, 255]): lround is a
                  // library call, three per voxel.
                  const auto blend = [&](std::uint8_t old, std::uint8_t obs) {
                    return static_cast<std::uint8_t>(
                        (static_cast<float>(old) * cw + static_cast<float>(obs)) * inv + 0.5f);
                  };
                  vox.r = blend(vox.r, c[0]);
                  vox.g = blend(vox.g, c[1]);
                  vox.b = blend(vox.b, c[2]);
                  if (vox.color_weight < 255) ++vox.color_weight;
                }
                vox.weight = w_new;
              }
            }
          }
        }
      });
  return touched.size();
}

}  // namespace objscan::fusion
