#include "objscan/render/offscreen_renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace objscan::render {
namespace {

/// A square of side 2 * half_m in the plane z = 0 of its own frame, transformed by T.
TriangleMesh square(const Pose& T, float half_m, std::int32_t label) {
  TriangleMesh m;
  for (const auto& [x, y] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
    m.positions.push_back(T * Eigen::Vector3f(x * half_m, y * half_m, 0.0f));
  }
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  m.labels.assign(4, label);
  return m;
}

/// A UV sphere; `segments` around, segments / 2 from pole to pole.
TriangleMesh sphere(const Eigen::Vector3f& centre, float radius, int segments) {
  TriangleMesh m;
  const int rings = segments / 2;
  for (int i = 0; i <= rings; ++i) {
    const double theta = std::numbers::pi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * std::numbers::pi * j / segments;
      m.positions.push_back(centre + radius * Eigen::Vector3d(std::sin(theta) * std::cos(phi),
                                                              std::sin(theta) * std::sin(phi),
                                                              std::cos(theta))
                                                  .cast<float>());
    }
  }
  auto id = [&](int i, int j) { return i * segments + (j % segments); };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      if (i > 0) m.triangles.emplace_back(id(i, j), id(i + 1, j), id(i, j + 1));
      if (i + 1 < rings) m.triangles.emplace_back(id(i, j + 1), id(i + 1, j), id(i + 1, j + 1));
    }
  }
  return m;
}

Eigen::Vector3d ray(const Intrinsics& in, int u, int v) {
  return {(u - in.cx_px) / in.fx_px, (v - in.cy_px) / in.fy_px, 1.0};
}

TEST(OffscreenRenderer, TiltedPlaneDepthMatchesAnalyticWithinHalfMillimetre) {
  const Intrinsics in = Intrinsics::xtionDefault();
  OffscreenRenderer renderer(in);
  // A plane through (0, 0, 1.5) tilted 35 degrees about x and 20 about y, seen from a camera at
  // the world origin rotated a little, so neither frame is trivial.
  Pose T_W_P = Pose::Identity();
  T_W_P.linear() = (Eigen::AngleAxisf(0.61f, Eigen::Vector3f::UnitX()) *
                    Eigen::AngleAxisf(0.35f, Eigen::Vector3f::UnitY()))
                       .toRotationMatrix();
  T_W_P.translation() = Eigen::Vector3f(0.1f, -0.05f, 1.5f);
  renderer.setMesh(square(T_W_P, 5.0f, 4));
  Pose T_W_C = Pose::Identity();
  T_W_C.linear() =
      Eigen::AngleAxisf(0.05f, Eigen::Vector3f(0.3f, 1.0f, 0.2f).normalized()).toRotationMatrix();
  const RenderedView view = renderer.render(T_W_C);

  // The plane in the camera frame: n . p = d.
  const Pose T_C_P = T_W_C.inverse() * T_W_P;
  const Eigen::Vector3d n = T_C_P.linear().col(2).cast<double>();
  const double d = n.dot(T_C_P.translation().cast<double>());
  double worst_m = 0.0;
  int valid = 0;
  for (int v = 0; v < in.height_px; ++v) {
    for (int u = 0; u < in.width_px; ++u) {
      const double z = d / n.dot(ray(in, u, v));
      const float rendered = view.depth_m.at<float>(v, u);
      ASSERT_GT(rendered, 0.0f) << "the plane fills the view; pixel " << u << ", " << v;
      worst_m = std::max(worst_m, std::abs(rendered - z));
      ++valid;
      ASSERT_EQ(view.label.at<std::int32_t>(v, u), 4);
      // |cos| of the angle between the plane's normal and the ray through the pixel.
      const Eigen::Vector3d r = ray(in, u, v).normalized();
      ASSERT_NEAR(view.cos_incidence.at<float>(v, u), std::abs(n.dot(r)), 1e-4);
    }
  }
  EXPECT_EQ(valid, in.width_px * in.height_px);
  EXPECT_LT(worst_m, 0.0005) << "worst depth error, m";
}

