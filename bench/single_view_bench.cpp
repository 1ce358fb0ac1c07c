// Single views: `objscan discover scene.pcd` against PCL's segmentations of the same labelled
// camera clouds (organized PCD, mOSD's label convention), time and recall side by side.
//
//   single_view_bench <scene.pcd>... [--repeat N] [--json FILE]
//
// Per scene, each method's wall time is the median of N runs (default 3), loading included:
//   objscan   the whole `objscan discover scene.pcd --out TMP --no-catalog` command, run as a
//             process (what a user waits for: start-up, PCD reading, meshing, discovery, writing
//             hypotheses.json and objects/);
//   LCCP      pcl::io::loadPCDFile, supervoxels and LCCP with PCL's example settings (voxel
//             7.5 mm, normal importance 4, concavity tolerance 10 deg, extended convexity,
//             sanity criterion, smoothness check 0.1) and the single-camera transform that PCL
//             advises for one camera's view; seeds of 2 cm, the best for LCCP of 3 cm, 2 cm and
//             1.5 cm (voxel 5 mm) on learn5, 19, 27 and 36 (0.91 recall@0.5 against 0.71 with
//             PCL's 3 cm default);
//   plane+EC  loadPCDFile, RANSAC's dominant plane (1 cm) removed, Euclidean clusters of 2 cm
//             (at least 50 points): the usual table-top baseline.
// Recall is per scene, over the object parts of the label field (each part an object, as the
// database intends): the share of objects some segment covers at IoU 0.5 / 0.7, over the pixels
// with a reading (evaluateRanking, the one definition eval uses). objscan's figures come from an
// in-process run of the same discovery on the scene alone (no catalog, its measures normalised
// over its own candidates, as one `discover` call does; `objscan eval` normalises over all its
// scenes together, which gives a different AP): its ranked hypotheses, recall and AP by
// sceneRecall. The peers' segments are not ranked, so they have recall only.
// The ratio column is objscan's time over the peer's: below 1, objscan is faster.

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <pcl/filters/filter.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/lccp_segmentation.h>
#include <pcl/segmentation/sac_segmentation.h>
#include <pcl/segmentation/supervoxel_clustering.h>
#include <nlohmann/json.hpp>

#include "bench_main.h"
#include "build_paths.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/organized_cloud.h"
#include "objscan/discovery/evaluation.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scenes.h"

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using Point = pcl::PointXYZRGBA;
using Cloud = pcl::PointCloud<Point>;

constexpr const char* kUsage = "usage: single_view_bench <scene.pcd>... [--repeat N] [--json FILE]";

double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  const std::size_t n = x.size();
  return n % 2 == 1 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

double secondsOf(const std::function<void()>& f) {
  const auto start = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Runs a program with its output thrown away; throws when it fails.
void runQuietly(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int error = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (error != 0) throw std::runtime_error("cannot run " + args[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw std::runtime_error(args[0] + " " + args[1] + " " + args[2] + " failed");
  }
}

/// Recall at IoU 0.5 and 0.7 of unranked segments (lists of pixel indices) against the objects
/// of `truth` (over pixel indices): evaluateRanking's share of objects found, which does not
/// depend on the order.
std::pair<double, double> recallOf(const std::vector<std::vector<std::int32_t>>& segments,
                                   const objscan::discovery::GroundTruthObjects& truth) {
  const auto at = [&](double iou) {
    const objscan::discovery::RankingEvaluation e =
        objscan::discovery::evaluateRanking(truth, segments, iou);
    return e.objects ? static_cast<double>(e.found) / static_cast<double>(e.objects) : 0.0;
  };
  return {at(0.5), at(0.7)};
}

/// Pixel-index segments from a label per pixel (0: none).
std::vector<std::vector<std::int32_t>> segmentsOfLabels(const std::vector<std::uint32_t>& labels) {
  std::map<std::uint32_t, std::vector<std::int32_t>> by_label;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] != 0) by_label[labels[i]].push_back(static_cast<std::int32_t>(i));
  }
  std::vector<std::vector<std::int32_t>> out;
  for (auto& [label, pixels] : by_label) out.push_back(std::move(pixels));
  return out;
}

Cloud::Ptr loadCloud(const std::string& path) {
  Cloud::Ptr cloud(new Cloud);
  if (pcl::io::loadPCDFile(path, *cloud) != 0) throw std::runtime_error("PCL cannot read " + path);
  return cloud;
}

