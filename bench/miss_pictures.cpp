// Not a benchmark: pictures of the objects discovery misses on labelled single views, for
// docs/discovery.md. The scenes are discovered together, as `objscan eval` does (no catalog, the
// measures normalised over them); an object part (mOSD's labels) is missed when evaluateRanking at
// IoU 0.7 does not find it among its scene's hypotheses, as eval counts it. For each scene with a
// miss, OUT/<scene>.jpg shows the camera's colour image, dimmed: every object outlined (green:
// found, red: missed), and the hypothesis that overlaps each missed object most filled in its own
// colour, captioned with the IoU and its rank within the scene.
//
//   miss_pictures OUT_DIR <scene.pcd>...

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bench_main.h"
#include "objscan/core/organized_cloud.h"
#include "objscan/discovery/evaluation.h"
#include "objscan/discovery/labels.h"
#include "objscan/discovery/scenes.h"

namespace {

namespace fs = std::filesystem;
namespace d = objscan::discovery;

/// A mask of the pixels of `vertices` (scene mesh vertices).
cv::Mat maskOf(const std::vector<std::int32_t>& vertices, const std::vector<std::int32_t>& pixel,
               int width, int height) {
  cv::Mat mask(height, width, CV_8UC1, cv::Scalar(0));
  for (std::int32_t v : vertices) mask.data[pixel[static_cast<std::size_t>(v)]] = 255;
  return mask;
}

void outline(cv::Mat& image, const cv::Mat& mask, const cv::Scalar& colour) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  cv::drawContours(image, contours, -1, colour, 2);
}

