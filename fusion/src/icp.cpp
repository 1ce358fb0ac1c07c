#include "objscan/fusion/icp.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Cholesky>

namespace objscan::fusion {

namespace {

/// Sums of one Gauss-Newton step: J^T W J (upper triangle), J^T W r, and the inlier statistics.
struct NormalEquations {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  std::size_t inliers = 0;
  std::size_t candidates = 0;  ///< frame pixels visited that have a vertex and a normal
  double squared_residuals = 0.0;

  void add(const NormalEquations& o) {
    A += o.A;
    b += o.b;
    inliers += o.inliers;
    candidates += o.candidates;
    squared_residuals += o.squared_residuals;
  }
};

using Float4 = float __attribute__((vector_size(16)));  // SSE2 on the default x86-64 target

float horizontalSum(Float4 x) { return (x[0] + x[1]) + (x[2] + x[3]); }

using Int4 = std::int32_t __attribute__((vector_size(16)));

/// Up to 4 frame points with a normal, structure of arrays, camera frame (lanes from `count` on
/// are unused, and zero).
struct Lanes {
  alignas(16) float p[3][4];
  alignas(16) float n[3][4];
  int count = 0;
};

Float4 load(const float* x) {
  Float4 v;
  std::memcpy(&v, x, sizeof v);
  return v;
}

/// Sums over every `stride`-th pixel of every `stride`-th row of `frame`, each associated with
/// the model pixel it projects to (the model may have another resolution than the frame).
NormalEquations accumulate(const DepthLevel& frame, const ModelMaps& model, const Pose& T_W_C,
                           const TrackingConfig& config, int stride) {
  const Eigen::Matrix3f R = T_W_C.linear();
  const Eigen::Vector3f t = T_W_C.translation();
  const Pose T_M_C = model.T_W_C.inverse() * T_W_C;  // the frame's camera to the model's
  const Eigen::Matrix3f R_MC = T_M_C.linear();
  const Eigen::Vector3f t_MC = T_M_C.translation();
  const Intrinsics& in = model.intrinsics;
  const float fx = static_cast<float>(in.fx_px), fy = static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  const float max_d2 = config.max_distance_m * config.max_distance_m;
  const float min_cos = std::cos(config.max_angle_rad);
  const float huber = config.huber_m;
  // The frame's maps may hold every n-th pixel only (DepthLevel::sample_stride_px): step through
  // them by what remains of `stride`.
  const int sampled = frame.sample_stride_px;
  if (sampled < 1 || stride % sampled != 0) {
    throw std::invalid_argument("trackFrame: the frame's maps hold every " +
                                std::to_string(sampled) + "th pixel, but tracking reads every " +
                                std::to_string(stride) + "th: build the pyramid with the stride " +
                                "tracking uses (or 1)");
  }
  stride /= sampled;
  const int width = (frame.depth_m.cols + sampled - 1) / sampled;
  const int height = (frame.depth_m.rows + sampled - 1) / sampled;
  assert(frame.vertices_C.size() == static_cast<std::size_t>(width) * height);
  // Deterministic: the rows are split and the partial sums joined the same way on every run, so
  // the floating-point sums, and with them the trajectory, do not depend on the thread schedule.
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<int>(0, (height + stride - 1) / stride, 4), NormalEquations(),
      [&](const tbb::blocked_range<int>& rows, NormalEquations sum) {
        // Upper triangle of J^T W J (21 values) and J^T W r (6), single precision per lane
        // within a row, double across rows.
        Float4 acc[27];
        const auto splat = [](float x) { return Float4{x, x, x, x}; };
        const Float4 zero = splat(0.0f);
        // Four points at a time: transformed, projected and gated in SSE2 vectors, with only
        // the model's vertex and normal fetched lane by lane. A lane that fails a gate gets
        // weight 0 (and zeros in place of NaN), which adds nothing to the sums.
        const auto addLanes = [&](const Lanes& l, NormalEquations& s) {
          const Float4 px = load(l.p[0]), py = load(l.p[1]), pz = load(l.p[2]);
          const Float4 nx = load(l.n[0]), ny = load(l.n[1]), nz = load(l.n[2]);
          const Float4 mx = R_MC(0, 0) * px + R_MC(0, 1) * py + R_MC(0, 2) * pz + t_MC.x();
          const Float4 my = R_MC(1, 0) * px + R_MC(1, 1) * py + R_MC(1, 2) * pz + t_MC.y();
          const Float4 mz = R_MC(2, 0) * px + R_MC(2, 1) * py + R_MC(2, 2) * pz + t_MC.z();
          Int4 ok = (Int4{0, 1, 2, 3} < l.count) & (mz > 0.0f);
          const Float4 safe_z = ok ? mz : splat(1.0f);
          // Pixel coordinates plus one half: their floor is the nearest pixel (roundToInt).
          const Float4 uf = fx * mx / safe_z + (cx + 0.5f), vf = fy * my / safe_z + (cy + 0.5f);
          ok &= (uf >= 0.0f) & (uf < static_cast<float>(in.width_px)) & (vf >= 0.0f) &
                (vf < static_cast<float>(in.height_px));
          // Truncation is the floor here: the coordinates of lanes still ok are >= 0.
          const Int4 j = __builtin_convertvector(ok ? vf : zero, Int4) * in.width_px +
                         __builtin_convertvector(ok ? uf : zero, Int4);
          alignas(16) float m[3][4], nm[3][4];
          for (int k = 0; k < 4; ++k) {
            const Eigen::Vector3f& vertex = model.vertices_W[static_cast<std::size_t>(j[k])];
            const Eigen::Vector3f& normal = model.normals_W[static_cast<std::size_t>(j[k])];
            for (int c = 0; c < 3; ++c) {
              m[c][k] = vertex[c];
              nm[c][k] = normal[c];
            }
          }
          Float4 qx = load(nm[0]), qy = load(nm[1]), qz = load(nm[2]);
          ok &= (qx == qx) & (qy == qy) & (qz == qz);  // the model has a normal there
          const Float4 wx = R(0, 0) * px + R(0, 1) * py + R(0, 2) * pz + t.x();
          const Float4 wy = R(1, 0) * px + R(1, 1) * py + R(1, 2) * pz + t.y();
          const Float4 wz = R(2, 0) * px + R(2, 1) * py + R(2, 2) * pz + t.z();
          const Float4 dx = wx - load(m[0]), dy = wy - load(m[1]), dz = wz - load(m[2]);
          ok &= dx * dx + dy * dy + dz * dz <= max_d2;
          const Float4 rnx = R(0, 0) * nx + R(0, 1) * ny + R(0, 2) * nz;
          const Float4 rny = R(1, 0) * nx + R(1, 1) * ny + R(1, 2) * nz;
          const Float4 rnz = R(2, 0) * nx + R(2, 1) * ny + R(2, 2) * nz;
          ok &= rnx * qx + rny * qy + rnz * qz >= min_cos;
          qx = ok ? qx : zero;
          qy = ok ? qy : zero;
          qz = ok ? qz : zero;
          const Float4 r = ok ? qx * dx + qy * dy + qz * dz : zero;
          const Float4 abs_r = r < 0.0f ? -r : r;
          const Float4 w = ok ? (abs_r <= huber ? splat(1.0f) : huber / abs_r) : zero;
          // J = [p x n, n]: the residual's derivative for a small motion (rotation first).
          const Float4 J[6] = {wy * qz - wz * qy, wz * qx - wx * qz, wx * qy - wy * qx, qx, qy, qz};
          int e = 0;
          for (int a = 0; a < 6; ++a) {
            const Float4 wj = w * J[a];
            for (int b = a; b < 6; ++b) acc[e++] += wj * J[b];
            acc[21 + a] -= wj * r;
          }
          for (int k = 0; k < 4; ++k) s.inliers += ok[k] != 0 ? 1 : 0;
          s.squared_residuals += static_cast<double>(horizontalSum(r * r));
        };
        Lanes lanes;
        for (int row = rows.begin(); row != rows.end(); ++row) {
          const int v = row * stride;
          for (Float4& a : acc) a = zero;
          const std::size_t first = static_cast<std::size_t>(v) * width;
          const Eigen::Vector3f* points = frame.vertices_C.data() + first;
          const Eigen::Vector3f* normals = frame.normals_C.data() + first;
          for (int u = 0; u < width; u += stride) {
            if (std::isnan(normals[u].x())) continue;  // a normal is NaN in all or none
            ++sum.candidates;
            const int k = lanes.count++;
            for (int c = 0; c < 3; ++c) {
              lanes.p[c][k] = points[u][c];
              lanes.n[c][k] = normals[u][c];
            }
            if (lanes.count == 4) {
              addLanes(lanes, sum);
              lanes.count = 0;
            }
          }
          if (lanes.count > 0) {
            for (int k = lanes.count; k < 4; ++k) {
              for (int c = 0; c < 3; ++c) lanes.p[c][k] = lanes.n[c][k] = 0.0f;
            }
            addLanes(lanes, sum);
            lanes.count = 0;
          }
          int k = 0;
          for (int a = 0; a < 6; ++a) {
            for (int b = a; b < 6; ++b) sum.A(a, b) += horizontalSum(acc[k++]);
            sum.b(a) += horizontalSum(acc[21 + a]);
          }
        }
        return sum;
      },
      [](NormalEquations a, const NormalEquations& o) {
        a.add(o);
        return a;
      });
}

/// exp of a small twist (rotation vector w, translation t), left-multiplied.
Pose twistToPose(const Eigen::Matrix<double, 6, 1>& x) {
  Pose delta = Pose::Identity();
  const Eigen::Vector3d w = x.head<3>();
  const double angle = w.norm();
  if (angle > 0.0)
    delta.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix().cast<float>();
  delta.translation() = x.tail<3>().cast<float>();
  return delta;
}

}  // namespace

