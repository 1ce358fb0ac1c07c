#include "objscan/fusion/raycast.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "objscan/fusion/preprocess.h"
#include "volume_internal.h"

namespace objscan::fusion {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr int kTilePx = 8;

/// Per tile of kTilePx x kTilePx pixels, the depth range of the allocated blocks that project
/// onto it (min > max: none).
struct RangeImage {
  int tiles_x = 0, tiles_y = 0;
  std::vector<float> near, far;

  RangeImage(int width, int height)
      : tiles_x((width + kTilePx - 1) / kTilePx),
        tiles_y((height + kTilePx - 1) / kTilePx),
        near(static_cast<std::size_t>(tiles_x) * tiles_y, std::numeric_limits<float>::infinity()),
        far(near.size(), -std::numeric_limits<float>::infinity()) {}

  void merge(const RangeImage& o) {
    for (std::size_t i = 0; i < near.size(); ++i) {
      near[i] = std::min(near[i], o.near[i]);
      far[i] = std::max(far[i], o.far[i]);
    }
  }
};

RangeImage projectBlocks(const TsdfVolume::Impl& volume, const Intrinsics& in, const Pose& T_W_C,
                         float min_depth_m, float max_depth_m) {
  const Eigen::Matrix3f R_CW = T_W_C.linear().transpose();
  const Eigen::Vector3f t_CW = -(R_CW * T_W_C.translation());
  const float block_m = volume.voxel_size_m * kBlockSide;
  const float fx = static_cast<float>(in.fx_px), fy = static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  tbb::combinable<RangeImage> partial([&] { return RangeImage(in.width_px, in.height_px); });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, volume.blocks.size(), 256),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      RangeImage& range = partial.local();
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        // The block's extent: its voxels plus the one-voxel margin trilinear
                        // interpolation reads.
                        const Eigen::Vector3f lo = volume.blocks[i].index.cast<float>() * block_m;
                        float z_lo = std::numeric_limits<float>::infinity(), z_hi = -z_lo;
                        float u_lo = z_lo, u_hi = z_hi, v_lo = z_lo, v_hi = z_hi;
                        bool behind = false;
                        for (int c = 0; c < 8; ++c) {
                          const Eigen::Vector3f corner =
                              lo + Eigen::Vector3f(c & 1, (c >> 1) & 1, (c >> 2) & 1) * block_m;
                          const Eigen::Vector3f p = R_CW * corner + t_CW;
                          z_lo = std::min(z_lo, p.z());
                          z_hi = std::max(z_hi, p.z());
                          if (p.z() <= 1e-3f) {
                            behind = true;
                            continue;
                          }
                          const float u = fx * p.x() / p.z() + cx, v = fy * p.y() / p.z() + cy;
                          u_lo = std::min(u_lo, u);
                          u_hi = std::max(u_hi, u);
                          v_lo = std::min(v_lo, v);
                          v_hi = std::max(v_hi, v);
                        }
                        if (z_hi < min_depth_m || z_lo > max_depth_m) continue;
                        if (behind) {  // a block around the camera's plane: it may cover any pixel
                          u_lo = v_lo = 0.0f;
                          u_hi = static_cast<float>(in.width_px - 1);
                          v_hi = static_cast<float>(in.height_px - 1);
                        }
                        if (u_hi < 0.0f || v_hi < 0.0f) continue;
                        // Clamped before the conversion to int: a block just in front of the camera
                        // projects far out.
                        const auto tileOf = [](float px) {
                          return static_cast<int>(std::clamp(px, 0.0f, 1e6f)) / kTilePx;
                        };
                        const int tx0 = tileOf(u_lo), ty0 = tileOf(v_lo);
                        const int tx1 = std::min(range.tiles_x - 1, tileOf(u_hi));
                        const int ty1 = std::min(range.tiles_y - 1, tileOf(v_hi));
                        const float z_near = std::max(z_lo, min_depth_m),
                                    z_far = std::min(z_hi, max_depth_m);
                        for (int ty = ty0; ty <= ty1; ++ty) {
                          for (int tx = tx0; tx <= tx1; ++tx) {
                            const std::size_t t = static_cast<std::size_t>(ty) * range.tiles_x + tx;
                            range.near[t] = std::min(range.near[t], z_near);
                            range.far[t] = std::max(range.far[t], z_far);
                          }
                        }
                      }
                    });
  RangeImage range(in.width_px, in.height_px);
  partial.combine_each([&](const RangeImage& r) { range.merge(r); });
  return range;
}

}  // namespace

