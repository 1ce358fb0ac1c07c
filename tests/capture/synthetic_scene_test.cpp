#include "objscan/capture/synthetic/synthetic_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "objscan/capture/synthetic/shapes.h"
#include "objscan/capture/synthetic/synthetic_recording.h"
#include "objscan/capture/tum_folder.h"
#include "objscan/core/error.h"
#include "objscan/core/mesh_distance.h"
#include "objscan/core/organized_cloud.h"
#include "objscan/core/ply_io.h"
#include "objscan/render/offscreen_renderer.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;

/// The vertices and triangles of one object, cut out of the scene mesh by label.
TriangleMesh objectMesh(const TriangleMesh& scene, std::int32_t id) {
  TriangleMesh m;
  std::vector<int> map(scene.positions.size(), -1);
  for (std::size_t i = 0; i < scene.positions.size(); ++i) {
    if (scene.labels[i] == id) {
      map[i] = static_cast<int>(m.positions.size());
      m.positions.push_back(scene.positions[i]);
    }
  }
  for (const auto& t : scene.triangles) {
    if (map[t[0]] >= 0) m.triangles.emplace_back(map[t[0]], map[t[1]], map[t[2]]);
  }
  return m;
}

/// Point inside a closed mesh: a ray along a fixed, generic direction crosses it an odd number
/// of times (Moller-Trumbore).
bool insideClosed(const TriangleMesh& m, const Eigen::Vector3f& p) {
  const Eigen::Vector3f dir = Eigen::Vector3f(0.5773f, 0.5774f, 0.5775f).normalized();
  int crossings = 0;
  for (const auto& t : m.triangles) {
    const Eigen::Vector3f a = m.positions[t[0]], e1 = m.positions[t[1]] - a,
                          e2 = m.positions[t[2]] - a;
    const Eigen::Vector3f h = dir.cross(e2);
    const float det = e1.dot(h);
    if (std::abs(det) < 1e-12f) continue;
    const Eigen::Vector3f s = p - a;
    const float u = s.dot(h) / det;
    if (u < 0 || u > 1) continue;
    const Eigen::Vector3f q = s.cross(e1);
    const float v = dir.dot(q) / det;
    if (v < 0 || u + v > 1) continue;
    if (e2.dot(q) / det > 0) ++crossings;
  }
  return crossings % 2 == 1;
}

/// Runs `check(scene, seed)` on the scene of every preset for each seed, with `objects` objects.
template <class Check>
void forEachScene(int objects, std::initializer_list<std::uint64_t> seeds, Check check) {
  for (const ScenePreset preset :
       {ScenePreset::kDesk, ScenePreset::kShelf, ScenePreset::kCounter}) {
    for (const std::uint64_t seed : seeds) {
      SCOPED_TRACE(std::string(toString(preset)) + " seed " + std::to_string(seed));
      SceneConfig config;
      config.preset = preset;
      config.objects = objects;
      config.seed = seed;
      check(composeScene(config), seed);
    }
  }
}

TEST(SyntheticScene, SameSeedSameSceneOtherSeedOtherScene) {
  SceneConfig config;
  config.seed = 21;
  const SyntheticScene a = composeScene(config), b = composeScene(config);
  EXPECT_TRUE(testing::bitwiseEqual(a.mesh, b.mesh));
  config.seed = 22;
  EXPECT_FALSE(testing::bitwiseEqual(a.mesh, composeScene(config).mesh));
}

/// Every object rests where its pose says (on a support, or on the object under it), in front of
/// the wall, and reaches into no other. Returns how many are touching another or the wall.
int expectRestingApart(const SyntheticScene& scene) {
  std::vector<TriangleMesh> parts;
  std::vector<Eigen::AlignedBox3f> boxes;
  for (const SceneObject& o : scene.objects) {
    parts.push_back(objectMesh(scene.mesh, o.id));
    boxes.push_back(parts.back().bounds());
    EXPECT_EQ(parts.back().positions.size(), o.vertex_count);
    // Resting: the lowest point is on the support the pose stands on.
    EXPECT_NEAR(boxes.back().min().z(), o.T_W_O.translation().z(), 1e-5f) << o.name;
    // In front of the wall, never into it.
    EXPECT_LE(boxes.back().max().y(), SyntheticScene::kWallY + 1e-5f) << o.name;
  }
  int touching = 0;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    touching += scene.objects[i].touching;
    for (std::size_t j = 0; j < parts.size(); ++j) {
      if (i == j || !boxes[i].intersects(boxes[j])) continue;
      // Touching objects share faces: a point on the other's surface (within 0.1 mm) is
      // contact, not penetration.
      const MeshDistance surface(parts[j], 1e-4f);
      for (const auto& p : parts[i].positions) {
        if (!boxes[j].contains(p) || surface.closest(p).triangle >= 0) continue;
        EXPECT_FALSE(insideClosed(parts[j], p))
            << scene.objects[i].name << " reaches into " << scene.objects[j].name;
        if (insideClosed(parts[j], p)) return touching;
      }
    }
  }
  return touching;
}