/// PCL's LCCP (supervoxels, then convexity merging): a segment label per pixel.
std::vector<std::uint32_t> lccp(const Cloud::Ptr& cloud) {
  const float voxel = 0.0075f, seed = 0.02f;
  pcl::SupervoxelClustering<Point> supervoxels(voxel, seed);
  supervoxels.setUseSingleCameraTransform(true);  // one camera's view
  supervoxels.setInputCloud(cloud);
  supervoxels.setColorImportance(0.0f);
  supervoxels.setSpatialImportance(1.0f);
  supervoxels.setNormalImportance(4.0f);
  std::map<std::uint32_t, pcl::Supervoxel<Point>::Ptr> clusters;
  supervoxels.extract(clusters);
  std::multimap<std::uint32_t, std::uint32_t> adjacency;
  supervoxels.getSupervoxelAdjacency(adjacency);
  pcl::LCCPSegmentation<Point> segmentation;
  segmentation.setConcavityToleranceThreshold(10.0f);
  segmentation.setSanityCheck(true);
  segmentation.setSmoothnessCheck(true, voxel, seed, 0.1f);
  segmentation.setKFactor(1);  // extended convexity
  segmentation.setMinSegmentSize(0);
  segmentation.setInputSupervoxels(clusters, adjacency);
  segmentation.segment();
  pcl::PointCloud<pcl::PointXYZL>::Ptr labelled = supervoxels.getLabeledCloud();
  segmentation.relabelCloud(*labelled);
  std::vector<std::uint32_t> labels(labelled->size());
  for (std::size_t i = 0; i < labelled->size(); ++i) labels[i] = (*labelled)[i].label;
  return labels;
}

/// The table-top baseline: the dominant plane removed, Euclidean clusters of the rest.
std::vector<std::uint32_t> planeAndClusters(const Cloud::Ptr& cloud) {
  Cloud::Ptr finite(new Cloud);
  pcl::Indices pixel_of;
  pcl::removeNaNFromPointCloud(*cloud, *finite, pixel_of);
  pcl::SACSegmentation<Point> sac;
  sac.setModelType(pcl::SACMODEL_PLANE);
  sac.setMethodType(pcl::SAC_RANSAC);
  sac.setDistanceThreshold(0.01);
  sac.setMaxIterations(200);
  sac.setInputCloud(finite);
  pcl::PointIndices::Ptr plane(new pcl::PointIndices);
  pcl::ModelCoefficients coefficients;
  sac.segment(*plane, coefficients);
  std::vector<bool> on_plane(finite->size(), false);
  for (int i : plane->indices) on_plane[static_cast<std::size_t>(i)] = true;
  pcl::IndicesPtr rest(new pcl::Indices);
  for (std::size_t i = 0; i < finite->size(); ++i) {
    if (!on_plane[i]) rest->push_back(static_cast<pcl::index_t>(i));
  }
  pcl::EuclideanClusterExtraction<Point> clustering;
  clustering.setClusterTolerance(0.02);
  clustering.setMinClusterSize(50);
  clustering.setInputCloud(finite);
  clustering.setIndices(rest);
  std::vector<pcl::PointIndices> clusters;
  clustering.extract(clusters);
  std::vector<std::uint32_t> labels(cloud->size(), 0);
  for (std::size_t c = 0; c < clusters.size(); ++c) {
    for (int i : clusters[c].indices) {
      labels[static_cast<std::size_t>(pixel_of[static_cast<std::size_t>(i)])] =
          static_cast<std::uint32_t>(c + 1);
    }
  }
  return labels;
}

struct Method {
  explicit Method(std::string n) : name(std::move(n)) {}
  std::string name;
  std::vector<double> seconds, recall_05, recall_07, ap_05;  ///< per scene
  std::vector<double> segments;
};

