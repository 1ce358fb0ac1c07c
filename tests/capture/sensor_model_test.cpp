#include "objscan/capture/synthetic/sensor_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>

#include "objscan/render/offscreen_renderer.h"

namespace objscan::capture {
namespace {

/// Renders quads (each: pose of its centre, half size in x and y, label) from the identity pose.
struct Quad {
  Eigen::Vector3f centre;
  float half_x, half_y;
  float tilt_about_y_rad = 0.0f;
};

render::RenderedView renderQuads(const std::vector<Quad>& quads) {
  TriangleMesh m;
  for (const Quad& q : quads) {
    const int base = static_cast<int>(m.positions.size());
    const Eigen::Matrix3f R =
        Eigen::AngleAxisf(q.tilt_about_y_rad, Eigen::Vector3f::UnitY()).toRotationMatrix();
    for (const auto& [x, y] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
      m.positions.push_back(q.centre + R * Eigen::Vector3f(x * q.half_x, y * q.half_y, 0.0f));
    }
    m.triangles.emplace_back(base, base + 1, base + 2);
    m.triangles.emplace_back(base, base + 2, base + 3);
  }
  render::OffscreenRenderer renderer(Intrinsics::xtionDefault());
  renderer.setMesh(m);
  return renderer.render(Pose::Identity());
}

render::RenderedView wallAt(float z_m) { return renderQuads({{{0, 0, z_m}, 10.0f, 10.0f}}); }

/// Only one effect at a time: everything else neutral.
SensorModelConfig quiet() {
  SensorModelConfig c;
  c.axial_a_m = 0.0;
  c.axial_b_per_m = 0.0;
  c.disparity_step_px = 0.0;
  c.lateral_sigma_px = 0.0;
  c.edge_dropout_probability = 0.0;
  return c;
}

double validFraction(const cv::Mat& depth) {
  return static_cast<double>(cv::countNonZero(depth)) / static_cast<double>(depth.total());
}

TEST(SensorModel, WallNoiseMatchesNguyenSigmaWithin15PercentAt1To3Metres) {
  const SensorModelConfig config;  // the full model: Gaussian + disparity quantisation
  for (const float z : {1.0f, 2.0f, 3.0f}) {
    SCOPED_TRACE("wall at " + std::to_string(z) + " m");
    const cv::Mat depth = applySensorModel(wallAt(z), Intrinsics::xtionDefault(), config, 42);
    double sum = 0.0, sum_sq = 0.0;
    int n = 0;
    for (int v = 0; v < depth.rows; ++v) {
      for (int u = 0; u < depth.cols; ++u) {
        const float d = depth.at<float>(v, u);
        if (d == 0.0f) continue;
        sum += d - z;
        sum_sq += (d - z) * (d - z);
        ++n;
      }
    }
    ASSERT_GT(n, 300000) << "a wall in range facing the camera reads almost everywhere";
    const double mean = sum / n;
    const double sigma = std::sqrt(sum_sq / n - mean * mean);
    const double model = config.axialSigmaM(z);  // 1.9 mm at 1 m, 5.6 mm at 2 m, 14.0 mm at 3 m
    EXPECT_NEAR(sigma / model, 1.0, 0.15) << "measured " << sigma << " m, model " << model << " m";
    EXPECT_LT(std::abs(mean), 0.2 * model) << "bias " << mean << " m";
  }
}

TEST(SensorModel, NoReadingsOutsideHalfToFourMetres) {
  const Intrinsics in = Intrinsics::xtionDefault();
  EXPECT_EQ(cv::countNonZero(applySensorModel(wallAt(0.45f), in, quiet(), 1)), 0);
  EXPECT_EQ(cv::countNonZero(applySensorModel(wallAt(4.3f), in, quiet(), 1)), 0);
  EXPECT_EQ(validFraction(applySensorModel(wallAt(0.55f), in, quiet(), 1)), 1.0);
  EXPECT_EQ(validFraction(applySensorModel(wallAt(3.9f), in, quiet(), 1)), 1.0);
}

TEST(SensorModel, GrazingSurfacesLoseTheirReadings) {
  const Intrinsics in = Intrinsics::xtionDefault();
  // Floor-like plane seen at about 88 degrees: nothing; at 30 degrees: everything.
  const render::RenderedView steep = renderQuads({{{0, 0, 2.0f}, 0.5f, 0.5f, 1.536f}});
  const render::RenderedView mild = renderQuads({{{0, 0, 2.0f}, 0.5f, 0.5f, 0.5236f}});
  ASSERT_GT(cv::countNonZero(steep.depth_m), 0);
  EXPECT_EQ(cv::countNonZero(applySensorModel(steep, in, quiet(), 3)), 0);
  EXPECT_EQ(cv::countNonZero(applySensorModel(mild, in, quiet(), 3)),
            cv::countNonZero(mild.depth_m));
}

TEST(SensorModel, ProjectorShadowLiesLeftOfForegroundWithTheBaselineWidth) {
  const Intrinsics in = Intrinsics::xtionDefault();
  // A 20 cm board at 1 m in front of a wall at 2 m.
  const render::RenderedView view =
      renderQuads({{{0, 0, 2.0f}, 10.0f, 10.0f}, {{0, 0, 1.0f}, 0.1f, 0.1f}});
  const cv::Mat depth = applySensorModel(view, in, quiet(), 5);
  const int v = 240;
  int left_edge = -1, right_edge = -1;
  for (int u = 0; u < in.width_px; ++u) {
    if (view.depth_m.at<float>(v, u) == 1.0f) {
      if (left_edge < 0) left_edge = u;
      right_edge = u;
    }
  }
  ASSERT_GT(left_edge, 0);
  int shadow = 0;
  for (int u = left_edge - 1; u >= 0 && depth.at<float>(v, u) == 0.0f; --u) ++shadow;
  // Width on the wall: f b (1/z_near - 1/z_far) = 570.3 * 0.075 * (1 - 0.5) = 21.4 px.
  EXPECT_NEAR(shadow, 21.4, 1.0);
  EXPECT_GT(depth.at<float>(v, right_edge + 1), 0.0f) << "no shadow on the right";
  EXPECT_GT(depth.at<float>(v, left_edge), 0.0f) << "the board itself reads";
}

TEST(SensorModel, DepthEdgesLoseHalfTheirReadingsAndBorrowTheRestFromNeighbours) {
  const Intrinsics in = Intrinsics::xtionDefault();
  SensorModelConfig config = quiet();
  config.edge_dropout_probability = 0.5;
  config.lateral_sigma_px = 0.8;
  config.baseline_m = 1e-6;  // no projector shadow: edges only
  const render::RenderedView view =
      renderQuads({{{0, 0, 2.0f}, 10.0f, 10.0f}, {{0, 0, 1.0f}, 0.15f, 0.15f}});
  const cv::Mat depth = applySensorModel(view, in, config, 9);
  int edge = 0, edge_missing = 0, borrowed = 0, interior_changed = 0;
  for (int v = 1; v + 1 < depth.rows; ++v) {
    for (int u = 1; u + 1 < depth.cols; ++u) {
      const float z = view.depth_m.at<float>(v, u);
      bool is_edge = false;
      for (const auto& [du, dv] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        is_edge |= std::abs(view.depth_m.at<float>(v + dv, u + du) - z) > 0.04f * z;
      }
      const float out = depth.at<float>(v, u);
      if (!is_edge) {
        interior_changed += out != z;
        continue;
      }
      ++edge;
      if (out == 0.0f) {
        ++edge_missing;
      } else {
        ASSERT_TRUE(out == 1.0f || out == 2.0f) << "an edge reading is the board's or the wall's";
        borrowed += out != z;
      }
    }
  }
  EXPECT_EQ(interior_changed, 0) << "away from edges nothing moves";
  ASSERT_GT(edge, 1300);  // a 171 px square board: 4 x 171 pixels on each side of its outline
  EXPECT_NEAR(static_cast<double>(edge_missing) / edge, 0.5, 0.06);
  // Of the readings kept, some come from across the edge (sigma 0.8 px): a fair share, not all.
  EXPECT_GT(borrowed, (edge - edge_missing) / 10);
  EXPECT_LT(borrowed, (edge - edge_missing) / 2);
}

TEST(SensorModel, DepthsFallOnTheDisparityGrid) {
  const Intrinsics in = Intrinsics::xtionDefault();
  SensorModelConfig config = quiet();
  config.disparity_step_px = 1.0 / 8.0;
  // A tilted plane covers a range of depths: every reading must sit on the 1/8 px grid.
  const cv::Mat depth =
      applySensorModel(renderQuads({{{0, 0, 2.0f}, 5.0f, 5.0f, 0.6f}}), in, config, 7);
  const double fb = in.fx_px * config.baseline_m;
  int readings = 0;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const float z = depth.at<float>(v, u);
      if (z == 0.0f) continue;
      ++readings;
      const double steps = fb / z / config.disparity_step_px;
      ASSERT_NEAR(steps, std::round(steps), 1e-3) << "pixel " << u << ", " << v;
    }
  }
  EXPECT_GT(readings, 300000);
  // At 2 m facing the camera: between grid depths 1.9997 m and 2.0114 m (171 and 170 eighths).
  EXPECT_NEAR(applySensorModel(wallAt(2.0f), in, config, 7).at<float>(100, 100), fb / (171.0 / 8.0),
              1e-5);
}

