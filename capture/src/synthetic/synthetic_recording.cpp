#include "objscan/capture/synthetic/synthetic_recording.h"

#include <tbb/parallel_invoke.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <string_view>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/image_codec.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"
#include "objscan/render/offscreen_renderer.h"

namespace objscan::capture {
namespace fs = std::filesystem;

namespace {

/// TUM's depth PNG convention: value / 5000 = metres (so at most 13.1 m).
constexpr double kDepthFactor = 5000.0;

void writePng(const fs::path& path, const cv::Mat& image) {
  // Into the recording's temporary folder, which is renamed into place whole.
  const std::string png = encodePng(image);
  std::ofstream out(path, std::ios::binary);
  if (!out.write(png.data(), static_cast<std::streamsize>(png.size())) || !out.flush()) {
    throw OutputError(path, "cannot write the PNG image");
  }
}

std::string stampName(double t) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6f", t);
  return buf;
}

nlohmann::json matrixJson(const Eigen::Matrix3f& R) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({R(r, 0), R(r, 1), R(r, 2)});
  return rows;
}

/// Pixels per object id 1..objects in a label image; index 0 counts every other pixel.
std::vector<std::size_t> countLabels(const cv::Mat& label, std::size_t objects) {
  std::vector<std::size_t> count(objects + 1, 0);
  for (int v = 0; v < label.rows; ++v) {
    const std::int32_t* row = label.ptr<std::int32_t>(v);
    for (int u = 0; u < label.cols; ++u) {
      const auto id = static_cast<std::size_t>(row[u]);
      ++count[row[u] > 0 && id <= objects ? id : 0];
    }
  }
  return count;
}

}  // namespace

SyntheticFrame renderSyntheticFrame(render::OffscreenRenderer& renderer, const Pose& T_W_C,
                                    std::size_t index, const SensorModelConfig& sensor,
                                    std::uint64_t noise_seed) {
  SyntheticFrame frame;
  frame.view = renderer.render(T_W_C);
  frame.depth_m =
      applySensorModel(frame.view, renderer.intrinsics(), sensor, noise_seed * 1000003ULL + index);
  return frame;
}

fs::path checkNewFolder(const fs::path& out_path) {
  // "out/" and "out" are the same folder; the temporary sibling must not land inside it.
  fs::path out_dir = out_path.lexically_normal();
  if (!out_dir.empty() && out_dir.filename().empty()) out_dir = out_dir.parent_path();
  if (out_dir.empty() || out_dir == "." || out_dir == "..") {
    throw std::invalid_argument("--out must name a new folder, not '" + out_path.string() + "'");
  }
  if (fs::exists(out_dir) && !(fs::is_directory(out_dir) && fs::is_empty(out_dir))) {
    throw std::invalid_argument(
        out_dir.string() +
        " already exists and is not an empty folder; remove it or choose another --out");
  }
  return out_dir;
}

SceneAndPath composeSceneSeenAlongPath(const SceneConfig& config,
                                       const HandheldPathConfig& path_config,
                                       const Intrinsics& intrinsics) {
  constexpr int kAttempts = 8;
  constexpr std::size_t kPoseStride = 10;
  constexpr std::size_t kMinPixels = 20;
  render::OffscreenRenderer renderer(intrinsics);
  SceneAndPath result;
  for (int attempt = 0; attempt < kAttempts; ++attempt) {
    SceneConfig c = config;
    c.seed = config.seed + static_cast<std::uint64_t>(attempt) * 1000003ULL;
    result.scene = composeScene(c);
    result.scene_seed = c.seed;
    HandheldPathConfig p = path_config;
    p.seed = c.seed;
    result.path = makeHandheldPath(result.scene, p);
    renderer.setMesh(result.scene.mesh);
    const std::size_t objects = result.scene.objects.size();
    std::vector<std::size_t> best(objects + 1, 0);
    for (std::size_t i = 0; i < result.path.size(); i += kPoseStride) {
      const std::vector<std::size_t> count =
          countLabels(renderer.render(result.path.poses[i].T_W_C).label, objects);
      for (std::size_t id = 1; id <= objects; ++id) best[id] = std::max(best[id], count[id]);
    }
    const auto hidden =
        std::count_if(best.begin() + 1, best.end(), [](std::size_t n) { return n < kMinPixels; });
    if (hidden == 0) return result;
    log::info("scene seed " + std::to_string(c.seed) + ": " + std::to_string(hidden) +
              " object(s) hidden along the path; composing again");
  }
  return result;
}

