#pragma once

#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string_view>

#include "objscan/core/intrinsics.h"
#include "objscan/render/offscreen_renderer.h"

namespace objscan::capture {

/// Depth-sensor effects of a structured-light camera of the Kinect v1 / Asus Xtion class,
/// applied to an ideal rendered view. Defaults are that device's.
struct SensorModelConfig {
  /// Off: the depth is the ideal rendered depth, untouched (exact tests).
  bool enabled = true;
  /// Readings exist only between these distances (z), metres.
  double min_range_m = 0.5;
  double max_range_m = 4.0;
  /// Axial noise sigma_z(z) = a + b (z - c)^2 (Nguyen, Izadi, Lovell, 3DIMPVT 2012, fit for
  /// incidence angles up to about 60 degrees).
  double axial_a_m = 0.0012;
  double axial_b_per_m = 0.0019;
  double axial_c_m = 0.4;
  /// Baseline between the IR camera and the IR projector, which sits to the camera's right (+x).
  /// Sets the width of projector shadows and the disparity of each depth.
  double baseline_m = 0.075;
  /// Disparity is measured in steps of this many pixels (the Kinect v1 reports 1/8 pixel).
  double disparity_step_px = 1.0 / 8.0;
  /// Lateral noise at depth edges: the reading comes from a neighbour this far away (sigma, px;
  /// Nguyen et al. report 0.8 px).
  double lateral_sigma_px = 0.8;
  /// A pixel is at a depth discontinuity when a 4-neighbour differs by more than this fraction
  /// of its depth.
  double discontinuity_ratio = 0.04;
  /// Probability that a pixel right at a discontinuity has no reading.
  double edge_dropout_probability = 0.5;
  /// Readings thin out as the surface turns away: none beyond max, all below start (radians
  /// between the surface normal and the viewing ray), a linear ramp between.
  double grazing_start_rad = 1.2217;  // 70 degrees
  double grazing_max_rad = 1.4835;    // 85 degrees

  /// The device's fixed depth distortion, which fusion cannot average out: each reading is
  /// multiplied by 1 + (z / 1 m) (distortion_radial rho^2 + distortion_wave w(u, v)), where rho
  /// is the pixel's distance from the image centre over the half-diagonal and w a fixed pattern
  /// of one and a half periods across and one down (values in [-1, 1]). Structured-light
  /// sensors read a plane as a shallow bowl whose depth grows with distance, with a low-frequency
  /// ripple (Smisek, Jancosek, Pajdla, ICCV-W 2011; Teichman, Miller, Thrun, RSS 2013). 0: none,
  /// the default, so that fusion of synthetic frames stays as exact as it was;
  /// withDeviceDistortion() sets values calibrated on real fusions.
  double distortion_radial = 0.0;
  double distortion_wave = 0.0;

  /// This configuration with the fixed distortion that makes objscan's fusion of a synthetic
  /// table as uneven as its fusion of a real one (`--noise full`). Calibrated on the table's
  /// deviation from its plane: TUM fr2/desk (50 frames) and a 7-Scenes kitchen fusion give
  /// 2.7 and 3.3 mm median, 6.3 and 7.1 mm 90th percentile; synthetic desk and shelf scenes
  /// give 2.1 and 3.2 mm, 6.4 and 7.0 mm with these values, against 0.4 and 1.5 mm without.
  SensorModelConfig withDeviceDistortion() const {
    SensorModelConfig c = *this;
    c.distortion_radial = 0.008;
    c.distortion_wave = 0.0025;
    return c;
  }

  /// Throws std::invalid_argument naming the bad field.
  void validate() const;
  /// sigma_z at depth z, metres.
  double axialSigmaM(double z_m) const;
  /// 1 + the fixed distortion's relative error at pixel (u, v) of a width x height image for a
  /// reading at depth z (metres).
  double distortionFactor(double u_px, double v_px, double z_m, int width_px, int height_px) const;
};

/// The sensor of a noise level as `objscan synth --noise` and the source `synth:<seed>,noise=`
/// name it: "on" (the default model), "full" (with withDeviceDistortion) or "off" (exact depth);
/// nothing for another word.
std::optional<SensorModelConfig> sensorForNoise(std::string_view level);

/// Returns the sensor's depth image (CV_32FC1, metres, 0 = no reading) for an ideal view.
/// Deterministic for a given seed; rows are processed in parallel.
cv::Mat applySensorModel(const render::RenderedView& view, const Intrinsics& intrinsics,
                         const SensorModelConfig& config, std::uint64_t seed);

}  // namespace objscan::capture
