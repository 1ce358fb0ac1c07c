#include "objscan/fusion/raycast.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "grid_math.h"
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
  assert(volume.block_indices.size() == volume.blocks.size());
  tbb::combinable<RangeImage> partial([&] { return RangeImage(in.width_px, in.height_px); });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, volume.blocks.size(), 256),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      RangeImage& range = partial.local();
                      for (std::size_t i = r.begin(); i != r.end(); ++i) {
                        // The block's extent: its voxels plus the one-voxel margin trilinear
                        // interpolation reads.
                        const Eigen::Vector3f lo = volume.block_indices[i].cast<float>() * block_m;
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

ModelMaps raycast(const TsdfVolume& volume, const Intrinsics& in, const Pose& T_W_C,
                  float min_depth_m, float max_depth_m, bool with_colors,
                  const cv::Mat* depth_hint, UnhintedRays unhinted) {
  ModelMaps maps;
  raycast(volume, in, T_W_C, min_depth_m, max_depth_m, with_colors, depth_hint, &maps, unhinted);
  return maps;
}

void raycast(const TsdfVolume& volume_in, const Intrinsics& in, const Pose& T_W_C,
             float min_depth_m, float max_depth_m, bool with_colors, const cv::Mat* depth_hint,
             ModelMaps* maps_out, UnhintedRays unhinted) {
  const TsdfVolume::Impl& volume = volume_in.impl();
  const float voxel = volume.voxel_size_m;
  const float trunc = volume.truncation_m;
  ModelMaps& maps = *maps_out;
  maps.intrinsics = in;
  maps.T_W_C = T_W_C;
  const std::size_t n = static_cast<std::size_t>(in.width_px) * in.height_px;
  maps.vertices_W.assign(n, Eigen::Vector3f::Constant(kNaN));
  maps.normals_W.assign(n, Eigen::Vector3f::Constant(kNaN));
  if (with_colors) {
    maps.colors.assign(n, Rgb8::Zero());
  } else {
    maps.colors.clear();
  }
  const RangeImage range = projectBlocks(volume, in, T_W_C, min_depth_m, max_depth_m);

  const Eigen::Matrix3f R_WC = T_W_C.linear();
  const Eigen::Vector3f origin_W = T_W_C.translation();
  const float fx = static_cast<float>(in.fx_px), fy = static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  const float inv_voxel = 1.0f / voxel;
  constexpr int kMaxBackSteps = 8;
  if (depth_hint && (depth_hint->type() != CV_32FC1 || depth_hint->cols != in.width_px ||
                     depth_hint->rows != in.height_px)) {
    throw std::invalid_argument("raycast: the depth hint must be CV_32FC1 of the image's size");
  }
  const bool skip_unhinted = depth_hint && unhinted == UnhintedRays::kSkip;
  tbb::combinable<std::size_t> hits([] { return std::size_t{0}; });
  // Rays in tiles of pixels rather than rows: neighbouring rays read the same blocks, so a tile
  // keeps them in the reader's cache and the CPU's.
  tbb::parallel_for(
      tbb::blocked_range2d<int>(0, in.height_px, 16, 0, in.width_px, 32),
      [&](const tbb::blocked_range2d<int>& r) {
        VoxelReader reader(volume);
        std::size_t& hit_count = hits.local();
        for (int v = r.rows().begin(); v != r.rows().end(); ++v) {
          for (int u = r.cols().begin(); u != r.cols().end(); ++u) {
            const float hint = depth_hint ? depth_hint->ptr<float>(v)[u] : 0.0f;
            if (skip_unhinted && !(hint > 0.0f)) continue;
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

            // Marches from z to z_end. Returns the depth of the first crossing from positive to
            // negative (between two nearest-voxel samples) in *bracket, with the last positive
            // sample's depth in *before; false when the first observed sample is negative (the
            // back of a surface) or nothing is crossed.
            const auto march = [&](float z, float z_stop, float* bracket, float* before,
                                   bool* back_face) {
              bool have_prev = false;
              float prev_z = 0.0f, prev_f = 0.0f;
              *back_face = false;
              while (z <= z_stop) {
                const Eigen::Vector3f q = q0 + z * dq;
                const Eigen::Vector3i g(roundToInt(q.x()), roundToInt(q.y()), roundToInt(q.z()));
                const PackedVoxel* vox = reader.get(g);
                if (!vox) {
                  // An unallocated block holds no surface: jump to where the ray leaves it.
                  float exit_z = std::numeric_limits<float>::infinity();
                  for (int a = 0; a < 3; ++a) {
                    const float lo = static_cast<float>((g[a] >> 3) * kBlockSide) - 0.5f;
                    if (dq[a] > 0.0f) {
                      exit_z = std::min(exit_z, z + (lo + kBlockSide - q[a]) / dq[a]);
                    } else if (dq[a] < 0.0f) {
                      exit_z = std::min(exit_z, z + (lo - q[a]) / dq[a]);
                    }
                  }
                  have_prev = false;
                  z = std::max(exit_z, z + 0.01f * min_step_z) + 0.01f * min_step_z;
                  continue;
                }
                if (!vox->observed()) {
                  have_prev = false;
                  z += unknown_step_z;
                  continue;
                }
                const float f = vox->tsdf();
                if (f < 0.0f) {
                  if (!have_prev) {
                    *back_face = true;
                    return false;
                  }
                  *bracket = prev_z + (z - prev_z) * prev_f / (prev_f - f);
                  *before = prev_z;
                  return true;
                }
                have_prev = true;
                prev_z = z;
                prev_f = f;
                z += std::max(min_step_z, 0.8f * f * trunc / metres_per_z);
              }
              return false;
            };
            // Cast right after integrating a depth image from the same pose, the surface is
            // near that image's reading. The distance stored at the reading says on which side
            // and about how far: search from there. Returns 1 when bracketed, 0 when marching on
            // from a reading in front of the surface finds no crossing (a march from the camera
            // would pass the same voxels), -1 to fall back to marching the whole range.
            const auto searchFromHint = [&](float start, float* bracket, float* before) -> int {
              const Eigen::Vector3f q = q0 + start * dq;
              const PackedVoxel* vox = reader.get(
                  Eigen::Vector3i(roundToInt(q.x()), roundToInt(q.y()), roundToInt(q.z())));
              if (!vox || !vox->observed()) return -1;
              if (vox->tsdf_q >= 0) {  // in front of the surface: march on from here
                bool back_face = false;
                const bool hit = march(start, z_end, bracket, before, &back_face);
                return hit ? 1 : (back_face ? -1 : 0);
              }
              // Behind it: step back toward the camera until the distance turns positive.
              float z_neg = start, f_neg = vox->tsdf();
              for (int step = 0; step < kMaxBackSteps; ++step) {
                const float z = z_neg - std::max(min_step_z, -0.8f * f_neg * trunc / metres_per_z);
                if (z < z_begin) return -1;
                const Eigen::Vector3f qb = q0 + z * dq;
                const PackedVoxel* b = reader.get(
                    Eigen::Vector3i(roundToInt(qb.x()), roundToInt(qb.y()), roundToInt(qb.z())));
                if (!b || !b->observed()) return -1;
                const float f_b = b->tsdf();
                if (f_b >= 0.0f) {
                  *bracket = z + (z_neg - z) * f_b / (f_b - f_neg);
                  *before = z;
                  return 1;
                }
                z_neg = z;
                f_neg = f_b;
              }
              return -1;
            };
            float bracket = 0.0f, prev_z = 0.0f;
            bool found = false;
            const int hinted =
                hint > z_begin && hint < z_end ? searchFromHint(hint, &bracket, &prev_z) : -1;
            if (hinted >= 0) {
              found = hinted == 1;
            } else {
              bool back_face = false;
              found = march(z_begin, z_end, &bracket, &prev_z, &back_face);
            }
            if (!found) continue;
            // One Newton step on the interpolated distance along the ray, kept near the
            // bracket; the same 8 voxels give the normal. The march read the nearest voxel at
            // each sample, up to half a voxel diagonal (0.87 voxel) from the sample itself, so
            // the step may leave the bracket by that much on either side.
            const float slack = 0.87f * min_step_z;
            const float lo = prev_z - slack, hi = bracket + (bracket - prev_z) + slack;
            float value = 0.0f;
            Eigen::Vector3f gradient;
            if (!reader.sample(q0 + bracket * dq, &value, &gradient)) continue;
            const float slope = gradient.dot(dq);  // d(value)/dz, negative toward the surface
            float hit_z = bracket;
            if (slope < 0.0f) hit_z = std::clamp(hit_z - value / slope, lo, hi);
            const float norm = gradient.norm();
            if (!(norm > 0.0f)) continue;
            const Eigen::Vector3f q = q0 + hit_z * dq;
            const std::size_t i = static_cast<std::size_t>(v) * in.width_px + u;
            maps.vertices_W[i] = q * voxel;
            maps.normals_W[i] = gradient / norm;
            ++hit_count;
            if (with_colors) {
              const VoxelColor* c = reader.color(
                  Eigen::Vector3i(roundToInt(q.x()), roundToInt(q.y()), roundToInt(q.z())));
              if (c) maps.colors[i] = Rgb8(c->r, c->g, c->b);
            }
          }
        }
      });
  maps.hits = hits.combine([](std::size_t a, std::size_t b) { return a + b; });
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
