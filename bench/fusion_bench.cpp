// Fusion speed: objscan's KinectFusion loop and its stages next to Open3D's and OpenCV's on the
// same frames, in the same run (see fusion_peers.h for what each peer runs).
//
//   fusion_bench [--folder DIR] [--frames N] [--voxel M ...] [--peers-at first|all|none]
//                [--icp-iterations FINEST,MIDDLE,COARSEST] [--model-level L] [--finest-stride S]
//                [--json PATH]
//
// DIR defaults to <data>/7scenes_300, N to all of its frames, the voxel sizes to KinectFusion's
// 3 m / 512 (5.86 mm, the default) and 10 mm. Peers run at the first voxel size only unless
// --peers-at all. Every stage is given the same depth range (0.3-3 m), truncation (30 mm) and, where there is
// a pose solve, the same iterations per pyramid level. --model-level and --finest-stride change
// objscan's tracking settings (FusionConfig::model_level, TrackingConfig::finest_level_stride).
//
// What is timed, in milliseconds per frame:
//   full loop  objscan only: Fusion::process on every frame, tracking from the first ground-truth
//              pose (preprocess + track + integrate + raycast), with the ATE of its trajectory.
//   prepare    what tracking needs before the solve: objscan's filtered 3-level pyramid with
//              vertex and normal maps (in the loop); OpenCV's prepareFrameCache; Open3D's
//              intensity RGB-D images.
//   track      the pose solve alone: objscan frame-to-model ICP (in the loop); OpenCV
//              ICPOdometry::compute and Open3D's hybrid RGB-D odometry, frame to frame.
//   tracking, all per-frame work: prepare + track, plus objscan's model raycast (in the loop),
//              which frame-to-model ICP needs and frame-to-frame odometry does not.
//   integrate  every frame into a fresh volume at its ground-truth pose.
//   raycast    a 640x480 vertex and normal map from about 50 ground-truth poses, the same for
//              objscan and OpenCV (objscan without the depth hint the loop uses, so that it does
//              the same work as OpenCV's).
//   mesh       once, the volume of all frames (Open3D's ExtractTriangleMesh).
// Each system runs in its own process (this program again, with --child), so the kernel's
// high-water mark gives its peak memory: the loader's freed memory is handed back, the mark is
// reset after the frames are loaded, and the table shows the peak above that baseline.

#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "bench_main.h"
#include "bench_memory.h"
#include "build_paths.h"
#include "fusion_peers.h"
#include "objscan/capture/folder_source.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/trajectory.h"
#include "objscan/fusion/marching_cubes.h"
#include "objscan/fusion/pipeline.h"
#include "objscan/fusion/raycast.h"

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
using Json = nlohmann::json;
using objscan::bench::FusionBenchInput;
using objscan::bench::FusionBenchResult;
using objscan::bench::resetPeakMemory;
using objscan::bench::statusBytes;

constexpr double kPoseMatchS = 0.02;
const std::vector<std::string> kSystems = {"objscan", "open3d", "opencv"};

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

fs::path defaultFolder() {
  const char* env = std::getenv("OBJSCAN_DATA_DIR");
  return fs::path(env ? env : OBJSCAN_DATA_DIR) / "7scenes_300";
}

// --- memory --------------------------------------------------------------------------------

/// What a run is given on its command line (a child gets the same flags).
struct Settings {
  fs::path folder;
  std::size_t frames = 0;  ///< 0 = all
  float voxel_m = 0.01f;
  std::vector<int> icp_iterations = FusionBenchInput().icp_iterations;
  int model_level = objscan::fusion::FusionConfig().model_level;              ///< objscan's only
  int finest_stride = objscan::fusion::TrackingConfig().finest_level_stride;  ///< objscan's only
};

// --- input ---------------------------------------------------------------------------------

struct LoadedInput {
  FusionBenchInput frames;
  objscan::Intrinsics intrinsics;
  std::vector<double> stamps;
};

