// Seed corpora for the fuzz targets, written by objscan's own writers (so every seed is a file
// objscan writes and reads): make_seeds OUT makes OUT/<target>/ for each target. scripts/fuzz adds
// the small files the repository ships (recordings' trajectories and JSON sidecars).
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <liblzf/lzf.h>

#include <cstdint>

#include "objscan/core/intrinsics.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/scoring.h"
#include "objscan/report/results_io.h"

namespace fs = std::filesystem;
using namespace objscan;

namespace {

TriangleMesh smallMesh(bool extras) {
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {0.1f, 0, 0}, {0, 0.1f, 0}, {0, 0, 0.1f}};
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  if (extras) {
    mesh.computeNormals();
    mesh.colors = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {9, 9, 9}};
    mesh.labels = {0, 1, 1, 2};
  }
  return mesh;
}

/// `bytes` prefixed with `which` (fuzz_results_json's reader selector).
void writeSelected(const fs::path& file, char which, const fs::path& from) {
  std::ifstream in(from, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(file, std::ios::binary) << which << bytes;
}

/// A 2 × 2 organized PCD (x y z rgb label) in `data` form ascii, binary or binary_compressed.
void writePcdSeed(const fs::path& file, const std::string& data) {
  const float xyz[4][3] = {{0, 0, 1}, {0.01f, 0, 1}, {0, 0.01f, 1}, {0.01f, 0.01f, 1.02f}};
  const std::uint32_t rgb[4] = {0xff0000, 0x00ff00, 0x0000ff, 0x101010};
  const std::uint32_t label[4] = {0, 1, 1, 10001};
  std::string header =
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb label\n"
      "SIZE 4 4 4 4 4\nTYPE F F F U U\nCOUNT 1 1 1 1 1\nWIDTH 2\nHEIGHT 2\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA " + data + "\n";
  std::string body;
  const auto put = [&body](const void* p, std::size_t n) {
    body.append(static_cast<const char*>(p), n);
  };
  if (data == "ascii") {
    for (int i = 0; i < 4; ++i) {
      body += std::to_string(xyz[i][0]) + " " + std::to_string(xyz[i][1]) + " " +
              std::to_string(xyz[i][2]) + " " + std::to_string(rgb[i]) + " " +
              std::to_string(label[i]) + "\n";
    }
  } else if (data == "binary") {
    for (int i = 0; i < 4; ++i) {
      put(xyz[i], 12);
      put(&rgb[i], 4);
      put(&label[i], 4);
    }
  } else {  // binary_compressed: fields one after the other, LZF-compressed, sizes first
    std::string raw;
    for (int d = 0; d < 3; ++d) {
      for (int i = 0; i < 4; ++i) raw.append(reinterpret_cast<const char*>(&xyz[i][d]), 4);
    }
    raw.append(reinterpret_cast<const char*>(rgb), 16);
    raw.append(reinterpret_cast<const char*>(label), 16);
    std::string packed(raw.size() * 2 + 16, '\0');
    const unsigned n = lzf_compress(raw.data(), static_cast<unsigned>(raw.size()), packed.data(),
                                    static_cast<unsigned>(packed.size()));
    const std::uint32_t sizes[2] = {n, static_cast<std::uint32_t>(raw.size())};
    put(sizes, 8);
    body.append(packed.data(), n);
  }
  std::ofstream(file, std::ios::binary) << header << body;
}

void make(const fs::path& out) {
  const fs::path pcd = out / "fuzz_pcd";
  fs::create_directories(pcd);
  for (const char* data : {"ascii", "binary", "binary_compressed"}) {
    writePcdSeed(pcd / (std::string(data) + ".pcd"), data);
  }

  const fs::path ply = out / "fuzz_ply";
  fs::create_directories(ply);
  int n = 0;
  for (const PlyFormat f : {PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian,
                            PlyFormat::kBinaryBigEndian}) {
    for (const bool extras : {false, true}) {
      writePly(ply / ("seed" + std::to_string(n++) + ".ply"), smallMesh(extras), f);
    }
  }

  const fs::path tum = out / "fuzz_tum_trajectory";
  fs::create_directories(tum);
  Trajectory t;
  for (int i = 0; i < 3; ++i) {
    StampedPose p;
    p.stamp_s = 1305031102.175304 + 0.033 * i;
    p.T_W_C.translation() = Eigen::Vector3f(0.1f * static_cast<float>(i), 0.0f, 0.5f);
    p.T_W_C.linear() = Eigen::AngleAxisf(0.1f * static_cast<float>(i), Eigen::Vector3f::UnitY())
                           .toRotationMatrix();
    t.poses.push_back(p);
  }
  writeTumTrajectory(tum / "seed0.txt", t);

  const fs::path tum_folder = out / "fuzz_tum_folder";
  fs::create_directories(tum_folder);
  std::ofstream(tum_folder / "associations") << "1305031102.175304 depth/1.png 1305031102.175304 rgb/1.png\n"
                                                 "1305031102.2 depth/2.png 1305031102.21 rgb/2.png\n";
  std::ofstream(tum_folder / "lists")
      << "\n=====\n# depth maps\n1305031102.175304 depth/1.png\n1305031102.2 depth/2.png\n=====\n"
         "# color images\n1305031102.175304 rgb/1.png\n1305031102.21 rgb/2.png\n=====\n"
         "1305031102.175304 0 0 0 0 0 0 1\n";

  const fs::path seven = out / "fuzz_seven_scenes";  // intrinsics, two poses, the valid PNG
  fs::create_directories(seven);
  const std::string pose0 = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  const std::string pose1 =
      "9.9939e-01 -3.4899e-02 0.0000e+00 1.2e-02\n3.4899e-02 9.9939e-01 0.0000e+00 -3.0e-03\n"
      "0.0000e+00 0.0000e+00 1.0000e+00 2.5e-02\n0.0000e+00 0.0000e+00 0.0000e+00 1.0000e+00\n";
  std::ofstream(seven / "seed0") << "585 0 320\n0 585 240\n0 0 1\n=====\n"
                                 << pose0 << "=====\n"
                                 << pose1 << "=====\n";
  std::ofstream(seven / "seed1") << "\n=====\n" << pose0 << "=====\n" << pose1;
  std::ofstream(seven / "seed2") << "\t583.0\t0\t320.0\n 0 583 240 \n0 0 1";

  const fs::path intrinsics = out / "fuzz_intrinsics_json";
  fs::create_directories(intrinsics);
  writeIntrinsicsJson(intrinsics / "seed0.json", Intrinsics::xtionDefault());
  writeIntrinsicsJson(intrinsics / "seed1.json", Intrinsics::xtionDefault(), 5000.0);

  const fs::path results = out / "fuzz_results_json";
  const fs::path scratch = out / "scratch";
  fs::create_directories(results);
  fs::create_directories(scratch);
  report::Hypotheses h;
  h.scoring = report::Scoring{"average", "", "catalog"};
  h.catalog = report::CatalogUse{"/tmp/catalog.sqlite", 2, 40};
  report::SceneRecord scene;
  scene.mesh = "mesh.ply";
  scene.vertices = 4;
  scene.faces = 4;
  scene.catalog_scene = 1;
  h.scenes.push_back(scene);
  report::HypothesisRecord r;
  r.rank = 1;
  r.score = 0.5;
  r.scene = "mesh.ply";
  r.vertices = {0, 1, 2};
  r.box = report::OrientedBox{};
  r.scale = 1.0f;
  r.file = "objects/rank_001.ply";
  h.hypotheses.push_back(r);
  report::writeHypotheses(scratch / "hypotheses.json", h);
  writeSelected(results / "seed0", 0, scratch / "hypotheses.json");
  report::Timings timings;
  timings.source = "synth:1";
  timings.stages = {{"fuse", 1.5}, {"discover", 0.5}};
  timings.total_s = 2.0;
  timings.frames = report::FrameCounts{10, 9, 1, 0, 0};
  report::writeTimings(scratch / "timings.json", timings);
  writeSelected(results / "seed1", 1, scratch / "timings.json");
  report::Settings settings;
  settings.objscan_version = "0.1.0";
  settings.command = "scan";
  settings.options = {{"voxel-size", {"0.005"}, false, false}, {"no-catalog", {"true"}, true, false}};
  settings.intrinsics = Intrinsics::xtionDefault();
  report::writeSettings(scratch / "settings.json", settings);
  writeSelected(results / "seed2", 2, scratch / "settings.json");
  report::Evaluation evaluation;
  evaluation.ground_truth = "scene_gt.ply";
  evaluation.objects = 2;
  evaluation.found = 1;
  evaluation.ranks = {{1, 1, "mug", 0.8, true, false, 1.0, 0.5}};
  report::writeEvaluation(scratch / "evaluation.json", evaluation);
  writeSelected(results / "seed3", 3, scratch / "evaluation.json");
  std::ofstream(results / "seed4", std::ios::binary)
      << '\x04'
      << R"({"view": "trajectory", "T_W_C": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
"intrinsics": {"fx": 570.3, "fy": 570.3, "cx": 319.5, "cy": 239.5, "width": 640, "height": 480}})";
  fs::remove_all(scratch);

  const fs::path model = out / "fuzz_model";
  fs::create_directories(model);
  discovery::MeasureNormaliser normaliser;
  normaliser.mean = {0.5, 0.2, 0.8, 0.7, 0.003, 1.0};
  normaliser.sd = {0.1, 0.1, 0.1, 0.1, 0.001, 0.5};
  discovery::ObjectnessModel::average(normaliser).save(model / "average.json");
  {  // a trained model of every kind, on two overlapping clouds of measures
    std::mt19937 random(5);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::vector<discovery::MeasureRow> rows(60);
    std::vector<int> labels(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      labels[i] = static_cast<int>(i % 2);
      for (double& v : rows[i]) v = noise(random) + labels[i];
    }
    for (const discovery::ScoreKind kind : discovery::kAllScoreKinds) {
      discovery::ObjectnessModel::train(kind, normaliser, rows, labels)
          .save(model / (std::string(discovery::toString(kind)) + ".json"));
    }
  }

  const fs::path catalog_dir = out / "fuzz_catalog";
  fs::create_directories(catalog_dir);
  {
    discovery::Catalog catalog(catalog_dir / "seed.sqlite");
    discovery::CatalogScene catalog_scene;
    catalog_scene.name = "scene.ply";
    catalog_scene.content_hash = "0123456789abcdef";
    catalog_scene.vertex_count = 4;
    catalog_scene.settings = "settings";
    discovery::CatalogSegment segment;
    segment.scale = 1.0f;
    segment.extents = {0.1f, 0.05f, 0.02f};
    segment.vertices = {0, 1, 2};
    segment.label = 1;
    const std::int64_t id = catalog.addScene(catalog_scene, {segment, segment});
    const auto rows = catalog.segments(id, false);
    const discovery::LabelEvent e = catalog.setLabel(rows.at(1).id, 0, "seed");
    catalog.undoLabel(e.id, "seed");
  }
  std::error_code ec;
  for (const char* extra : {"-journal", "-wal", "-shm"}) {
    fs::remove(catalog_dir / (std::string("seed.sqlite") + extra), ec);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds OUT\n");
    return 2;
  }
  try {
    make(argv[1]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