void TrackingConfig::validate() const {
  for (int n : iterations) {
    if (n < 0 || n > 100) throw std::invalid_argument("ICP iterations must be 0 to 100 per level");
  }
  const auto positive = [](float x) { return std::isfinite(x) && x > 0.0f; };
  if (!positive(max_distance_m) || !positive(max_angle_rad) || !positive(huber_m) ||
      !positive(max_rmse_m) || !positive(max_translation_m) || !positive(max_rotation_rad)) {
    throw std::invalid_argument("ICP distances, angles and thresholds must be positive");
  }
  if (finest_level_stride < 1 || finest_level_stride > 4) {
    throw std::invalid_argument("the finest level's pixel stride must be 1 to 4");
  }
  if (!(min_inlier_fraction >= 0.0f && min_inlier_fraction < 1.0f)) {
    throw std::invalid_argument("the minimum inlier share must be in [0, 1)");
  }
}

TrackingResult trackFrame(const DepthPyramid& frame, const ModelMaps& model,
                          const Pose& initial_T_W_C, const TrackingConfig& config) {
  const int levels = std::min<int>(static_cast<int>(frame.levels.size()), 3);
  if (levels == 0 || model.intrinsics.width_px <= 0) {
    throw std::invalid_argument("trackFrame: an empty frame pyramid or model");
  }
  // The model may be cast at a coarser resolution than the frame's finest level: frame level l
  // is matched against model level max(0, l - offset), where the model is 2^offset smaller.
  int offset = 0;
  while ((frame.levels.front().intrinsics.width_px >> offset) > model.intrinsics.width_px) {
    ++offset;
  }
  std::vector<ModelMaps> coarser;  // model levels 1, 2, ... (level 0 is `model` itself)
  coarser.reserve(static_cast<std::size_t>(levels));
  for (int l = 1; l < levels - offset; ++l) {
    coarser.push_back(halfResolution(l == 1 ? model : coarser.back()));
  }
  const auto modelFor = [&](int frame_level) -> const ModelMaps& {
    const int l = std::max(0, frame_level - offset);
    return l == 0 ? model : coarser[static_cast<std::size_t>(l) - 1];
  };
  const auto strideFor = [&](int frame_level) {
    return frame_level == 0 ? config.finest_level_stride : 1;
  };

  TrackingResult result;
  Pose T = initial_T_W_C;
  NormalEquations last;
  bool last_at_finest = false;  // whether `last` was summed at level 0
  bool solved = true;
  for (int level = levels - 1; level >= 0 && solved; --level) {
    const DepthLevel& f = frame.levels[static_cast<std::size_t>(level)];
    const ModelMaps& m = modelFor(level);
    for (int it = 0; it < config.iterations[static_cast<std::size_t>(level)]; ++it) {
      last = accumulate(f, m, T, config, strideFor(level));
      last_at_finest = level == 0;
      if (last.inliers < 6) {
        solved = false;
        break;
      }
      const Eigen::Matrix<double, 6, 6> A = last.A.selfadjointView<Eigen::Upper>();
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(A);
      const Eigen::Matrix<double, 6, 1> x = ldlt.solve(last.b);
      if (ldlt.info() != Eigen::Success || !x.allFinite()) {
        solved = false;
        break;
      }
      T = twistToPose(x) * T;
      T.linear() = Eigen::Quaternionf(T.linear()).normalized().toRotationMatrix();
      ++result.iterations;
      // Converged: the step turns less than 0.006 degrees and moves less than 0.1 mm.
      if (x.head<3>().norm() < 1e-4 && x.tail<3>().norm() < 1e-4) break;
    }
  }
  // The statistics judge the pose the last finest-level step started from: that step is a
  // refinement of at most a few millimetres, and summing all pixels once more would cost a fifth
  // of the tracking time. Without a finest-level step, they are summed for the pose reached.
  if (!last_at_finest)
    last = accumulate(frame.levels.front(), modelFor(0), T, config, strideFor(0));
  result.T_W_C = T;
  result.inliers = last.inliers;
  result.inlier_fraction =
      last.candidates > 0 ? static_cast<float>(last.inliers) / static_cast<float>(last.candidates)
                          : 0.0f;
  result.rmse_m = last.inliers > 0
                      ? static_cast<float>(std::sqrt(last.squared_residuals / last.inliers))
                      : 0.0f;
  const Pose motion = initial_T_W_C.inverse() * T;
  const float moved_m = motion.translation().norm();
  const float turned_rad = Eigen::AngleAxisf(motion.linear()).angle();
  char why[160] = "";
  if (!solved || !T.matrix().allFinite()) {
    std::snprintf(why, sizeof why, "ICP found too few correspondences to solve for the pose");
  } else if (result.inlier_fraction < config.min_inlier_fraction) {
    std::snprintf(why, sizeof why, "only %.0f %% of the frame matched the model (needs %.0f %%)",
                  100.0 * result.inlier_fraction, 100.0 * config.min_inlier_fraction);
  } else if (result.rmse_m > config.max_rmse_m) {
    std::snprintf(why, sizeof why, "the residual is %.1f mm (limit %.1f mm)", 1e3 * result.rmse_m,
                  1e3 * config.max_rmse_m);
  } else if (moved_m > config.max_translation_m || turned_rad > config.max_rotation_rad) {
    std::snprintf(why, sizeof why, "the pose jumped %.0f mm and %.1f degrees in one frame",
                  1e3 * moved_m, turned_rad * 180.0 / M_PI);
  }
  result.failure = why;
  result.ok = result.failure.empty();
  return result;
}

}  // namespace objscan::fusion
