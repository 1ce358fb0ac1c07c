#include <algorithm>
#include <cmath>
#include <cstring>
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

using F4 = float __attribute__((vector_size(16)));
using I4 = std::int32_t __attribute__((vector_size(16)));

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
  // Integration numbers pixels in float, exact below 2^24.
  if (static_cast<double>(depth_m.cols) * depth_m.rows >= 16777216.0) {
    throw std::invalid_argument("integrate: images of 2^24 pixels or more are not supported");
  }
  if (!color_rgb.empty() && (color_rgb.type() != CV_8UC3 || color_rgb.size() != depth_m.size())) {
    throw std::invalid_argument("integrate: colour must be CV_8UC3 of the depth image's size");
  }
}

/// Three standard deviations of a structured-light sensor's depth noise over z^2, per metre
/// (Khoshelham and Elberink 2012: sigma = 1.425e-3 z^2 m for the Kinect v1).
constexpr float kNoiseSigmasPerM2 = 3.0f * 1.425e-3f;

/// The noise's band behind a reading at depth `d`: its three sigmas, at least `min_band`.
inline float noiseBand(float d, float min_band) {
  return std::max(min_band, kNoiseSigmasPerM2 * d * d);
}

}  // namespace

float VolumeConfig::truncation() const {
  return truncation_m.value_or(std::max(0.03f, 3.0f * voxel_size_m));
}

float VolumeConfig::behindBand(float depth_m) const {
  if (behind_m) return *behind_m;
  if (behind_follows_noise) return std::min(noiseBand(depth_m, 2.0f * voxel_size_m), truncation());
  return truncation();
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
  if (behind_m && !(std::isfinite(*behind_m) && *behind_m >= 2.0f * voxel_size_m &&
                    *behind_m <= truncation_used)) {
    throw std::invalid_argument(
        "the band behind a reading must span at least 2 voxels and at most the truncation");
  }
  if (!(std::isfinite(max_weight) && max_weight >= 1.0f && max_weight <= 65535.0f)) {
    throw std::invalid_argument("the maximum voxel weight must be 1 to 65535 observations");
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
    to.block_indices.push_back(block.index);
    to.map.emplace(blockKey(block.index), static_cast<std::int32_t>(i));
  }
  return std::max(first, end);
}

std::size_t TsdfVolume::memoryBytes() const {
  return impl_->blocks.size() * (sizeof(VoxelBlock) + sizeof(Eigen::Vector3i)) +
         impl_->map.bucket_count() * (sizeof(std::uint64_t) + sizeof(std::int32_t) + 8);
}