LoadedInput load(const Settings& settings) {
  const fs::path& folder = settings.folder;
  objscan::capture::FrameSelection selection;
  if (settings.frames > 0) selection.end = settings.frames;
  auto source = objscan::capture::openFolderSource(folder, selection);
  const objscan::capture::SourceInfo info = source->info();
  if (!info.ground_truth) throw std::runtime_error(folder.string() + " has no ground-truth poses");
  LoadedInput in;
  in.intrinsics = info.intrinsics;
  FusionBenchInput& f = in.frames;
  f.fx = info.intrinsics.fx_px;
  f.fy = info.intrinsics.fy_px;
  f.cx = info.intrinsics.cx_px;
  f.cy = info.intrinsics.cy_px;
  f.width = info.intrinsics.width_px;
  f.height = info.intrinsics.height_px;
  f.voxel_m = settings.voxel_m;
  f.icp_iterations = settings.icp_iterations;
  for (;;) {
    objscan::capture::FrameResult r = source->next();
    if (r.status == objscan::capture::FrameStatus::kEndOfStream) break;
    if (r.status != objscan::capture::FrameStatus::kOk) throw std::runtime_error(r.reason);
    const auto pose = objscan::nearestPose(*info.ground_truth, r.frame.stamp_s, kPoseMatchS);
    if (!pose) continue;  // every system gets only the frames with a ground-truth pose
    cv::Mat depth = r.frame.depth_m.clone();
    depth.setTo(0.0f, depth != depth);  // NaN -> no reading
    cv::Mat mm;
    depth.convertTo(mm, CV_16UC1, 1000.0);
    f.depth_m.push_back(depth);
    f.depth_mm.push_back(mm);
    f.color_rgb.push_back(r.frame.color_rgb.empty()
                              ? cv::Mat(depth.size(), CV_8UC3, cv::Scalar::all(128))
                              : r.frame.color_rgb);
    f.T_W_C.push_back(pose->matrix().cast<double>());
    in.stamps.push_back(r.frame.stamp_s);
  }
  if (f.depth_m.size() < 2) throw std::runtime_error(folder.string() + ": fewer than 2 frames");
  return in;
}

objscan::Pose poseAt(const FusionBenchInput& f, std::size_t i) {
  return objscan::Pose(f.T_W_C[i].cast<float>());
}

// --- objscan -------------------------------------------------------------------------------