TEST(SyntheticScene, TwentyObjectsRestOnSupportsWithoutInterpenetrating) {
  forEachScene(20, {1u, 2u}, [](const SyntheticScene& scene, std::uint64_t) {
    ASSERT_EQ(scene.objects.size(), 20u);
    ASSERT_NO_THROW(scene.mesh.validate());
    EXPECT_GT(expectRestingApart(scene), 0)
        << "some objects stand flush against the wall or a neighbour";
  });
}

TEST(SyntheticScene, HardClutterStacksSmallObjectsAmongPlantsAndCables) {
  std::size_t small = 0, stacked = 0, objects = 0, two_tone = 0;
  for (const ScenePreset preset :
       {ScenePreset::kDesk, ScenePreset::kShelf, ScenePreset::kCounter}) {
    for (const std::uint64_t seed : {1u, 2u}) {
      SCOPED_TRACE(std::string(toString(preset)) + " seed " + std::to_string(seed));
      SceneConfig config;
      config.preset = preset;
      config.objects = 20;
      config.seed = seed;
      config.hard_clutter = true;
      const SyntheticScene scene = composeScene(config);
      ASSERT_EQ(scene.objects.size(), 20u);
      ASSERT_NO_THROW(scene.mesh.validate());
      // Half touching at least, by the draw; the placement may fall back for a few.
      EXPECT_GE(expectRestingApart(scene), 6);
      const std::vector<std::string>& names = shapes::smallNames();
      for (const SceneObject& o : scene.objects) {
        ++objects;
        small += std::find(names.begin(), names.end(), o.name) != names.end();
        if (!o.stacked) continue;
        ++stacked;
        // On the top of an object that stands on a support, within its footprint.
        const Eigen::Vector3f centre = o.T_W_O.translation();
        EXPECT_TRUE(std::any_of(scene.objects.begin(), scene.objects.end(),
                                [&](const auto& u) {
                                  const Eigen::Vector3f c = u.T_W_O.inverse() * centre;
                                  return u.id != o.id && !u.stacked &&
                                         std::abs(u.box_max_O.z() - u.box_min_O.z() - c.z()) <
                                             1e-4f &&
                                         c.x() >= u.box_min_O.x() && c.x() <= u.box_max_O.x() &&
                                         c.y() >= u.box_min_O.y() && c.y() <= u.box_max_O.y();
                                }))
            << o.name << " is stacked on nothing";
      }
      std::map<std::int32_t, std::set<std::uint32_t>> colours;
      std::size_t leaves = 0;
      for (std::size_t v = 0; v < scene.mesh.positions.size(); ++v) {
        const Rgb8& c = scene.mesh.colors[v];
        if (scene.mesh.labels[v] > 0) {
          colours[scene.mesh.labels[v]].insert(c.x() << 16 | c.y() << 8 | c.z());
        } else {
          leaves += c.y() > c.x() + 40 && c.y() > c.z() + 40;  // green: a leaf or a stem
        }
      }
      for (const auto& [id, set] : colours) two_tone += set.size() == 2;
      // A potted plant on desks and counters (its leaves are clutter: label 0); none fits a
      // shelf board.
      if (preset == ScenePreset::kShelf) {
        EXPECT_EQ(leaves, 0u);
      } else {
        EXPECT_GT(leaves, 500u);
      }
    }
  }
  // A third small, a fifth stacked where a flat top is free, half in two colours, by the draws.
  EXPECT_GT(small, objects / 5);
  EXPECT_GT(stacked, objects / 20);
  EXPECT_GT(two_tone, objects / 4);
}