TEST(OffscreenRenderer, SphereDepthMatchesAnalyticWithinHalfMillimetre) {
  const Intrinsics in = Intrinsics::xtionDefault();
  OffscreenRenderer renderer(in);
  const Eigen::Vector3d c(0.05, -0.03, 1.2);
  const double r = 0.3;
  TriangleMesh ball = sphere(c.cast<float>(), static_cast<float>(r), 512);
  ball.labels.assign(ball.positions.size(), 9);
  renderer.setMesh(ball);
  const RenderedView view = renderer.render(Pose::Identity());

  double worst_m = 0.0;
  int compared = 0, rendered_only = 0, analytic_only = 0;
  for (int v = 0; v < in.height_px; ++v) {
    for (int u = 0; u < in.width_px; ++u) {
      const Eigen::Vector3d dir = ray(in, u, v);
      // |t dir - c|^2 = r^2, nearest root; z = t because dir.z = 1.
      const double a = dir.squaredNorm(), b = -2.0 * dir.dot(c), cc = c.squaredNorm() - r * r;
      const double disc = b * b - 4 * a * cc;
      const float rendered = view.depth_m.at<float>(v, u);
      if (disc < 0) {
        rendered_only += rendered > 0.0f;
        continue;
      }
      const double z = (-b - std::sqrt(disc)) / (2 * a);
      if (rendered == 0.0f) {
        ++analytic_only;
        continue;
      }
      EXPECT_EQ(view.label.at<std::int32_t>(v, u), 9);
      // Distance of the ray from the centre, in pixels at the sphere: skip the outermost 2 px,
      // where any tessellation (here 512 x 256) departs from the sphere along grazing rays.
      const double ray_offset_m = dir.cross(c).norm() / dir.norm();
      const double margin_m = 2.0 * c.z() / in.fx_px;
      if (ray_offset_m > r - margin_m) continue;
      worst_m = std::max(worst_m, std::abs(rendered - z));
      ++compared;
    }
  }
  EXPECT_GT(compared, 60000);  // the disc is about 150 px in radius
  EXPECT_LT(worst_m, 0.0005) << "worst depth error, m";
  EXPECT_EQ(rendered_only, 0) << "rendered pixels outside the true silhouette";
  EXPECT_LT(analytic_only, 40) << "silhouette pixels the tessellated sphere misses";
}

TEST(OffscreenRenderer, NearerSurfaceWinsAndBackgroundIsEmpty) {
  const Intrinsics in = Intrinsics::xtionDefault();
  OffscreenRenderer renderer(in);
  Pose far = Pose::Identity(), near = Pose::Identity();
  far.translation() = Eigen::Vector3f(0, 0, 2.0f);
  near.translation() = Eigen::Vector3f(0.3f, 0, 1.0f);
  TriangleMesh scene = square(far, 0.5f, 1);
  const TriangleMesh front = square(near, 0.1f, 2);
  for (const auto& t : front.triangles) scene.triangles.push_back(t + Eigen::Vector3i::Constant(4));
  scene.positions.insert(scene.positions.end(), front.positions.begin(), front.positions.end());
  scene.labels.insert(scene.labels.end(), front.labels.begin(), front.labels.end());
  renderer.setMesh(scene);
  const RenderedView view = renderer.render(Pose::Identity());
  // Pixel of (0.3, 0, 1.0): u = 570.3 * 0.3 + 319.5 = 490.6 -> 491; v = 239.5 -> 240.
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(240, 491), 1.0f);
  EXPECT_EQ(view.label.at<std::int32_t>(240, 491), 2);
  EXPECT_FLOAT_EQ(view.depth_m.at<float>(240, 320), 2.0f);
  EXPECT_EQ(view.label.at<std::int32_t>(240, 320), 1);
  EXPECT_EQ(view.depth_m.at<float>(5, 5), 0.0f) << "corner sees nothing";
  EXPECT_EQ(view.label.at<std::int32_t>(5, 5), 0);
  EXPECT_EQ(view.color_rgb.at<cv::Vec3b>(5, 5), cv::Vec3b(0, 0, 0));
  EXPECT_GT(view.color_rgb.at<cv::Vec3b>(240, 320)[0], 100) << "lit grey surface";
}

}  // namespace
}  // namespace objscan::render
