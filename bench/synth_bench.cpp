// Synthetic-capture throughput: a 20-object desk scene at 640x480 along the default hand-held
// path. Times each stage separately (OSMesa render, sensor model, PNG encoding of the three
// images) and prints frames per second.
//
// No peer runs here: the natural ones are unusable on Debian 12 (Open3D's off-screen renderer
// needs EGL, its RaycastingScene returns no hits with Debian's Embree; DESIGN.md, "Known traps").
//
//   synth_bench [--frames N] [--objects N] [--picture out.png]
// --picture writes colour | depth | labels of the middle frame side by side (docs/).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bench_main.h"
#include "objscan/capture/synthetic/sensor_model.h"
#include "objscan/capture/synthetic/synthetic_scene.h"
#include "objscan/render/offscreen_renderer.h"

namespace {

using Clock = std::chrono::steady_clock;

double ms(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

/// Depth as a colour map (turbo, 0.4-3 m), no reading black.
cv::Mat depthPicture(const cv::Mat& depth_m) {
  cv::Mat scaled;
  depth_m.convertTo(scaled, CV_8UC1, 255.0 / 2.6, -255.0 * 0.4 / 2.6);
  cv::Mat colour;
  cv::applyColorMap(scaled, colour, cv::COLORMAP_TURBO);
  colour.setTo(cv::Scalar(0, 0, 0), depth_m == 0.0f);
  return colour;
}

/// Labels as distinct colours, 0 (not an object) dark grey.
cv::Mat labelPicture(const cv::Mat& label) {
  cv::Mat out(label.size(), CV_8UC3);
  for (int v = 0; v < label.rows; ++v) {
    for (int u = 0; u < label.cols; ++u) {
      const int id = label.at<std::int32_t>(v, u);
      out.at<cv::Vec3b>(v, u) = id == 0 ? cv::Vec3b(50, 50, 50)
                                        : cv::Vec3b(static_cast<uchar>((id * 97) % 200 + 55),
                                                    static_cast<uchar>((id * 57) % 200 + 55),
                                                    static_cast<uchar>((id * 151) % 200 + 55));
    }
  }
  return out;
}

}  // namespace

int run(int argc, char** argv) {
  int frames = 300, objects = 20;
  std::string picture;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--frames")
      frames = std::max(1, std::atoi(argv[i + 1]));
    else if (flag == "--objects")
      objects = std::atoi(argv[i + 1]);
    else if (flag == "--picture")
      picture = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: synth_bench [--frames N] [--objects N] [--picture out.png]\n");
      return 2;
    }
  }
  using namespace objscan;
  capture::SceneConfig scene_config;
  scene_config.objects = objects;
  const auto t0 = Clock::now();
  const capture::SyntheticScene scene = capture::composeScene(scene_config);
  capture::HandheldPathConfig path_config;
  path_config.frames = frames;
  const Trajectory path = capture::makeHandheldPath(scene, path_config);
  const Intrinsics in = Intrinsics::xtionDefault();
  render::OffscreenRenderer renderer(in);
  renderer.setMesh(scene.mesh);
  const auto t1 = Clock::now();

  double render_ms = 0, noise_ms = 0, encode_ms = 0;
  const capture::SensorModelConfig sensor;
  for (std::size_t i = 0; i < path.size(); ++i) {
    const auto a = Clock::now();
    const render::RenderedView view = renderer.render(path.poses[i].T_W_C);
    const auto b = Clock::now();
    const cv::Mat depth = capture::applySensorModel(view, in, sensor, i);
    const auto c = Clock::now();
    std::vector<uchar> buffer;
    cv::Mat depth16, label16;
    depth.convertTo(depth16, CV_16UC1, 5000.0);
    view.label.convertTo(label16, CV_16UC1);
    cv::imencode(".png", view.color_rgb, buffer);
    cv::imencode(".png", depth16, buffer);
    cv::imencode(".png", label16, buffer);
    const auto d = Clock::now();
    render_ms += ms(a, b);
    noise_ms += ms(b, c);
    encode_ms += ms(c, d);
    if (!picture.empty() && i == path.size() / 2) {
      cv::Mat bgr, side;
      cv::cvtColor(view.color_rgb, bgr, cv::COLOR_RGB2BGR);
      cv::hconcat(std::vector<cv::Mat>{bgr, depthPicture(depth), labelPicture(view.label)}, side);
      if (!cv::imwrite(picture, side)) {
        std::fprintf(stderr, "synth_bench: cannot write %s\n", picture.c_str());
        return 1;
      }
    }
  }
  const double n = static_cast<double>(path.size());
  std::printf(
      "synthetic capture: desk, %zu objects, %zu vertices / %zu triangles, %dx%d, %zu frames\n",
      scene.objects.size(), scene.mesh.positions.size(), scene.mesh.triangles.size(), in.width_px,
      in.height_px, path.size());
  std::printf("  scene + path + upload   %8.1f ms once\n", ms(t0, t1));
  std::printf("  render (OSMesa)         %8.2f ms/frame  %7.1f frames/s\n", render_ms / n,
              1000.0 * n / render_ms);
  std::printf("  sensor model            %8.2f ms/frame  %7.1f frames/s\n", noise_ms / n,
              1000.0 * n / noise_ms);
  std::printf("  render + sensor model   %8.2f ms/frame  %7.1f frames/s  (target >= 60)\n",
              (render_ms + noise_ms) / n, 1000.0 * n / (render_ms + noise_ms));
  std::printf("  PNG encode (3 images)   %8.2f ms/frame  %7.1f frames/s\n", encode_ms / n,
              1000.0 * n / encode_ms);
  std::printf("  all stages, one thread  %8.2f ms/frame  %7.1f frames/s\n",
              (render_ms + noise_ms + encode_ms) / n,
              1000.0 * n / (render_ms + noise_ms + encode_ms));
  return 0;
}

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("synth_bench", run, argc, argv);
}