TEST(SyntheticScene, ObjectsFromAFolderAreUsed) {
  testing::TempDir dir;
  TriangleMesh widget = shapes::box(0.05f, 0.05f, 0.05f);
  for (auto& p : widget.positions) p += Eigen::Vector3f(3.0f, 3.0f, 3.0f);  // not resting yet
  writePly(dir / "widget.ply", widget);
  SceneConfig config;
  config.objects = 20;
  config.object_dir = dir.path();
  const SyntheticScene scene = composeScene(config);
  int widgets = 0;
  for (const SceneObject& o : scene.objects) {
    if (o.name != "widget") continue;
    ++widgets;
    EXPECT_NEAR((o.box_max_O - o.box_min_O).maxCoeff(), 0.05f, 1e-6f);
    EXPECT_NEAR(o.box_min_O.z(), 0.0f, 1e-6f);
  }
  EXPECT_GT(widgets, 0) << "1 of 12 candidates, 20 draws";
}

TEST(SyntheticScene, BadMeshesInTheObjectFolderAreNamedErrors) {
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  struct Case {
    std::string file, text, needle;
  };
  const std::vector<Case> cases = {
      // An empty mesh must not quietly turn into the built-in mug of the same name.
      {"mug.ply", "ply\nformat ascii 1.0\nelement vertex 0\n" + xyz + "end_header\n",
       "has no faces"},
      {"cloud.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "end_header\n0 0 0\n1 0 0\n0 1 0\n",
       "has no faces"},
      {"flat.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
           "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n0.1 0 0\n0 "
           "0.1 0\n3 0 1 2\n",
       "zero extent"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.file);
    testing::TempDir dir;
    testing::writeBytes(dir / c.file, c.text);
    SceneConfig config;
    config.object_dir = dir.path();
    testing::expectInputError([&] { composeScene(config); }, dir / c.file, c.needle);
  }
}

TEST(HandheldPath, EveryObjectIsSeenAlongTheDefaultPath) {
  // The default 300-frame (10 s) path of each preset, rendered at every 10th pose.
  forEachScene(12, {1u, 2u, 3u}, [](const SyntheticScene& scene, std::uint64_t seed) {
    HandheldPathConfig path_config;
    path_config.seed = seed;
    const Trajectory path = makeHandheldPath(scene, path_config);
    render::OffscreenRenderer renderer(Intrinsics::xtionDefault());
    renderer.setMesh(scene.mesh);
    std::vector<int> seen(scene.objects.size() + 1, 0);
    for (std::size_t i = 0; i < path.size(); i += 10) {
      const cv::Mat labels = renderer.render(path.poses[i].T_W_C).label;
      for (int v = 0; v < labels.rows; ++v) {
        for (int u = 0; u < labels.cols; ++u)
          ++seen[static_cast<std::size_t>(labels.at<std::int32_t>(v, u))];
      }
    }
    for (const SceneObject& o : scene.objects) {
      EXPECT_GT(seen[static_cast<std::size_t>(o.id)], 0)
          << o.name << " (id " << o.id << ") never seen";
    }
  });
}

TEST(HandheldPath, StaysInRangeLooksAtTheSceneAndMovesLikeAHand) {
  const SyntheticScene scene = composeScene(SceneConfig{});
  HandheldPathConfig config;
  const Trajectory path = makeHandheldPath(scene, config);
  ASSERT_EQ(path.size(), 300u);
  EXPECT_NEAR(path.durationS(), 299.0 / 30.0, 1e-9);
  for (std::size_t i = 0; i < path.size(); ++i) {
    const Pose& T = path.poses[i].T_W_C;
    const Eigen::Vector3f to_target = scene.look_at_W - T.translation();
    // Distance 0.6-1.5 m, give or take the hand's wobble (jitter 1 cm).
    EXPECT_GT(to_target.norm(), 0.58f);
    EXPECT_LT(to_target.norm(), 1.52f);
    // The optical axis points at the scene (within the 5 cm aim wobble: a few degrees).
    const float angle = std::acos(T.linear().col(2).dot(to_target.normalized()));
    EXPECT_LT(angle, 0.12f);
    // y (down) points mostly down: roll stays small.
    EXPECT_LT(T.linear().col(1).z(), -0.5f);
    if (i > 0) {
      const float speed = (T.translation() - path.poses[i - 1].T_W_C.translation()).norm() * 30.0f;
      EXPECT_LT(speed, 0.6f) << "m/s at frame " << i;
    }
  }
}