FusionBenchResult runObjscan(const LoadedInput& loaded, const Settings& settings) {
  const FusionBenchInput& in = loaded.frames;
  const std::size_t n = in.depth_m.size();
  objscan::fusion::FusionConfig config;
  config.volume.voxel_size_m = in.voxel_m;
  config.volume.truncation_m = in.truncation_m;
  config.preprocess.min_depth_m = in.min_depth_m;
  config.preprocess.max_depth_m = in.max_depth_m;
  for (std::size_t l = 0; l < config.tracking.iterations.size(); ++l) {
    config.tracking.iterations[l] = l < in.icp_iterations.size() ? in.icp_iterations[l] : 0;
  }
  config.model_level = settings.model_level;
  config.tracking.finest_level_stride = settings.finest_stride;
  FusionBenchResult out;
  out.system = "objscan";
  out.notes["model_level"] = settings.model_level;
  out.notes["finest_level_stride"] = settings.finest_stride;

  // 1. The full loop, tracking. Its volume is freed before the next measurement, so the peak is
  // that of the loop or of a stage below, whichever is larger.
  {
    objscan::fusion::Fusion fusion(config, loaded.intrinsics, poseAt(in, 0));
    objscan::fusion::FrameTimings sum;
    std::size_t tracked = 0, iterations = 0;
    const auto loop_start = Clock::now();
    for (std::size_t i = 0; i < n; ++i) {
      objscan::RgbdFrame frame;
      frame.index = static_cast<std::int64_t>(i);
      frame.stamp_s = loaded.stamps[i];
      frame.depth_m = in.depth_m[i];
      frame.color_rgb = in.color_rgb[i];
      frame.intrinsics = loaded.intrinsics;
      const objscan::fusion::FrameOutcome o = fusion.process(frame);
      if (o.status != objscan::fusion::FrameStatus::kTracked) continue;
      ++tracked;
      iterations += static_cast<std::size_t>(o.tracking.iterations);
      sum += o.timings;
    }
    const double loop_s = msSince(loop_start) / 1e3;
    objscan::Trajectory truth;
    for (std::size_t i = 0; i < n; ++i) truth.poses.push_back({loaded.stamps[i], poseAt(in, i)});
    out.ate_rmse_m = objscan::absoluteTrajectoryError(fusion.trajectory(), truth).rmse_m;
    out.tracking_failures = fusion.framesLost();
    const double per = 1.0 / static_cast<double>(std::max<std::size_t>(tracked, 1));
    out.prepare_ms = sum.preprocess_ms * per;
    out.track_ms = sum.track_ms * per;
    out.notes["loop_fps"] = static_cast<double>(n) / loop_s;
    out.notes["loop_ms"] = {{"preprocess", sum.preprocess_ms * per},
                            {"track", sum.track_ms * per},
                            {"integrate", sum.integrate_ms * per},
                            {"raycast_with_hint", sum.raycast_ms * per}};
    out.notes["loop_icp_iterations_per_frame"] = static_cast<double>(iterations) * per;
    out.notes["loop_lost_frames"] = fusion.framesLost();
    out.notes["loop_blocks"] = fusion.volume().blockCount();
    out.notes["loop_volume_mb"] = static_cast<double>(fusion.volume().memoryBytes()) / 1e6;
  }

  // 2. Integration at the ground-truth poses (clipping the depth range included: the peers clip
  // inside their integrate calls).
  objscan::fusion::TsdfVolume volume(config.volume);
  double integrate_ms = 0.0;
  cv::Mat clipped;
  for (std::size_t i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    objscan::fusion::clipDepth(in.depth_m[i], config.preprocess, &clipped);
    volume.integrate(clipped, in.color_rgb[i], loaded.intrinsics, poseAt(in, i));
    integrate_ms += msSince(t0);
  }
  out.integrate_ms = integrate_ms / static_cast<double>(n);

  // 3. Raycasts from the same poses as the peers', without a hint, into reused maps (as
  // OpenCV's reuses its output arrays).
  double raycast_ms = 0.0;
  std::size_t casts = 0;
  objscan::fusion::ModelMaps maps;
  for (std::size_t i = 0; i < n; i += objscan::bench::raycastPoseStride(n), ++casts) {
    const auto t0 = Clock::now();
    objscan::fusion::raycast(volume, loaded.intrinsics, poseAt(in, i), in.min_depth_m,
                             in.max_depth_m, false, nullptr, &maps);
    raycast_ms += msSince(t0);
  }
  out.raycast_ms = raycast_ms / static_cast<double>(casts);

  // 4. Meshing.
  const auto t0 = Clock::now();
  const objscan::TriangleMesh mesh = objscan::fusion::extractMesh(volume);
  out.mesh_ms = msSince(t0);
  out.mesh_vertices = mesh.positions.size();
  out.mesh_triangles = mesh.triangles.size();
  out.notes["blocks"] = volume.blockCount();
  out.notes["iterations_finest_first"] = in.icp_iterations;
  return out;
}

// --- results as JSON -----------------------------------------------------------------------

Json number(double x) { return std::isfinite(x) ? Json(x) : Json(); }

double number(const Json& j) {
  return j.is_number() ? j.get<double>() : objscan::bench::kNotMeasured;
}