OrganizedCloud syntheticView(const SyntheticFrame& frame, const Intrinsics& intrinsics) {
  RgbdFrame rgbd;
  rgbd.depth_m = frame.depth_m;  // cv::Mat shares the pixels
  rgbd.color_rgb = frame.view.color_rgb;
  rgbd.intrinsics = intrinsics;
  OrganizedCloud cloud = cloudOfFrame(rgbd);
  cloud.labels.assign(cloud.points_C.size(), 0);
  for (int v = 0; v < cloud.height; ++v) {
    const std::int32_t* label = frame.view.label.ptr<std::int32_t>(v);
    for (int u = 0; u < cloud.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(cloud.width) +
                            static_cast<std::size_t>(u);
      if (!cloud.valid(i)) continue;
      cloud.labels[i] = label[u] > 0 ? 10u * static_cast<std::uint32_t>(label[u]) : 1u;
    }
  }
  return cloud;
}

std::vector<Visibility> writeSyntheticRecording(const SyntheticScene& scene, const Trajectory& path,
                                                const Intrinsics& intrinsics,
                                                const SensorModelConfig& sensor, std::uint64_t seed,
                                                const fs::path& out_path, ProgressBar* progress,
                                                std::size_t views) {
  sensor.validate();
  intrinsics.validate();
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    if (scene.objects[i].id != static_cast<std::int32_t>(i + 1)) {
      throw std::invalid_argument("synthetic recording: object ids must run 1..N in order");
    }
  }
  const fs::path out_dir = checkNewFolder(out_path);
  fs::path tmp = out_dir;
  tmp += ".tmp-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(tmp, ec);
  if (views > path.size()) {
    throw std::invalid_argument("synthetic recording: " + std::to_string(views) +
                                " views asked of " + std::to_string(path.size()) + " frames");
  }
  // The frames written as views: the middles of `views` equal stretches of the path.
  std::vector<bool> is_view(path.size(), false);
  for (std::size_t k = 0; k < views; ++k) is_view[(2 * k + 1) * path.size() / (2 * views)] = true;
  for (const char* sub : {"rgb", "depth", "label", "views"}) {
    if (std::string_view(sub) == "views" && views == 0) continue;
    fs::create_directories(tmp / sub, ec);
    if (ec) throw OutputError(tmp / sub, "cannot create the folder: " + ec.message());
  }

  try {
    render::OffscreenRenderer renderer(intrinsics);
    renderer.setMesh(scene.mesh);
    // Scene object ids run 1..N in order (composeScene): index by id.
    std::vector<Visibility> seen(scene.objects.size() + 1);
    for (const SceneObject& o : scene.objects) seen[static_cast<std::size_t>(o.id)].id = o.id;
    std::string rgb_txt = "# color images\n# timestamp filename\n";
    std::string depth_txt = "# depth maps\n# timestamp filename\n";
    std::string associations;
    for (std::size_t i = 0; i < path.size(); ++i) {
      const StampedPose& pose = path.poses[i];
      const SyntheticFrame frame = renderSyntheticFrame(renderer, pose.T_W_C, i, sensor, seed);
      const render::RenderedView& view = frame.view;
      const cv::Mat& depth_m = frame.depth_m;

      const std::vector<std::size_t> counts = countLabels(view.label, scene.objects.size());
      for (std::size_t id = 1; id < counts.size(); ++id) {
        seen[id].pixels += counts[id];
        seen[id].frames += counts[id] > 0 ? 1 : 0;
      }

      cv::Mat depth16, label16, bgr;
      depth_m.convertTo(depth16, CV_16UC1, kDepthFactor);  // saturates beyond 13.1 m
      depth16.setTo(0, depth_m * kDepthFactor > 65535.0);
      view.label.convertTo(label16, CV_16UC1);
      cv::cvtColor(view.color_rgb, bgr, cv::COLOR_RGB2BGR);
      const std::string stamp = stampName(pose.stamp_s);
      const std::string name = stamp + ".png";
      tbb::parallel_invoke([&] { writePng(tmp / "rgb" / name, bgr); },
                           [&] { writePng(tmp / "depth" / name, depth16); },
                           [&] { writePng(tmp / "label" / name, label16); });
      if (is_view[i]) writePcd(tmp / "views" / (stamp + ".pcd"), syntheticView(frame, intrinsics));
      rgb_txt += stamp + " rgb/" + name + "\n";
      depth_txt += stamp + " depth/" + name + "\n";
      associations += stamp + " rgb/" + name + " " + stamp + " depth/" + name + "\n";
      if (progress) progress->advance();
    }
    writeFileAtomically(tmp / "rgb.txt", rgb_txt);
    writeFileAtomically(tmp / "depth.txt", depth_txt);
    writeFileAtomically(tmp / "associations.txt", associations);
    writeTumTrajectory(tmp / "groundtruth.txt", path);

    writeIntrinsicsJson(tmp / "intrinsics.json", intrinsics, kDepthFactor);
    writePly(tmp / "scene_gt.ply", scene.mesh);

    nlohmann::json objects = nlohmann::json::array();
    std::vector<Visibility> visibility;
    for (const SceneObject& o : scene.objects) {
      const Eigen::Vector3f centre_W = o.T_W_O * (0.5f * (o.box_min_O + o.box_max_O));
      const Eigen::Quaternionf q(o.T_W_O.rotation());
      const Eigen::Vector3f t = o.T_W_O.translation();
      objects.push_back({{"id", o.id},
                         {"name", o.name},
                         {"pose",
                          {{"translation", {t.x(), t.y(), t.z()}},
                           {"quaternion_xyzw", {q.x(), q.y(), q.z(), q.w()}}}},
                         {"oriented_box",
                          {{"center", {centre_W.x(), centre_W.y(), centre_W.z()}},
                           {"extents",
                            {o.box_max_O.x() - o.box_min_O.x(), o.box_max_O.y() - o.box_min_O.y(),
                             o.box_max_O.z() - o.box_min_O.z()}},
                           {"rotation", matrixJson(o.T_W_O.rotation())}}},
                         {"vertex_count", o.vertex_count},
                         {"touching", o.touching},
                         {"stacked", o.stacked},
                         {"visible_pixels", seen[static_cast<std::size_t>(o.id)].pixels},
                         {"frames_visible", seen[static_cast<std::size_t>(o.id)].frames}});
      visibility.push_back(seen[static_cast<std::size_t>(o.id)]);
    }
    const nlohmann::json gt = {
        {"format", "objscan synthetic scene ground truth, version 1"},
        {"units", "metres; world frame z up, floor at z = 0"},
        {"preset", toString(scene.preset)},
        {"frames", path.size()},
        {"mesh", "scene_gt.ply (vertex property object_id: 0 = not an object)"},
        {"objects", objects}};
    writeFileAtomically(tmp / "scene_gt.json", gt.dump(2) + "\n");

    fs::remove(out_dir, ec);  // an empty folder (checked above), or nothing
    fs::rename(tmp, out_dir, ec);
    if (ec)
      throw OutputError(out_dir, "cannot move the finished recording into place: " + ec.message());
    return visibility;
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

std::map<std::int32_t, std::string> readSceneObjectNames(const fs::path& scene_gt_json) {
  std::map<std::int32_t, std::string> names;
  try {
    const nlohmann::json doc = nlohmann::json::parse(readWholeFile(scene_gt_json));
    for (const nlohmann::json& o : doc.at("objects")) {
      // objscan synth's "id", or a hand-labelled mesh's objects.json "label".
      names[o.at(o.contains("id") ? "id" : "label").get<std::int32_t>()] =
          o.value("name", std::string());
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(scene_gt_json,
                     std::string("not a scene_gt.json objscan synth writes: ") + e.what());
  }
  return names;
}

}  // namespace objscan::capture