/// A small recording shared by the tests below: 8 objects, 12 frames, noise off.
class SyntheticRecording : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir;
    SceneConfig config;
    config.objects = 8;
    config.seed = 5;
    scene_ = new SyntheticScene(composeScene(config));
    HandheldPathConfig path_config;
    path_config.frames = 12;
    path_config.seed = 5;
    path_ = new Trajectory(makeHandheldPath(*scene_, path_config));
    SensorModelConfig off;
    off.enabled = false;
    visibility_ = writeSyntheticRecording(*scene_, *path_, Intrinsics::xtionDefault(), off, 5,
                                          dir_->path() / "rec");
  }
  static void TearDownTestSuite() {
    delete path_;
    delete scene_;
    delete dir_;
  }
  static fs::path rec() { return dir_->path() / "rec"; }

  static testing::TempDir* dir_;
  static SyntheticScene* scene_;
  static Trajectory* path_;
  static std::vector<Visibility> visibility_;
};
testing::TempDir* SyntheticRecording::dir_ = nullptr;
SyntheticScene* SyntheticRecording::scene_ = nullptr;
Trajectory* SyntheticRecording::path_ = nullptr;
std::vector<Visibility> SyntheticRecording::visibility_;

TEST_F(SyntheticRecording, BackProjectedDepthLiesOnTheGroundTruthMeshWithinOneMillimetre) {
  // Read back through the real readers: the TUM folder as capture sees it, scene_gt.ply as any
  // tool would.
  const capture::TumFolder folder(rec());
  const TriangleMesh gt = readPly(rec() / "scene_gt.ply");
  ASSERT_TRUE(folder.groundTruth().has_value());
  ASSERT_EQ(folder.size(), 12u);
  const MeshDistance distance(gt, 0.005f);
  double worst = 0.0;
  std::size_t points = 0, label_agrees = 0, labelled = 0;
  for (std::size_t i = 0; i < folder.size(); ++i) {
    const RgbdFrame frame = folder.load(i);
    const Pose& T_W_C = folder.groundTruth()->poses[i].T_W_C;
    const cv::Mat labels = cv::imread(
        (rec() / "label" / folder.frames()[i].depth.filename()).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(labels.type(), CV_16UC1);
    const Intrinsics& in = frame.intrinsics;
    for (int v = 0; v < in.height_px; v += 3) {
      for (int u = 0; u < in.width_px; u += 3) {
        const float z = frame.depth_m.at<float>(v, u);
        if (z <= 0.0f) continue;
        const Eigen::Vector3f p_C(static_cast<float>((u - in.cx_px) / in.fx_px) * z,
                                  static_cast<float>((v - in.cy_px) / in.fy_px) * z, z);
        const MeshDistance::Closest c = distance.closest(T_W_C * p_C);
        ASSERT_LT(c.distance_m, 0.005f) << "frame " << i << " pixel " << u << ", " << v;
        worst = std::max(worst, static_cast<double>(c.distance_m));
        ++points;
        const int label = labels.at<std::uint16_t>(v, u);
        if (label > 0) {
          ++labelled;
          label_agrees += gt.labels[gt.triangles[c.triangle][0]] == label;
        }
      }
    }
  }
  EXPECT_GT(points, 12u * 30000u);
  // Depth PNGs hold 0.2 mm steps; the rest is float rounding.
  EXPECT_LT(worst, 0.001) << "worst distance to scene_gt.ply, m";
  // The label image names the object whose surface the depth lies on (a few pixels on the
  // contact line between two surfaces may pick the neighbour).
  EXPECT_GT(static_cast<double>(label_agrees) / static_cast<double>(labelled), 0.999);
}

TEST_F(SyntheticRecording, JsonVisibilityMatchesARecountOfTheLabelImages) {
  // Count each object's pixels and frames again from the label PNGs on disk.
  std::map<int, std::pair<std::size_t, std::size_t>> recount;  // id -> pixels, frames
  for (const auto& entry : fs::directory_iterator(rec() / "label")) {
    const cv::Mat labels = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(labels.type(), CV_16UC1);
    std::map<int, std::size_t> in_frame;
    for (int v = 0; v < labels.rows; ++v) {
      for (int u = 0; u < labels.cols; ++u) {
        if (const int id = labels.at<std::uint16_t>(v, u); id > 0) ++in_frame[id];
      }
    }
    for (const auto& [id, n] : in_frame) {
      recount[id].first += n;
      recount[id].second += 1;
    }
  }
  const nlohmann::json gt = nlohmann::json::parse(testing::readBytes(rec() / "scene_gt.json"));
  ASSERT_EQ(gt["objects"].size(), scene_->objects.size());
  std::size_t seen = 0;
  for (std::size_t i = 0; i < scene_->objects.size(); ++i) {
    const auto& o = gt["objects"][i];
    const int id = scene_->objects[i].id;
    EXPECT_EQ(o["id"].get<int>(), id);
    EXPECT_EQ(o["name"].get<std::string>(), scene_->objects[i].name);
    EXPECT_EQ(o["vertex_count"].get<std::size_t>(), scene_->objects[i].vertex_count);
    EXPECT_EQ(o["visible_pixels"].get<std::size_t>(), recount[id].first) << "id " << id;
    EXPECT_EQ(o["frames_visible"].get<std::size_t>(), recount[id].second) << "id " << id;
    seen += recount[id].second > 0;
  }
  EXPECT_GT(seen, 0u);
  const TriangleMesh mesh = readPly(rec() / "scene_gt.ply");
  EXPECT_EQ(mesh.labels, scene_->mesh.labels);
}

TEST_F(SyntheticRecording, SameSeedWritesIdenticalFiles) {
  testing::TempDir again;
  SceneConfig config;
  config.objects = 8;
  config.seed = 5;
  HandheldPathConfig path_config;
  path_config.frames = 12;
  path_config.seed = 5;
  const SyntheticScene scene = composeScene(config);
  SensorModelConfig off;
  off.enabled = false;
  writeSyntheticRecording(scene, makeHandheldPath(scene, path_config), Intrinsics::xtionDefault(),
                          off, 5, again / "rec");
  std::size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(rec())) {
    if (!entry.is_regular_file()) continue;
    ++files;
    const fs::path twin = again / "rec" / fs::relative(entry.path(), rec());
    ASSERT_EQ(testing::readBytes(entry.path()), testing::readBytes(twin)) << twin;
  }
  EXPECT_EQ(files, 12u * 3u + 7u);  // rgb, depth, label per frame; 7 index and ground-truth files
}