TEST(SensorModel, RefusesViewsWithoutIncidence) {
  render::RenderedView view;
  view.depth_m = cv::Mat(4, 4, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_THROW(applySensorModel(view, Intrinsics::xtionDefault(), SensorModelConfig{}, 1),
               std::invalid_argument);
}

/// Mean reading of the 21 x 21 pixel window around (u, v); readings of 0 are skipped.
double windowMean(const cv::Mat& depth, int u, int v) {
  double sum = 0.0;
  int n = 0;
  for (int dv = -10; dv <= 10; ++dv) {
    for (int du = -10; du <= 10; ++du) {
      const float d = depth.at<float>(v + dv, u + du);
      if (d == 0.0f) continue;
      sum += d;
      ++n;
    }
  }
  return n == 0 ? 0.0 : sum / n;
}

TEST(SensorModel, DeviceDistortionBendsAWallIntoABowlThatDeepensWithDistance) {
  const Intrinsics in = Intrinsics::xtionDefault();
  // Without it (the default), a wall stays flat to float precision.
  const cv::Mat flat = applySensorModel(wallAt(1.0f), in, quiet(), 1);
  EXPECT_NEAR(windowMean(flat, 20, 20) - windowMean(flat, 320, 240), 0.0, 1e-6);

  const SensorModelConfig bent = quiet().withDeviceDistortion();
  double rise_at_1m = 0.0;
  for (const float z : {1.0f, 2.0f}) {
    SCOPED_TRACE("wall at " + std::to_string(z) + " m");
    const cv::Mat depth = applySensorModel(wallAt(z), in, bent, 1);
    const double centre = windowMean(depth, 320, 240);
    const double corner = windowMean(depth, 20, 20);
    // A corner reads deeper than the middle: the bowl. Near the top-left corner that is 0.8 % of
    // the depth per metre at the half-diagonal (rho^2 = 0.87 there), less the ripple's 0.25 % at
    // most: 5.7 mm at 1 m, whatever else the model does.
    const double rise = corner - centre;
    EXPECT_NEAR(rise,
                z * (bent.distortionFactor(20, 20, z, in.width_px, in.height_px) -
                     bent.distortionFactor(320, 240, z, in.width_px, in.height_px)),
                2e-4);
    if (z == 1.0f) {
      EXPECT_GT(rise, 0.005);
      rise_at_1m = rise;
    } else {
      // The relative error grows with depth, so the absolute one with its square.
      EXPECT_NEAR(rise / rise_at_1m, 4.0, 0.1);
    }
    // Each reading is the wall's depth times the documented factor (the window's spread of the
    // factor is well under 0.1 mm).
    EXPECT_NEAR(corner, z * bent.distortionFactor(20, 20, z, in.width_px, in.height_px), 1e-4);
  }
}

TEST(SensorModel, OffMeansUntouchedAndSeedsAreDeterministic) {
  const Intrinsics in = Intrinsics::xtionDefault();
  const render::RenderedView view =
      renderQuads({{{0, 0, 2.0f}, 10.0f, 10.0f}, {{0.2f, 0, 1.2f}, 0.1f, 0.2f}});
  SensorModelConfig off;
  off.enabled = false;
  EXPECT_EQ(cv::norm(applySensorModel(view, in, off, 1), view.depth_m, cv::NORM_INF), 0.0);
  const SensorModelConfig on;
  const cv::Mat a = applySensorModel(view, in, on, 11);
  const cv::Mat b = applySensorModel(view, in, on, 11);
  const cv::Mat c = applySensorModel(view, in, on, 12);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace objscan::capture
