#include "objscan/fusion/icp.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Cholesky>
#include "grid_math.h"

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

/// Up to kSize point-to-plane pairs, structure of arrays: Jacobian rows, Huber weights and
/// residuals.
struct Batch {
  static constexpr int kSize = 64;
  alignas(16) float J[6][kSize];
  alignas(16) float w[kSize];
  alignas(16) float r[kSize];
  int n = 0;

  /// Adds w J^T J (upper triangle, 21 values) and -w J^T r (6) of the pairs to `acc`, lane by
  /// lane, and empties the batch.
  void addTo(Float4* acc) {
    if (n == 0) return;
    for (int k = n; k % 4 != 0; ++k) {  // pad to whole vectors with pairs of weight 0
      for (float* row : J) row[k] = 0.0f;
      w[k] = 0.0f;
      r[k] = 0.0f;
    }
    for (int k = 0; k < n; k += 4) {
      Float4 j[6], wj[6], wv, rv;
      std::memcpy(&wv, w + k, sizeof wv);
      std::memcpy(&rv, r + k, sizeof rv);
      for (int a = 0; a < 6; ++a) {
        std::memcpy(&j[a], J[a] + k, sizeof j[a]);
        wj[a] = wv * j[a];
      }
      int e = 0;
      for (int a = 0; a < 6; ++a) {
        for (int b = a; b < 6; ++b) acc[e++] += wj[a] * j[b];
        acc[21 + a] -= wj[a] * rv;
      }
    }
    n = 0;
  }
};

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
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(0, (height + stride - 1) / stride), NormalEquations(),
      [&](const tbb::blocked_range<int>& rows, NormalEquations sum) {
        // Upper triangle of J^T W J (21 values) and J^T W r (6), single precision within a
        // row, double across rows. The pairs found are collected in a batch, structure of
        // arrays, and summed 4 at a time: the sums cost as much as finding the pairs otherwise.
        Batch batch;
        Float4 acc[27];
        for (int row = rows.begin(); row != rows.end(); ++row) {
          const int v = row * stride;
          for (Float4& a : acc) a = Float4{0.0f, 0.0f, 0.0f, 0.0f};
          for (int u = 0; u < width; u += stride) {
            const std::size_t i = static_cast<std::size_t>(v) * width + u;
            const Eigen::Vector3f& n_C = frame.normals_C[i];
            if (!n_C.allFinite()) continue;
            ++sum.candidates;
            const Eigen::Vector3f& p_C = frame.vertices_C[i];
            const Eigen::Vector3f p_M = R_MC * p_C + t_MC;
            if (p_M.z() <= 0.0f) continue;
            const int mu = roundToInt(fx * p_M.x() / p_M.z() + cx);
            const int mv = roundToInt(fy * p_M.y() / p_M.z() + cy);
            if (mu < 0 || mv < 0 || mu >= in.width_px || mv >= in.height_px) continue;
            const std::size_t j = static_cast<std::size_t>(mv) * in.width_px + mu;
            const Eigen::Vector3f& m = model.vertices_W[j];
            const Eigen::Vector3f& nm = model.normals_W[j];
            if (!nm.allFinite()) continue;
            const Eigen::Vector3f p_W = R * p_C + t;
            const Eigen::Vector3f d = p_W - m;
            if (d.squaredNorm() > max_d2) continue;
            if ((R * n_C).dot(nm) < min_cos) continue;
            const float r = nm.dot(d);
            const float w = std::abs(r) <= huber ? 1.0f : huber / std::abs(r);
            // J = [p x n, n]: the residual's derivative for a small motion (rotation first).
            const int k = batch.n++;
            batch.J[0][k] = p_W.y() * nm.z() - p_W.z() * nm.y();
            batch.J[1][k] = p_W.z() * nm.x() - p_W.x() * nm.z();
            batch.J[2][k] = p_W.x() * nm.y() - p_W.y() * nm.x();
            batch.J[3][k] = nm.x();
            batch.J[4][k] = nm.y();
            batch.J[5][k] = nm.z();
            batch.w[k] = w;
            batch.r[k] = r;
            if (batch.n == Batch::kSize) batch.addTo(acc);
            ++sum.inliers;
            sum.squared_residuals += static_cast<double>(r) * r;
          }
          batch.addTo(acc);
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