TEST_F(SyntheticRecording, FailureWhileWritingLeavesNoFolderBehind) {
  // A 64 KB file-size limit makes the first PNG write fail part-way (as a full disk would).
  testing::TempDir dir;
  bool threw = false;
  {
    const testing::FileSizeLimit limit(64 * 1024);
    try {
      writeSyntheticRecording(*scene_, *path_, Intrinsics::xtionDefault(), SensorModelConfig{}, 1,
                              dir / "rec");
    } catch (const OutputError&) {
      threw = true;
    }
  }
  EXPECT_TRUE(threw);
  EXPECT_EQ(testing::entryCount(dir.path()), 0u)
      << "neither the recording nor its temporary folder remains";
}

TEST(SyntheticViews, AreTheFramesAsLabelledPcdsOnTheirPixelGrid) {
  // Two views of six noisy frames: the middles of the path's halves, frames 1 and 4. Each is the
  // frame's own depth (as the depth PNG stores it, to its 0.2 mm resolution), colour and label
  // image, the labels in mOSD's convention, every point on its own pixel's ray.
  testing::TempDir dir;
  SceneConfig config;
  config.objects = 6;
  config.seed = 9;
  const SyntheticScene scene = composeScene(config);
  HandheldPathConfig six;
  six.frames = 6;
  const Trajectory path = makeHandheldPath(scene, six);
  const Intrinsics k = Intrinsics::xtionDefault();
  writeSyntheticRecording(scene, path, k, SensorModelConfig{}, 3, dir / "rec", nullptr, 2);
  std::vector<fs::path> views;
  for (const auto& entry : fs::directory_iterator(dir / "rec" / "views")) views.push_back(entry);
  std::sort(views.begin(), views.end());
  ASSERT_EQ(views.size(), 2u);
  const TumFolder folder(dir / "rec");
  std::size_t objects_seen = 0;
  for (std::size_t j = 0; j < views.size(); ++j) {
    const fs::path frame_png = dir / "rec" / folder.frames()[j == 0 ? 1 : 4].depth;
    EXPECT_EQ(views[j].stem(), frame_png.stem());
    const OrganizedCloud cloud = readPcd(views[j]);
    ASSERT_EQ(cloud.width, k.width_px);
    ASSERT_EQ(cloud.height, k.height_px);
    ASSERT_EQ(cloud.labels.size(), cloud.points_C.size());
    ASSERT_EQ(cloud.colors.size(), cloud.points_C.size());
    const cv::Mat depth = cv::imread(frame_png.string(), cv::IMREAD_UNCHANGED);
    const cv::Mat labels =
        cv::imread((dir / "rec" / "label" / frame_png.filename()).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat bgr =
        cv::imread((dir / "rec" / "rgb" / frame_png.filename()).string(), cv::IMREAD_COLOR);
    ASSERT_EQ(depth.type(), CV_16UC1);
    std::set<std::uint32_t> ids;
    std::size_t readings = 0, wrong = 0;
    for (int v = 0; v < depth.rows; ++v) {
      for (int u = 0; u < depth.cols; ++u) {
        const std::size_t i = static_cast<std::size_t>(v * depth.cols + u);
        const cv::Vec3b c = bgr.at<cv::Vec3b>(v, u);
        wrong += cloud.colors[i] != Rgb8(c[2], c[1], c[0]);
        const int png = depth.at<std::uint16_t>(v, u);
        if (png == 0) {
          wrong += cloud.valid(i) || cloud.labels[i] != 0;
          continue;
        }
        ++readings;
        const Eigen::Vector3f& p = cloud.points_C[i];
        wrong += std::abs(p.z() - png / 5000.0f) > 1.1e-4f;
        wrong += std::abs(k.fx_px * p.x() / p.z() + k.cx_px - u) > 1e-3;
        wrong += std::abs(k.fy_px * p.y() / p.z() + k.cy_px - v) > 1e-3;
        const int id = labels.at<std::uint16_t>(v, u);
        wrong += cloud.labels[i] != (id > 0 ? 10u * static_cast<std::uint32_t>(id) : 1u);
        if (id > 0) ids.insert(cloud.labels[i]);
      }
    }
    EXPECT_EQ(wrong, 0u) << views[j];
    EXPECT_GT(readings, depth.total() / 2) << views[j];
    objects_seen += ids.size();
  }
  EXPECT_GE(objects_seen, 2u) << "the views show objects";
  // More views than frames: refused before anything is written.
  EXPECT_THROW(
      writeSyntheticRecording(scene, path, k, SensorModelConfig{}, 3, dir / "rec2", nullptr, 7),
      std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir / "rec2"));
}

TEST(SyntheticRecordingPaths, TrailingSlashNamesTheSameFolder) {
  testing::TempDir dir;
  EXPECT_EQ(checkNewFolder((dir / "out").string() + "/"), dir / "out");
  EXPECT_THROW(checkNewFolder(""), std::invalid_argument);
  EXPECT_THROW(checkNewFolder("."), std::invalid_argument);
  const SyntheticScene scene = composeScene(SceneConfig{});
  HandheldPathConfig one;
  one.frames = 1;
  writeSyntheticRecording(scene, makeHandheldPath(scene, one), Intrinsics::xtionDefault(),
                          SensorModelConfig{}, 1, (dir / "out").string() + "/");
  EXPECT_TRUE(fs::is_regular_file(dir / "out" / "scene_gt.json"));
}

TEST_F(SyntheticRecording, RefusesToOverwriteAnExistingRecording) {
  EXPECT_THROW(writeSyntheticRecording(*scene_, *path_, Intrinsics::xtionDefault(),
                                       SensorModelConfig{}, 1, rec()),
               std::invalid_argument);
  EXPECT_EQ(testing::entryCount(dir_->path()), 1u);
}

}  // namespace
}  // namespace objscan::capture