ModelMaps raycast(const TsdfVolume& volume_in, const Intrinsics& in, const Pose& T_W_C,
                  float min_depth_m, float max_depth_m, bool with_colors) {
  const TsdfVolume::Impl& volume = volume_in.impl();
  const float voxel = volume.voxel_size_m;
  const float trunc = volume.truncation_m;
  ModelMaps maps;
  maps.intrinsics = in;
  maps.T_W_C = T_W_C;
  const std::size_t n = static_cast<std::size_t>(in.width_px) * in.height_px;
  maps.vertices_W.assign(n, Eigen::Vector3f::Constant(kNaN));
  maps.normals_W.assign(n, Eigen::Vector3f::Constant(kNaN));
  if (with_colors) maps.colors.assign(n, Rgb8::Zero());
  const RangeImage range = projectBlocks(volume, in, T_W_C, min_depth_m, max_depth_m);

  const Eigen::Matrix3f R_WC = T_W_C.linear();
  const Eigen::Vector3f origin_W = T_W_C.translation();
  const float fx = static_cast<float>(in.fx_px), fy = static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  const float inv_voxel = 1.0f / voxel;
  tbb::combinable<std::size_t> hits([] { return std::size_t{0}; });
  tbb::parallel_for(
      tbb::blocked_range<int>(0, in.height_px), [&](const tbb::blocked_range<int>& r) {
        VoxelReader reader(volume);
        std::size_t& hit_count = hits.local();
        for (int v = r.begin(); v != r.end(); ++v) {
          for (int u = 0; u < in.width_px; ++u) {
            const std::size_t tile =
                static_cast<std::size_t>(v / kTilePx) * range.tiles_x + u / kTilePx;
            const float z_begin = range.near[tile], z_end = range.far[tile];
            if (!(z_begin <= z_end)) continue;
            const Eigen::Vector3f ray_C((static_cast<float>(u) - cx) / fx,
                                        (static_cast<float>(v) - cy) / fy, 1.0f);
            const float metres_per_z = ray_C.norm();
            const Eigen::Vector3f dir_W = R_WC * ray_C;  // p(z) = origin + z * dir: z is depth
            // Grid coordinates along the ray: q(z) = q0 + z * dq.
            const Eigen::Vector3f q0 = origin_W * inv_voxel, dq = dir_W * inv_voxel;
            const float unknown_step_z = 0.8f * trunc / metres_per_z;
            const float min_step_z = voxel / metres_per_z;

            float z = z_begin, prev_z = 0.0f, prev_f = 0.0f;
            bool have_prev = false;
            std::optional<float> hit_z;
            while (z <= z_end) {
              const Eigen::Vector3f q = q0 + z * dq;
              const Voxel* vox = reader.get(Eigen::Vector3i(static_cast<int>(std::lround(q.x())),
                                                            static_cast<int>(std::lround(q.y())),
                                                            static_cast<int>(std::lround(q.z()))));
              if (!vox || vox->weight <= 0.0f) {
                have_prev = false;
                z += unknown_step_z;
                continue;
              }
              const float f = vox->tsdf;
              if (f < 0.0f) {
                if (!have_prev) break;  // behind a surface without having seen its front
                // Refine between the two samples with the trilinear distance where available.
                float f0 = prev_f, f1 = f;
                const std::optional<float> t0 = reader.tsdf(q0 + prev_z * dq);
                const std::optional<float> t1 = reader.tsdf(q);
                if (t0 && t1 && *t0 > 0.0f && *t1 < 0.0f) {
                  f0 = *t0;
                  f1 = *t1;
                }
                hit_z = prev_z + (z - prev_z) * f0 / (f0 - f1);
                break;
              }
              have_prev = true;
              prev_z = z;
              prev_f = f;
              z += std::max(min_step_z, 0.8f * f * trunc / metres_per_z);
            }
            if (!hit_z) continue;
            const Eigen::Vector3f q = q0 + *hit_z * dq;
            // Central differences of the interpolated distance, one voxel apart.
            Eigen::Vector3f gradient;
            bool ok = true;
            for (int axis = 0; axis < 3 && ok; ++axis) {
              Eigen::Vector3f e = Eigen::Vector3f::Zero();
              e[axis] = 1.0f;
              const std::optional<float> plus = reader.tsdf(q + e), minus = reader.tsdf(q - e);
              ok = plus && minus;
              if (ok) gradient[axis] = *plus - *minus;
            }
            const float norm = ok ? gradient.norm() : 0.0f;
            if (!(norm > 0.0f)) continue;
            const std::size_t i = static_cast<std::size_t>(v) * in.width_px + u;
            maps.vertices_W[i] = q * voxel;
            maps.normals_W[i] = gradient / norm;
            ++hit_count;
            if (with_colors) {
              const Voxel* vox = reader.get(Eigen::Vector3i(static_cast<int>(std::lround(q.x())),
                                                            static_cast<int>(std::lround(q.y())),
                                                            static_cast<int>(std::lround(q.z()))));
              if (vox) maps.colors[i] = Rgb8(vox->r, vox->g, vox->b);
            }
          }
        }
      });
  maps.hits = hits.combine([](std::size_t a, std::size_t b) { return a + b; });
  return maps;
}

ModelMaps halfResolution(const ModelMaps& maps) {
  ModelMaps half;
  half.intrinsics = levelIntrinsics(maps.intrinsics, 1);
  half.T_W_C = maps.T_W_C;
  const int w = half.intrinsics.width_px, h = half.intrinsics.height_px;
  const int full_w = maps.intrinsics.width_px;
  half.vertices_W.resize(static_cast<std::size_t>(w) * h);
  half.normals_W.resize(half.vertices_W.size());
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const std::size_t from = static_cast<std::size_t>(2 * v) * full_w + 2 * u;
      const std::size_t to = static_cast<std::size_t>(v) * w + u;
      half.vertices_W[to] = maps.vertices_W[from];
      half.normals_W[to] = maps.normals_W[from];
      half.hits += maps.normals_W[from].allFinite() ? 1 : 0;
    }
  }
  return half;
}

}  // namespace objscan::fusion