Json toJson(const FusionBenchResult& r) {
  return {{"system", r.system},
          {"integrate_ms", number(r.integrate_ms)},
          {"raycast_ms", number(r.raycast_ms)},
          {"prepare_ms", number(r.prepare_ms)},
          {"track_ms", number(r.track_ms)},
          {"mesh_ms", number(r.mesh_ms)},
          {"mesh_vertices", r.mesh_vertices},
          {"mesh_triangles", r.mesh_triangles},
          {"ate_rmse_m", number(r.ate_rmse_m)},
          {"tracking_failures", r.tracking_failures},
          {"notes", r.notes}};
}

/// Runs one system on the frames and writes its result (with peak memory) to `out`.
int runChild(const std::string& system, const Settings& settings, const fs::path& out) {
  const LoadedInput loaded = load(settings);
  malloc_trim(0);  // what the loader freed goes back to the kernel, and counts when reused
  const double baseline = statusBytes("VmRSS");
  const bool peak_measurable = resetPeakMemory();
  FusionBenchResult r;
  if (system == "objscan") {
    r = runObjscan(loaded, settings);
  } else if (system == "open3d") {
    r = objscan::bench::runOpen3dPeer(loaded.frames);
  } else if (system == "opencv") {
    r = objscan::bench::runOpenCvPeer(loaded.frames);
  } else {
    throw std::invalid_argument("unknown system " + system);
  }
  Json j = toJson(r);
  j["frames"] = loaded.frames.depth_m.size();
  j["peak_mb_above_frames"] =
      peak_measurable ? Json((statusBytes("VmHWM") - baseline) / 1e6) : Json();
  objscan::writeFileAtomically(out, j.dump(2) + "\n");
  return 0;
}

/// Runs `self --child SYSTEM ...` and returns what it wrote.
Json spawnChild(const std::string& self, const std::string& system, const Settings& settings) {
  char voxel_text[32];
  std::snprintf(voxel_text, sizeof voxel_text, "%.9g", static_cast<double>(settings.voxel_m));
  std::string iterations;
  for (int n : settings.icp_iterations) {
    if (!iterations.empty()) iterations.append(",");
    iterations.append(std::to_string(n));
  }
  const fs::path out =
      fs::temp_directory_path() /
      ("objscan_fusion_bench_" + std::to_string(getpid()) + "_" + system + ".json");
  const std::vector<std::string> args = {self,
                                         "--child",
                                         system,
                                         "--folder",
                                         settings.folder.string(),
                                         "--frames",
                                         std::to_string(settings.frames),
                                         "--voxel",
                                         voxel_text,
                                         "--icp-iterations",
                                         iterations,
                                         "--model-level",
                                         std::to_string(settings.model_level),
                                         "--finest-stride",
                                         std::to_string(settings.finest_stride),
                                         "--child-out",
                                         out.string()};
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    execv("/proc/self/exe", argv.data());
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw std::runtime_error("the " + system + " run failed (exit status " +
                             std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")");
  }
  std::ifstream file(out);
  Json j = Json::parse(file);
  fs::remove(out);
  return j;
}

// --- the table -----------------------------------------------------------------------------

std::string cell(double x, const char* format = "%.1f") {
  if (!std::isfinite(x)) return "-";
  char text[32];
  std::snprintf(text, sizeof text, format, x);
  return text;
}

/// "3.2x" for peer / objscan time (higher: objscan faster).
std::string ratio(double peer, double ours) {
  if (!std::isfinite(peer) || !std::isfinite(ours) || ours <= 0.0) return "-";
  return cell(peer / ours, "%.1fx");
}

void printRow(const std::string& name, const Json& systems, const std::string& key,
              const char* format = "%.1f") {
  const auto at = [&](const std::string& s) {
    return systems.contains(s) ? number(systems[s][key]) : objscan::bench::kNotMeasured;
  };
  std::printf("  %-34s %10s %10s %10s %12s %12s\n", name.c_str(),
              cell(at("objscan"), format).c_str(), cell(at("open3d"), format).c_str(),
              cell(at("opencv"), format).c_str(), ratio(at("open3d"), at("objscan")).c_str(),
              ratio(at("opencv"), at("objscan")).c_str());
}