int run(int argc, char** argv) {
  std::vector<std::string> scenes;
  int repeat = 3;
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else if (!a.empty() && a[0] == '-') {
      throw std::invalid_argument(kUsage);
    } else {
      scenes.push_back(a);
    }
  }
  if (scenes.empty()) throw std::invalid_argument(kUsage);
  const fs::path out =
      fs::temp_directory_path() / ("single_view_bench_" + std::to_string(::getpid()));
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup{out};

  Method objscan("objscan discover"), lccp_method("PCL LCCP"), plane_method("PCL plane+EC");
  std::printf("%-14s %8s %8s %8s   %-23s %-23s\n", "scene", "objscan", "LCCP", "plane+EC",
              "recall@0.5 obj/LCCP/EC", "recall@0.7 obj/LCCP/EC");
  for (const std::string& path : scenes) {
    namespace d = objscan::discovery;
    // Ground truth over the pixels, as objscan eval takes it.
    const objscan::OrganizedCloud cloud = objscan::readPcd(path);
    if (cloud.labels.empty()) throw std::runtime_error(path + ": no label field");
    std::vector<std::int32_t> ids(cloud.labels.size(), 0);
    for (std::size_t i = 0; i < ids.size(); ++i) {
      if (cloud.valid(i)) ids[i] = objscan::objectIdOfLabel(cloud.labels[i]);
    }
    const d::GroundTruthObjects truth(ids);

    std::vector<double> t_objscan, t_lccp, t_plane;
    std::vector<std::uint32_t> lccp_labels, plane_labels;
    for (int r = 0; r < repeat; ++r) {
      t_objscan.push_back(secondsOf([&] {
        runQuietly({OBJSCAN_EXE, "discover", path, "--out", out.string(), "--no-catalog"});
      }));
      t_lccp.push_back(secondsOf([&] { lccp_labels = lccp(loadCloud(path)); }));
      t_plane.push_back(secondsOf([&] { plane_labels = planeAndClusters(loadCloud(path)); }));
    }

    // objscan's figures as eval computes them.
    d::SceneReading reading;
    reading.labelled = true;
    reading.hash = false;
    std::vector<d::SceneInput> inputs;
    inputs.push_back(d::loadScene(path, reading));
    d::SceneDiscoveryOptions options;
    options.progress_label = "";
    const d::SceneDiscovery discovery = d::discoverScenes(std::move(inputs), options);
    const d::SceneRecall own = d::sceneRecall(discovery).at(0);

    const auto lccp_segments = segmentsOfLabels(lccp_labels);
    const auto plane_segments = segmentsOfLabels(plane_labels);
    const auto [l5, l7] = recallOf(lccp_segments, truth);
    const auto [p5, p7] = recallOf(plane_segments, truth);
    const auto add = [](Method& m, double s, double r5, double r7, double ap, std::size_t n) {
      m.seconds.push_back(s);
      m.recall_05.push_back(r5);
      m.recall_07.push_back(r7);
      m.ap_05.push_back(ap);
      m.segments.push_back(static_cast<double>(n));
    };
    add(objscan, median(t_objscan), own.recall_05, own.recall_07, own.ap_05,
        discovery.ranked.size());
    add(lccp_method, median(t_lccp), l5, l7, -1.0, lccp_segments.size());
    add(plane_method, median(t_plane), p5, p7, -1.0, plane_segments.size());
    std::printf("%-14s %7.2fs %7.2fs %7.2fs   %.2f / %.2f / %.2f      %.2f / %.2f / %.2f\n",
                fs::path(path).filename().c_str(), median(t_objscan), median(t_lccp),
                median(t_plane), own.recall_05, l5, p5, own.recall_07, l7, p7);
    std::fflush(stdout);
  }

  const auto mean = [](const std::vector<double>& x) {
    double s = 0.0;
    for (double v : x) s += v;
    return x.empty() ? 0.0 : s / static_cast<double>(x.size());
  };
  std::printf("\n%zu scenes, %d runs each (median per scene, then the mean over scenes)\n",
              scenes.size(), repeat);
  std::printf("  %-18s %10s %12s %11s %11s %8s %10s\n", "method", "s/scene", "objscan/it",
              "recall@0.5", "recall@0.7", "AP@0.5", "segments");
  Json methods = Json::array();
  for (const Method* m : {&objscan, &lccp_method, &plane_method}) {
    const double ratio = mean(objscan.seconds) / mean(m->seconds);
    const bool ranked = m == &objscan;
    std::printf("  %-18s %10.2f %12.2f %11.3f %11.3f %8s %10.0f\n", m->name.c_str(),
                mean(m->seconds), ratio, mean(m->recall_05), mean(m->recall_07),
                ranked ? std::to_string(mean(m->ap_05)).substr(0, 5).c_str() : "-",
                mean(m->segments));
    methods.push_back({{"method", m->name},
                       {"seconds_per_scene", mean(m->seconds)},
                       {"objscan_time_ratio", ratio},
                       {"recall_05", mean(m->recall_05)},
                       {"recall_07", mean(m->recall_07)},
                       {"ap_05", ranked ? Json(mean(m->ap_05)) : Json()},
                       {"segments_per_scene", mean(m->segments)},
                       {"per_scene_seconds", m->seconds}});
  }
  std::printf(
      "  (objscan: the whole command as a process, loading included; its segments are the "
      "hypotheses after suppression)\n");
  if (!json_path.empty()) {
    objscan::writeFileAtomically(
        json_path,
        Json{{"scenes", scenes}, {"repeat", repeat}, {"methods", methods}}.dump(2) + "\n");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("single_view_bench", run, argc, argv);
}