int run(int argc, char** argv) {
  if (argc < 3) throw std::invalid_argument("usage: miss_pictures OUT_DIR <scene.pcd>...");
  const fs::path out = argv[1];
  fs::create_directories(out);
  std::vector<std::string> paths(argv + 2, argv + argc);
  std::vector<d::SceneInput> inputs;
  d::SceneReading reading;
  reading.labelled = true;
  reading.hash = false;
  for (const std::string& p : paths) inputs.push_back(d::loadScene(p, reading));
  d::SceneDiscoveryOptions options;
  const d::SceneDiscovery run = d::discoverScenes(std::move(inputs), options);

  const cv::Scalar kFound(80, 200, 80), kMissed(40, 40, 230);  // BGR
  const cv::Scalar kFill[] = {{230, 120, 40}, {40, 200, 230}, {200, 60, 200}, {230, 220, 60}};
  for (std::size_t s = 0; s < run.scenes.size(); ++s) {
    const d::DiscoveredScene& scene = run.scenes[s];
    const objscan::OrganizedCloud cloud = objscan::readPcd(paths[s]);
    std::vector<std::int32_t> pixel;
    const objscan::TriangleMesh mesh = objscan::meshOrganized(cloud, reading.meshing, &pixel);
    if (mesh.positions.size() != scene.mesh.positions.size()) {
      throw std::runtime_error(paths[s] + ": the mesh differs from discover's");
    }
    // The scene's hypotheses, best first.
    std::vector<const d::Hypothesis*> ranked;
    for (const d::RankedHypothesis& h : run.ranked) {
      if (h.scene == s) ranked.push_back(&h.hypothesis);
    }
    const d::GroundTruthObjects& truth = *scene.truth;
    std::map<std::int32_t, std::vector<std::int32_t>> object_vertices;
    for (std::size_t v = 0; v < truth.vertexLabels().size(); ++v) {
      if (truth.vertexLabels()[v] != 0) {
        object_vertices[truth.vertexLabels()[v]].push_back(static_cast<std::int32_t>(v));
      }
    }
    // Found: evaluateRanking at IoU 0.7 over the scene's ranking (eval's definition).
    std::vector<std::vector<std::int32_t>> ranked_vertices;
    for (const d::Hypothesis* h : ranked) ranked_vertices.push_back(h->segment.vertices);
    std::set<std::int32_t> found;
    for (const d::RankMatch& r : d::evaluateRanking(truth, ranked_vertices, 0.7).ranks) {
      if (r.found) found.insert(r.match.object_id);
    }
    // For the picture, each missed object's most overlapping hypothesis (IoU with it alone).
    struct Best {
      double iou = 0.0;
      std::size_t rank = 0;  ///< 0: none overlaps it
    };
    std::map<std::int32_t, Best> best;
    for (const auto& [id, vertices] : object_vertices) {
      if (found.count(id)) {
        best[id] = {1.0, 0};
        continue;
      }
      std::vector<std::int32_t> only(truth.vertexLabels().size(), 0);
      for (std::int32_t v : vertices) only[static_cast<std::size_t>(v)] = id;
      const d::GroundTruthObjects alone(std::move(only));
      for (std::size_t r = 0; r < ranked.size(); ++r) {
        const double iou = alone.bestMatch(ranked_vertices[r]).iou;
        if (iou > best[id].iou) best[id] = {iou, r + 1};
      }
    }
    if (found.size() == object_vertices.size()) continue;

    cv::Mat image(cloud.height, cloud.width, CV_8UC3, cv::Scalar(0, 0, 0));
    for (std::size_t i = 0; i < cloud.colors.size(); ++i) {
      const auto& c = cloud.colors[i];
      image.at<cv::Vec3b>(static_cast<int>(i) / cloud.width, static_cast<int>(i) % cloud.width) =
          cv::Vec3b(c[2] / 2 + 40, c[1] / 2 + 40, c[0] / 2 + 40);
    }
    std::size_t misses = 0;
    std::vector<std::string> captions;
    for (const auto& [id, vertices] : object_vertices) {
      if (found.count(id)) continue;
      const Best& b = best[id];
      const cv::Scalar fill = kFill[misses++ % 4];
      if (b.rank > 0) {
        const cv::Mat m =
            maskOf(ranked[b.rank - 1]->segment.vertices, pixel, cloud.width, cloud.height);
        cv::Mat tinted = image.clone();
        tinted.setTo(fill, m);
        cv::addWeighted(image, 0.45, tinted, 0.55, 0.0, image);
        outline(image, m, fill);
      }
      char text[96];
      std::snprintf(text, sizeof text, "object %d: best IoU %.2f (rank %zu)", id, b.iou, b.rank);
      captions.push_back(text);
    }
    for (const auto& [id, vertices] : object_vertices) {
      outline(image, maskOf(vertices, pixel, cloud.width, cloud.height),
              found.count(id) ? kFound : kMissed);
    }
    for (const auto& [id, vertices] : object_vertices) {
      cv::Mat m = maskOf(vertices, pixel, cloud.width, cloud.height);
      const cv::Moments mo = cv::moments(m, true);
      if (mo.m00 <= 0) continue;
      cv::putText(image, std::to_string(id), cv::Point(mo.m10 / mo.m00, mo.m01 / mo.m00),
                  cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
    }
    int y = 18;
    const std::string name = fs::path(paths[s]).stem().string();
    cv::putText(image, name + ": red outline missed, green found; fill = best hypothesis",
                cv::Point(8, y), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1,
                cv::LINE_AA);
    for (const std::string& c : captions) {
      y += 18;
      cv::putText(image, c, cv::Point(8, y), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                  cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
      std::printf("  %s %s\n", name.c_str(), c.c_str());
    }
    const fs::path jpg = out / (name + ".jpg");
    if (!cv::imwrite(jpg.string(), image, {cv::IMWRITE_JPEG_QUALITY, 85})) {
      throw std::runtime_error("cannot write " + jpg.string());
    }
    std::printf("%s: %zu of %zu objects missed at IoU 0.7 -> %s\n", name.c_str(), misses,
                object_vertices.size(), jpg.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return objscan::bench::guardedMain("miss_pictures", run, argc, argv);
}