/// Prints one voxel size's table and returns its targets as JSON.
Json report(const Json& systems, float voxel_m, std::size_t frames, const fs::path& folder) {
  const Json& ours = systems["objscan"];
  const Json& loop = ours["notes"]["loop_ms"];
  std::printf("\nfusion: %s, %zu frames, voxel %.2f mm, truncation 30 mm, depth 0.3-3 m\n",
              folder.filename().string().c_str(), frames, 1e3 * voxel_m);
  std::printf(
      "  full loop (objscan): %.1f frames/s; per frame preprocess %.1f, track %.1f, "
      "integrate %.1f, raycast %.1f ms; %.1f ICP steps per frame; %d lost; ATE %.1f mm\n",
      number(ours["notes"]["loop_fps"]), number(loop["preprocess"]), number(loop["track"]),
      number(loop["integrate"]), number(loop["raycast_with_hint"]),
      number(ours["notes"]["loop_icp_iterations_per_frame"]), ours["tracking_failures"].get<int>(),
      1e3 * number(ours["ate_rmse_m"]));
  std::printf("  %-34s %10s %10s %10s %12s %12s\n", "ms per frame (mesh: once)", "objscan",
              "Open3D", "OpenCV", "Open3D/ours", "OpenCV/ours");
  printRow("prepare for tracking", systems, "prepare_ms");
  printRow("track (pose solve)", systems, "track_ms");
  printRow("tracking, all per-frame work (*)", systems, "tracking_total_ms");
  printRow("integrate (ground-truth poses)", systems, "integrate_ms");
  printRow("raycast 640x480", systems, "raycast_ms");
  printRow("mesh the whole volume", systems, "mesh_ms");
  printRow("mesh vertices (thousands)", systems, "mesh_kvertices");
  printRow("peak memory above the frames, MB", systems, "peak_mb_above_frames", "%.0f");
  printRow("tracking ATE RMSE, mm", systems, "ate_mm");
  printRow("tracking failures", systems, "tracking_failures", "%.0f");

  const auto get = [&](const std::string& s, const std::string& key) {
    return systems.contains(s) ? number(systems[s][key]) : objscan::bench::kNotMeasured;
  };
  Json targets = Json::object();
  const auto target = [&](const std::string& name, double value, double goal) {
    const bool met = std::isfinite(value) && value >= goal;
    targets[name] = {{"value", number(value)}, {"target", goal}, {"met", met}};
    std::printf("  target %-40s %8s  (>= %.0f)  %s\n", name.c_str(), cell(value, "%.2f").c_str(),
                goal, std::isfinite(value) ? (met ? "met" : "NOT MET") : "not measured");
  };
  // The fusion speed-up's target: real time at the default voxel size (KinectFusion's 3 m / 512).
  target("full loop frames/s at the default 5.86 mm",
         std::abs(voxel_m - 3.0f / 512.0f) < 1e-6f ? number(ours["notes"]["loop_fps"])
                                                   : objscan::bench::kNotMeasured,
         30.0);
  const double integrate = get("objscan", "integrate_ms");
  target("integration vs Open3D", get("open3d", "integrate_ms") / integrate, 2.0);
  target("integration vs OpenCV", get("opencv", "integrate_ms") / integrate, 2.0);
  target("tracking vs OpenCV ICPOdometry", get("opencv", "track_ms") / get("objscan", "track_ms"),
         2.0);
  target("tracking, all per-frame work (*), vs OpenCV",
         get("opencv", "tracking_total_ms") / get("objscan", "tracking_total_ms"), 2.0);
  target("meshing vs Open3D", get("open3d", "mesh_ms") / get("objscan", "mesh_ms"), 3.0);
  std::printf(
      "  (*) prepare + track, and for objscan also the model raycast that its "
      "frame-to-model ICP needs\n");
  return targets;
}

