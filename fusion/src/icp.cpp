#include "objscan/fusion/icp.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <stdexcept>
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
  const int width = frame.depth_m.cols;
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(0, (frame.depth_m.rows + stride - 1) / stride), NormalEquations(),
      [&](const tbb::blocked_range<int>& rows, NormalEquations sum) {
        // Upper triangle of J^T W J (21 values) and J^T W r (6), single precision within a
        // row, double across rows. Written out: Eigen's 6x6 rank update is not inlined.
        float acc[27];
        for (int row = rows.begin(); row != rows.end(); ++row) {
          const int v = row * stride;
          std::fill(std::begin(acc), std::end(acc), 0.0f);
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
            const float J[6] = {p_W.y() * nm.z() - p_W.z() * nm.y(),
                                p_W.z() * nm.x() - p_W.x() * nm.z(),
                                p_W.x() * nm.y() - p_W.y() * nm.x(),
                                nm.x(),
                                nm.y(),
                                nm.z()};
            int k = 0;
            for (int a = 0; a < 6; ++a) {
              const float wa = w * J[a];
              for (int b = a; b < 6; ++b) acc[k++] += wa * J[b];
              acc[21 + a] -= wa * r;
            }
            ++sum.inliers;
            sum.squared_residuals += static_cast<double>(r) * r;
          }
          int k = 0;
          for (int a = 0; a < 6; ++a) {
            for (int b = a; b < 6; ++b) sum.A(a, b) += acc[k++];
            sum.b(a) += acc[21 + a];
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
