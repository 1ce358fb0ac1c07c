#include "objscan/render/sensor_model.h"

#include <tbb/parallel_for.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace objscan::render {
namespace {

/// Projector-shadow tolerance, pixels of projector coordinate.
constexpr double kShadowTolerance_px = 0.05;

std::uint64_t mix(std::uint64_t seed, std::uint64_t row) {
  // splitmix64 of the pair: independent streams per row, whatever the thread schedule.
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (row + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

void SensorModelConfig::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("sensor model: " + what); };
  if (!(min_range_m > 0.0) || !(max_range_m > min_range_m))
    fail("need 0 < min_range_m < max_range_m");
  if (!(axial_a_m >= 0.0) || !(axial_b_per_m >= 0.0)) fail("axial noise terms must be >= 0");
  if (!(baseline_m > 0.0)) fail("baseline_m must be > 0");
  if (!(disparity_step_px >= 0.0)) fail("disparity_step_px must be >= 0 (0 = no quantisation)");
  if (!(lateral_sigma_px >= 0.0)) fail("lateral_sigma_px must be >= 0");
  if (!(discontinuity_ratio > 0.0)) fail("discontinuity_ratio must be > 0");
  if (!(edge_dropout_probability >= 0.0 && edge_dropout_probability <= 1.0)) {
    fail("edge_dropout_probability must be in [0, 1]");
  }
  if (!(grazing_start_rad > 0.0) || !(grazing_max_rad > grazing_start_rad) ||
      grazing_max_rad > 1.5708) {
    fail("need 0 < grazing_start_rad < grazing_max_rad <= pi/2");
  }
}

double SensorModelConfig::axialSigmaM(double z_m) const {
  return axial_a_m + axial_b_per_m * (z_m - axial_c_m) * (z_m - axial_c_m);
}

cv::Mat applySensorModel(const RenderedView& view, const Intrinsics& in,
                         const SensorModelConfig& config, std::uint64_t seed) {
  config.validate();
  const cv::Mat& ideal = view.depth_m;
  if (!config.enabled) return ideal.clone();
  const int w = ideal.cols, h = ideal.rows;
  const double fb = in.fx_px * config.baseline_m;  // disparity (px) times depth (m)
  cv::Mat out(h, w, CV_32FC1, cv::Scalar(0.0f));

  auto at = [&](int v, int u) { return ideal.at<float>(v, u); };
  auto isEdge = [&](int v, int u) {
    const float z = at(v, u);
    const float limit = static_cast<float>(config.discontinuity_ratio) * z;
    const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
    for (int k = 0; k < 4; ++k) {
      const int uu = u + du[k], vv = v + dv[k];
      if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
      const float zn = at(vv, uu);
      if (zn == 0.0f || std::abs(zn - z) > limit) return true;
    }
    return false;
  };

  tbb::parallel_for(0, h, [&](int v) {
    std::mt19937_64 rng(mix(seed, static_cast<std::uint64_t>(v)));
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);

    // Projector shadows along the row. The projector at +x sees camera pixel u at projector
    // column u - fb / z; a point is lit only if no point to its right reaches a smaller
    // projector column (a nearer surface on the same projector ray).
    std::vector<char> lit(static_cast<std::size_t>(w), 0);
    double min_projector_u = std::numeric_limits<double>::infinity();
    for (int u = w - 1; u >= 0; --u) {
      const float z = at(v, u);
      if (z <= 0.0f) continue;
      const double projector_u = u - fb / z;
      lit[static_cast<std::size_t>(u)] = projector_u <= min_projector_u + kShadowTolerance_px;
      min_projector_u = std::min(min_projector_u, projector_u);
    }

    float* row = out.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      double z = at(v, u);
      if (z <= 0.0 || !lit[static_cast<std::size_t>(u)]) continue;

      // Grazing incidence: angle between the surface normal and the viewing ray.
      const cv::Vec3f n = view.normal_C.at<cv::Vec3f>(v, u);
      const Eigen::Vector3d ray((u - in.cx_px) / in.fx_px, (v - in.cy_px) / in.fy_px, 1.0);
      const double cos_incidence =
          std::abs(n[0] * ray.x() + n[1] * ray.y() + n[2] * ray.z()) / ray.norm();
      const double incidence = std::acos(std::min(1.0, cos_incidence));
      if (incidence >= config.grazing_max_rad) continue;
      if (incidence > config.grazing_start_rad &&
          uniform(rng) < (incidence - config.grazing_start_rad) /
                             (config.grazing_max_rad - config.grazing_start_rad)) {
        continue;
      }

      // Depth edges: readings go missing, or come from a laterally displaced neighbour.
      if (isEdge(v, u)) {
        if (uniform(rng) < config.edge_dropout_probability) continue;
        const int uu = std::clamp(
            u + static_cast<int>(std::lround(config.lateral_sigma_px * gauss(rng))), 0, w - 1);
        const int vv = std::clamp(
            v + static_cast<int>(std::lround(config.lateral_sigma_px * gauss(rng))), 0, h - 1);
        if (at(vv, uu) <= 0.0f) continue;
        z = at(vv, uu);
      }

      // Axial noise, then disparity quantisation. The Gaussian part is reduced by the
      // quantisation's own variance (step^2 / 12, in depth units) so that the total matches
      // sigma_z of the model.
      const double sigma = config.axialSigmaM(z);
      const double step_m = z * z * config.disparity_step_px / fb;
      const double gaussian_sigma =
          std::sqrt(std::max(0.0, sigma * sigma - step_m * step_m / 12.0));
      z += gaussian_sigma * gauss(rng);
      if (config.disparity_step_px > 0.0 && z > 0.0) {
        const double disparity = fb / z;
        z = fb / (std::round(disparity / config.disparity_step_px) * config.disparity_step_px);
      }
      if (z < config.min_range_m || z > config.max_range_m) continue;
      row[u] = static_cast<float>(z);
    }
  });
  return out;
}

}  // namespace objscan::render