int run(int argc, char** argv) {
  Settings settings;
  settings.folder = defaultFolder();
  fs::path child_out;
  std::vector<float> voxels;
  std::string json_path, child, peers_at = "first";
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    const bool has_value = i + 1 < argc;
    if (flag == "--folder" && has_value) {
      settings.folder = argv[++i];
    } else if (flag == "--frames" && has_value) {
      settings.frames = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (flag == "--voxel" && has_value) {
      voxels.push_back(static_cast<float>(std::atof(argv[++i])));
    } else if (flag == "--peers-at" && has_value) {
      peers_at = argv[++i];
    } else if (flag == "--icp-iterations" && has_value) {
      settings.icp_iterations.clear();
      std::stringstream list(argv[++i]);
      for (std::string item; std::getline(list, item, ',');) {
        settings.icp_iterations.push_back(std::stoi(item));
      }
    } else if (flag == "--model-level" && has_value) {
      settings.model_level = std::atoi(argv[++i]);
    } else if (flag == "--finest-stride" && has_value) {
      settings.finest_stride = std::atoi(argv[++i]);
    } else if (flag == "--json" && has_value) {
      json_path = argv[++i];
    } else if (flag == "--child" && has_value) {
      child = argv[++i];
    } else if (flag == "--child-out" && has_value) {
      child_out = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: fusion_bench [--folder DIR] [--frames N] [--voxel M ...] "
                   "[--peers-at first|all|none] [--icp-iterations FINEST,...] [--model-level L] "
                   "[--finest-stride S] [--json PATH]\n");
      return 2;
    }
  }
  if (voxels.empty()) voxels = {3.0f / 512.0f, 0.01f};
  for (float v : voxels) {
    if (!(v >= 0.001f && v <= 0.5f)) throw std::invalid_argument("--voxel must be 0.001 to 0.5 m");
  }
  if (settings.icp_iterations.empty() || settings.icp_iterations.size() > 3) {
    throw std::invalid_argument("--icp-iterations takes 1 to 3 counts, finest level first");
  }
  if (!child.empty()) {
    settings.voxel_m = voxels.front();
    return runChild(child, settings, child_out);
  }

  Json all = {{"folder", settings.folder.string()},
              {"icp_iterations_finest_first", settings.icp_iterations},
              {"runs", Json::array()}};
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  for (std::size_t k = 0; k < voxels.size(); ++k) {
    const bool peers = peers_at == "all" || (peers_at == "first" && k == 0);
    Json systems = Json::object();
    for (const std::string& system : kSystems) {
      if (system != "objscan" && !peers) continue;
      std::fprintf(stderr, "fusion_bench: %s at %.2f mm...\n", system.c_str(), 1e3 * voxels[k]);
      settings.voxel_m = voxels[k];
      Json r = spawnChild(self, system, settings);
      r["mesh_kvertices"] =
          r["mesh_ms"].is_number() ? Json(r["mesh_vertices"].get<double>() / 1e3) : Json();
      r["ate_mm"] =
          r["ate_rmse_m"].is_number() ? Json(1e3 * r["ate_rmse_m"].get<double>()) : Json();
      // What tracking costs per frame: a peer prepares each frame and solves; objscan also casts
      // the model its next solve matches against.
      const double model_ms =
          system == "objscan" ? number(r["notes"]["loop_ms"]["raycast_with_hint"]) : 0.0;
      r["tracking_total_ms"] = number(number(r["prepare_ms"]) + number(r["track_ms"]) + model_ms);
      systems[system] = r;
    }
    const std::size_t n = systems["objscan"]["frames"].get<std::size_t>();
    Json targets = report(systems, voxels[k], n, settings.folder);
    all["frames"] = n;
    all["runs"].push_back({{"voxel_m", voxels[k]}, {"systems", systems}, {"targets", targets}});
  }
  if (!json_path.empty()) objscan::writeFileAtomically(json_path, all.dump(2) + "\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("fusion_bench", run, argc, argv);
}
