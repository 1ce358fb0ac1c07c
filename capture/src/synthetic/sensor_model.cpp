#include "objscan/capture/synthetic/sensor_model.h"

#include <tbb/parallel_for.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace objscan::capture {
namespace {

/// Projector-shadow tolerance, pixels of projector coordinate.
constexpr double kShadowTolerance_px = 0.05;

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// xoshiro256** (Blackman and Vigna) with polar-method normals: a few nanoseconds a draw, which
/// matters at 300k pixels a frame. Seeded per row, so results do not depend on the thread
/// schedule.
class RowRng {
 public:
  RowRng(std::uint64_t seed, std::uint64_t row) {
    std::uint64_t state = seed ^ (0xd1b54a32d192ed03ULL * (row + 1));
    for (auto& word : s_) word = splitmix64(state);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  /// Marsaglia's polar method: one log and one sqrt per pair, no trigonometry.
  double gauss() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double x, y, r2;
    do {
      x = 2.0 * uniform() - 1.0;
      y = 2.0 * uniform() - 1.0;
      r2 = x * x + y * y;
    } while (r2 >= 1.0 || r2 == 0.0);
    const double scale = std::sqrt(-2.0 * std::log(r2) / r2);
    spare_ = y * scale;
    has_spare_ = true;
    return x * scale;
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t next() {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  std::uint64_t s_[4];
  double spare_ = 0.0;
  bool has_spare_ = false;
};

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
  if (!(std::abs(distortion_radial) <= 0.1) || !(std::abs(distortion_wave) <= 0.1)) {
    fail("distortion_radial and distortion_wave must lie in [-0.1, 0.1]");
  }
}

double SensorModelConfig::distortionFactor(double u_px, double v_px, double z_m, int width_px,
                                           int height_px) const {
  if (distortion_radial == 0.0 && distortion_wave == 0.0) return 1.0;
  constexpr double kTwoPi = 6.283185307179586;
  const double half_w = 0.5 * width_px, half_h = 0.5 * height_px;
  const double du = u_px - half_w, dv = v_px - half_h;
  const double rho2 = (du * du + dv * dv) / (half_w * half_w + half_h * half_h);
  // Fixed phases: the pattern belongs to the device, not to a recording.
  const double wave = std::cos(kTwoPi * 1.5 * u_px / width_px + 0.7) *
                      std::cos(kTwoPi * 1.0 * v_px / height_px + 1.9);
  return 1.0 + z_m * (distortion_radial * rho2 + distortion_wave * wave);
}

double SensorModelConfig::axialSigmaM(double z_m) const {
  return axial_a_m + axial_b_per_m * (z_m - axial_c_m) * (z_m - axial_c_m);
}

cv::Mat applySensorModel(const render::RenderedView& view, const Intrinsics& in,
                         const SensorModelConfig& config, std::uint64_t seed) {
  config.validate();
  if (view.depth_m.type() != CV_32FC1 || view.cos_incidence.type() != CV_32FC1 ||
      view.depth_m.size() != view.cos_incidence.size()) {
    throw std::invalid_argument(
        "sensor model: the view needs depth_m and cos_incidence, both CV_32FC1 of one size");
  }
  const cv::Mat& ideal = view.depth_m;
  if (!config.enabled) return ideal.clone();
  const int w = ideal.cols, h = ideal.rows;
  const double fb = in.fx_px * config.baseline_m;  // disparity (px) times depth (m)
  cv::Mat out(h, w, CV_32FC1, cv::Scalar(0.0f));

  auto at = [&](int v, int u) { return ideal.at<float>(v, u); };
  const double cos_grazing_start = std::cos(config.grazing_start_rad);
  const double cos_grazing_max = std::cos(config.grazing_max_rad);
  // A depth discontinuity: a 4-neighbour with no reading or a depth that differs by more than
  // discontinuity_ratio of this one.
  const float ratio = static_cast<float>(config.discontinuity_ratio);
  auto isEdge = [&](int v, int u) {
    const float* row = ideal.ptr<float>(v);
    const float z = row[u];
    const float limit = ratio * z;
    auto differs = [&](float zn) { return zn == 0.0f || std::abs(zn - z) > limit; };
    return (u + 1 < w && differs(row[u + 1])) || (u > 0 && differs(row[u - 1])) ||
           (v + 1 < h && differs(ideal.ptr<float>(v + 1)[u])) ||
           (v > 0 && differs(ideal.ptr<float>(v - 1)[u]));
  };

  tbb::parallel_for(0, h, [&](int v) {
    RowRng rng(seed, static_cast<std::uint64_t>(v));

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
    const float* ideal_row = ideal.ptr<float>(v);
    const float* cos_row = view.cos_incidence.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      double z = ideal_row[u];
      if (z <= 0.0 || !lit[static_cast<std::size_t>(u)]) continue;

      // Grazing incidence: angle between the surface normal and the viewing ray, compared as
      // cosines; the angle itself only inside the ramp.
      const double cos_incidence = cos_row[u];
      if (cos_incidence <= cos_grazing_max) continue;
      if (cos_incidence < cos_grazing_start &&
          rng.uniform() < (std::acos(cos_incidence) - config.grazing_start_rad) /
                              (config.grazing_max_rad - config.grazing_start_rad)) {
        continue;
      }

      // Depth edges: readings go missing, or come from a laterally displaced neighbour.
      if (isEdge(v, u)) {
        if (rng.uniform() < config.edge_dropout_probability) continue;
        const int uu = std::clamp(
            u + static_cast<int>(std::lround(config.lateral_sigma_px * rng.gauss())), 0, w - 1);
        const int vv = std::clamp(
            v + static_cast<int>(std::lround(config.lateral_sigma_px * rng.gauss())), 0, h - 1);
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
      z += gaussian_sigma * rng.gauss();
      if (config.disparity_step_px > 0.0 && z > 0.0) {
        const double disparity = fb / z;
        z = fb / (std::round(disparity / config.disparity_step_px) * config.disparity_step_px);
      }
      z *= config.distortionFactor(u, v, z, w, h);
      if (z < config.min_range_m || z > config.max_range_m) continue;
      row[u] = static_cast<float>(z);
    }
  });
  return out;
}

std::optional<SensorModelConfig> sensorForNoise(std::string_view level) {
  SensorModelConfig sensor;
  if (level == "off") {
    sensor.enabled = false;
  } else if (level == "full") {
    sensor = sensor.withDeviceDistortion();
  } else if (level != "on") {
    return std::nullopt;
  }
  return sensor;
}

}  // namespace objscan::capture