std::optional<Voxel> TsdfVolume::voxelAt(const Eigen::Vector3i& g) const {
  const VoxelBlock* block = impl_->find(blockOf(g));
  if (!block) return std::nullopt;
  return block->voxel(static_cast<std::size_t>(localIndex(g)));
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
  // How deep behind each reading to update (at most trunc): fixed, or per reading's depth.
  const bool behind_varies = !config_.behind_m && config_.behind_follows_noise;
  const float behind = config_.behindBand(0.0f);
  const float min_behind = 2.0f * voxel;
  const bool carve = config_.carve_free_space;
  const float min_behind_t = min_behind * (1.0f / trunc);
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
            const float z0 = std::max(z - trunc, 1e-3f),
                        z1 = z + (behind_varies ? config_.behindBand(z) : behind);
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
  // (a deque keeps earlier blocks in place while new ones are appended). New blocks are appended
  // in key order, not in the order the threads happened to find them: the block order is the
  // order of the extracted mesh's vertices, which must not depend on the thread schedule.
  KeySet merged;
  for (const KeySet& keys : local_keys) merged.insert(keys.begin(), keys.end());
  std::vector<std::uint64_t> sorted_keys(merged.begin(), merged.end());
  std::sort(sorted_keys.begin(), sorted_keys.end());
  std::vector<VoxelBlock*> touched;
  touched.reserve(sorted_keys.size());
  for (const std::uint64_t key : sorted_keys) {
    auto [it, inserted] =
        volume.map.try_emplace(key, static_cast<std::int32_t>(volume.blocks.size()));
    if (inserted) {
      volume.blocks.emplace_back();
      volume.blocks.back().index = decodeBlockKey(key);
      volume.block_indices.push_back(volume.blocks.back().index);
    }
    touched.push_back(&volume.blocks[static_cast<std::size_t>(it->second)]);
  }

  // 2. Update every voxel of those blocks that projects onto a reading.
  const Eigen::Matrix3f R_CW = R_WC.transpose();
  const Eigen::Vector3f t_CW = -(R_CW * t_WC);
  const Eigen::Vector3f step_x_C = R_CW.col(0) * voxel;
  const auto max_weight = static_cast<std::uint16_t>(config_.max_weight);
  // 1 / (w + 1) for every weight a voxel or its colour can hold: a division per voxel was a
  // tenth of the time.
  // The colour's weight goes to 255.
  std::vector<float> inv_count(std::max<std::size_t>(max_weight, 255) + 1);
  for (std::size_t w = 0; w < inv_count.size(); ++w) {
    inv_count[w] = 1.0f / static_cast<float>(w + 1);
  }
  const float inv_trunc = 1.0f / trunc;
  const bool has_color = !color_rgb.empty();
  volume.has_colors = volume.has_colors || has_color;
  const int cols = depth_m.cols, rows = depth_m.rows;
  // The pixel's centre is at integer coordinates; +0.5 makes truncation round to the nearest.
  const float u_max = static_cast<float>(cols), v_max = static_cast<float>(rows);
  const float cu = cx + 0.5f, cv = cy + 0.5f;
  // Continuous copies, so that a pixel is one number (cv::Mat rows may be padded).
  const cv::Mat depth_flat = depth_m.isContinuous() ? depth_m : depth_m.clone();
  const cv::Mat color_flat =
      color_rgb.empty() || color_rgb.isContinuous() ? color_rgb : color_rgb.clone();
  const float* depth_data = depth_flat.ptr<float>(0);
  const std::uint8_t* color_data = has_color ? color_flat.ptr<std::uint8_t>(0) : nullptr;
  const auto row_px = static_cast<float>(cols);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, touched.size(), 16),
      [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          VoxelBlock& block = *touched[i];
          const Eigen::Vector3i g0 = block.index * kBlockSide;
          for (int z = 0; z < kBlockSide; ++z) {
            for (int y = 0; y < kBlockSide; ++y) {
              const Eigen::Vector3f p_W = (g0 + Eigen::Vector3i(0, y, z)).cast<float>() * voxel;
              const Eigen::Vector3f p0_C = R_CW * p_W + t_CW;
              // The row's 8 projections, 4 at a time (GCC/Clang vector types: SSE2 on x86-64,
              // NEON on ARM). One voxel after another, with a division and branches each, they
              // were half the integration's time.
              alignas(16) float depth_C[kBlockSide], pixel[kBlockSide];
              for (int half = 0; half < kBlockSide; half += 4) {
                const F4 xf = F4{0.0f, 1.0f, 2.0f, 3.0f} + static_cast<float>(half);
                const F4 pz = p0_C.z() + xf * step_x_C.z();
                const F4 inv_z = 1.0f / pz;
                const F4 fu = fx * (p0_C.x() + xf * step_x_C.x()) * inv_z + cu;
                const F4 fv = fy * (p0_C.y() + xf * step_x_C.y()) * inv_z + cv;
                // NaN and anything off the image fail here; in range, truncation is floor.
                const I4 inside = (pz > 0.0f) & (fu >= 0.0f) & (fu < u_max) & (fv >= 0.0f) &
                                  (fv < v_max);
                const F4 zero = F4{} + 0.0f;
                const F4 iu = __builtin_convertvector(
                    __builtin_convertvector(inside ? fu : zero, I4), F4);
                const F4 iv = __builtin_convertvector(
                    __builtin_convertvector(inside ? fv : zero, I4), F4);
                // Row-major pixel number, exact in float below 2^24 pixels; -1 when outside.
                const F4 px = inside ? iv * row_px + iu : zero - 1.0f;
                std::memcpy(pixel + half, &px, sizeof px);
                std::memcpy(depth_C + half, &pz, sizeof pz);
              }
              const std::size_t row = static_cast<std::size_t>(localIndex(0, y, z));
              for (int x = 0; x < kBlockSide; ++x) {
                if (pixel[x] < 0.0f) continue;
                const auto px = static_cast<std::size_t>(pixel[x]);
                const float d = depth_data[px];
                if (!(d > 0.0f)) continue;
                const float sdf = d - depth_C[x];
                if (sdf < -(behind_varies ? config_.behindBand(d) : behind)) continue;
                PackedVoxel& vox = block.voxels[row + x];
                const float tsdf = std::min(1.0f, sdf * inv_trunc);
                std::uint16_t w = vox.weight;
                const float current = vox.tsdf();
                // (Both cases need the reading and the voxel on either side, each beyond the band
                // of at least 2 voxels: most updates differ from the voxel by less.)
                if (carve && w != 0 && std::abs(tsdf - current) > 2.0f * min_behind_t) {
                  // Free space seen beats solid inferred from deep behind another surface: a
                  // reading beyond the noise's band behind its surface does not move a voxel
                  // that averages more than the band in front of one, and one more than the band
                  // in front of its surface replaces a voxel that averages more than the band
                  // behind one (VolumeConfig::carve_free_space). A band past the truncation, 1 in
                  // these units, never holds: no clamp needed.
                  const float noise = noiseBand(d, min_behind) * inv_trunc;
                  if (tsdf < -noise && current > noise) continue;
                  if (tsdf > noise && current < -noise) w = 0;
                }
                vox.tsdf_q =
                    PackedVoxel::quantize((current * static_cast<float>(w) + tsdf) * inv_count[w]);
                vox.weight = static_cast<std::uint16_t>(std::min<int>(w + 1, max_weight));
                if (has_color && sdf < trunc) {
                  VoxelColor& col = block.colors[row + x];
                  const std::uint8_t* c = color_data + 3 * px;
                  const float cw = col.weight;
                  const float inv = inv_count[col.weight];
                  // Rounded by +0.5 and truncation (the value is in [0, 255]): lround is a
                  // library call, three per voxel.
                  const auto blend = [&](std::uint8_t old, std::uint8_t obs) {
                    return static_cast<std::uint8_t>(
                        (static_cast<float>(old) * cw + static_cast<float>(obs)) * inv + 0.5f);
                  };
                  col.r = blend(col.r, c[0]);
                  col.g = blend(col.g, c[1]);
                  col.b = blend(col.b, c[2]);
                  if (col.weight < 255) ++col.weight;
                }
              }
            }
          }
        }
      });
  return touched.size();
}

}  // namespace objscan::fusion
