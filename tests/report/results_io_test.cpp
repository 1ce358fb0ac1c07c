// The results model's readers and writers: every file a results folder holds reads back as it was
// written, with the keys the documentation gives; a damaged file, or one of an older objscan that
// lacks a key the readers need, is an InputError naming the file and the key.

#include "objscan/report/results_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan::report {
namespace {

namespace fs = std::filesystem;
using objscan::testing::TempDir;

std::set<std::string> keysOf(const nlohmann::json& j) {
  std::set<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.insert(key);
  return keys;
}

nlohmann::json parse(const fs::path& file) {
  return nlohmann::json::parse(testing::readBytes(file));
}

Hypotheses sampleHypotheses() {
  Hypotheses h;
  h.scoring = Scoring{"average", "", "these scenes"};
  h.catalog = CatalogUse{"/tmp/catalog.sqlite", 3, 120};
  SceneRecord scene;
  scene.mesh = "out/mesh.ply";
  scene.vertices = 1000;
  scene.faces = 1900;
  scene.candidates = 12;
  scene.hypotheses = 2;
  scene.findings = SceneFindings{0.0058, 500, 1, 400, {1.5, 2.5, 3.5, 4.5, 5.5}};
  h.scenes.push_back(scene);
  for (std::size_t rank = 1; rank <= 2; ++rank) {
    HypothesisRecord r;
    r.rank = rank;
    r.score = 1.25 / static_cast<double>(rank);
    r.scene = scene.mesh;
    r.measures.compactness = 0.5;
    r.measures.symmetry = 0.125;
    r.measures.smoothness = 2.0;
    r.measures.local_convexity = 0.75;
    r.measures.global_convexity = 0.001;
    r.measures.recurrence = rank == 1 ? NAN : 0.25;  // unknown for rank 1
    OrientedBox box;
    box.centre = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
    box.axes = Eigen::Matrix3f::Identity();
    box.extents = Eigen::Vector3f(0.05f, 0.04f, 0.03f);
    r.box = box;
    r.scale = 80.0f;
    r.vertices = {static_cast<std::int32_t>(rank), 10, 20};
    r.vertex_count = r.vertices.size();
    r.file = "objects/" + rankFileName(rank, ".ply");
    h.hypotheses.push_back(r);
  }
  return h;
}

TEST(ResultsIo, TheObjectSetAndEachHypothesisContextReadBackAsWritten) {
  TempDir dir;
  Hypotheses written = sampleHypotheses();
  written.hypotheses[0].object_rank = 1;
  written.hypotheses[0].object_score = 0.75;
  written.hypotheses[0].footing = "support";
  written.hypotheses[0].height_m = 0.002;
  written.hypotheses[0].share_of_region = 1.0;
  written.hypotheses[0].observation = 1.5;
  written.hypotheses[0].rise_m = 0.09;
  written.hypotheses[0].support_noise_m = 0.002;
  written.hypotheses[0].covered_share = 0.375;
  written.hypotheses[1].object_rank = 0;  // an alternative
  written.hypotheses[1].object_score = -0.25;
  written.hypotheses[1].footing = "none";
  written.hypotheses[1].share_of_region = 0.125;  // height and observation unknown
  writeHypotheses(dir / "hypotheses.json", written);
  const nlohmann::json doc = parse(dir / "hypotheses.json");
  EXPECT_TRUE(doc["hypotheses"][0]["object_set"].get<bool>());
  EXPECT_EQ(doc["hypotheses"][0]["object_rank"].get<int>(), 1);
  EXPECT_FALSE(doc["hypotheses"][1]["object_set"].get<bool>());
  EXPECT_FALSE(doc["hypotheses"][1].contains("object_rank"));
  EXPECT_EQ(keysOf(doc["hypotheses"][1]["context"]),
            (std::set<std::string>{"footing", "height_m", "share_of_region", "observation",
                                   "rise_m", "support_noise_m", "covered_share"}));
  EXPECT_TRUE(doc["hypotheses"][1]["context"]["height_m"].is_null());
  const Hypotheses read = readHypotheses(dir / "hypotheses.json");
  for (std::size_t i = 0; i < 2; ++i) {
    const HypothesisRecord &a = written.hypotheses[i], &b = read.hypotheses[i];
    EXPECT_EQ(b.object_rank, a.object_rank);
    EXPECT_EQ(b.object_score, a.object_score);
    EXPECT_EQ(b.footing, a.footing);
    EXPECT_EQ(b.height_m, a.height_m);
    EXPECT_EQ(b.share_of_region, a.share_of_region);
    EXPECT_EQ(b.observation, a.observation);
    EXPECT_EQ(b.rise_m, a.rise_m);
    EXPECT_EQ(b.support_noise_m, a.support_noise_m);
    EXPECT_EQ(b.covered_share, a.covered_share);
  }
  // A file from before the object set: no object rank, no context.
  const Hypotheses old = readHypotheses([&] {
    writeHypotheses(dir / "old.json", sampleHypotheses());
    return dir / "old.json";
  }());
  EXPECT_FALSE(old.hypotheses[0].object_rank.has_value());
  EXPECT_TRUE(old.hypotheses[0].footing.empty());
  // An object without its rank is damaged.
  nlohmann::json damaged = doc;
  damaged["hypotheses"][0].erase("object_rank");
  testing::writeBytes(dir / "damaged.json", damaged.dump());
  testing::expectInputError([&] { readHypotheses(dir / "damaged.json"); }, dir / "damaged.json",
                            "object_rank");
}

TEST(ResultsIo, HypothesesReadBackAsWrittenWithTheDocumentedKeys) {
  TempDir dir;
  const Hypotheses written = sampleHypotheses();
  writeHypotheses(dir / "hypotheses.json", written);

  const nlohmann::json doc = parse(dir / "hypotheses.json");
  EXPECT_EQ(keysOf(doc), (std::set<std::string>{"scoring", "catalog", "scenes", "hypotheses"}));
  EXPECT_EQ(keysOf(doc["scenes"][0]),
            (std::set<std::string>{"mesh", "vertices", "faces", "candidates", "hypotheses",
                                   "from_catalog", "median_edge_m", "min_size", "support_planes",
                                   "support_vertices", "timings_ms"}));
  EXPECT_EQ(keysOf(doc["hypotheses"][0]),
            (std::set<std::string>{"rank", "score", "scene", "measures", "box", "scale",
                                   "vertex_count", "vertices", "file"}));
  EXPECT_TRUE(doc["hypotheses"][0]["measures"]["recurrence"].is_null());  // unknown: null

  const Hypotheses read = readHypotheses(dir / "hypotheses.json");
  ASSERT_EQ(read.hypotheses.size(), 2u);
  ASSERT_EQ(read.scenes.size(), 1u);
  EXPECT_EQ(read.scenes[0].mesh, "out/mesh.ply");
  EXPECT_EQ(read.scenes[0].vertices, 1000u);
  ASSERT_TRUE(read.scenes[0].findings.has_value());
  EXPECT_EQ(read.scenes[0].findings->timings_ms.measures, 5.5);
  EXPECT_EQ(read.scoring->normalised_over, "these scenes");
  EXPECT_EQ(read.catalog->segments, 120u);
  for (std::size_t i = 0; i < 2; ++i) {
    const HypothesisRecord &a = written.hypotheses[i], &b = read.hypotheses[i];
    EXPECT_EQ(b.rank, a.rank);
    EXPECT_EQ(b.score, a.score);
    EXPECT_EQ(b.vertices, a.vertices);
    EXPECT_EQ(b.file, a.file);
    EXPECT_EQ(b.scale, a.scale);
    EXPECT_EQ(b.box->extents, a.box->extents);  // floats through JSON's doubles: exact
    EXPECT_EQ(b.measures.symmetry, a.measures.symmetry);
  }
  EXPECT_TRUE(std::isnan(read.hypotheses[0].measures.recurrence));
  // Written again from what was read: the same bytes.
  writeHypotheses(dir / "again.json", read);
  EXPECT_EQ(testing::readBytes(dir / "again.json"), testing::readBytes(dir / "hypotheses.json"));
}

TEST(ResultsIo, TimingsEvaluationAndSettingsReadBackAsWritten) {
  TempDir dir;
  Timings t;
  t.source = "recordings/x.oni";
  t.interrupted = true;
  t.not_produced = {"renders/"};
  t.stages = {{"fuse", 1.5}, {"mesh", 0.25}};
  t.total_s = 2.0;
  t.frames = FrameCounts{50, 49, 1, 0, 0};
  t.mesh_vertices = 10;
  t.mesh_faces = 12;
  t.hypotheses = 3;
  writeTimings(dir / "timings.json", t);
  EXPECT_EQ(keysOf(parse(dir / "timings.json")),
            (std::set<std::string>{"source", "interrupted", "not_produced", "stages", "total_s",
                                   "frames", "mesh", "hypotheses"}));
  const Timings rt = readTimings(dir / "timings.json");
  EXPECT_EQ(rt.source, t.source);
  EXPECT_TRUE(rt.interrupted);
  EXPECT_EQ(rt.not_produced, t.not_produced);
  ASSERT_EQ(rt.stages.size(), 2u);
  EXPECT_EQ(rt.stages[1].name, "mesh");
  EXPECT_EQ(rt.frames->fused, 49u);
  EXPECT_EQ(rt.mesh_faces, 12u);

  Evaluation e;
  e.ground_truth = "gt.ply";
  e.objects = 2;
  e.found = 1;
  e.ap = 0.5;
  e.ranks = {{1, 7, "mug", 0.8, true, false, 1.0, 0.5}, {2, 0, "", 0.0, false, true, 0.5, 0.5}};
  writeEvaluation(dir / "evaluation.json", e);
  EXPECT_EQ(keysOf(parse(dir / "evaluation.json")),
            (std::set<std::string>{"ground_truth", "objects", "min_iou", "found", "ap", "curve",
                                   "hypotheses"}));
  const Evaluation re = readEvaluation(dir / "evaluation.json");
  ASSERT_EQ(re.ranks.size(), 2u);
  EXPECT_EQ(re.ranks[0].object, "mug");
  EXPECT_TRUE(re.ranks[0].found);
  EXPECT_FALSE(re.ranks[0].ignored);
  EXPECT_TRUE(re.ranks[1].ignored);
  EXPECT_EQ(re.ranks[1].precision, 0.5);
  EXPECT_EQ(re.ap, 0.5);

  Settings s;
  s.objscan_version = "9.9.9";
  s.command = "scan";
  s.options = {{"voxel-size", {"0.005859375"}, false, false},
               {"no-color", {"true"}, true, false},
               {"source", {"a b.oni"}, false, false},
               {"meshes", {"1.ply", "2.ply"}, false, true},
               {"model", {}, false, false}};
  s.intrinsics = Intrinsics::xtionDefault();
  s.intrinsics_origin = "sensor";
  writeSettings(dir / "settings.json", s);
  const nlohmann::json sj = parse(dir / "settings.json");
  EXPECT_EQ(sj["options"]["voxel-size"], 0.005859375);  // numbers as numbers
  EXPECT_EQ(sj["options"]["no-color"], true);           // flags as booleans
  EXPECT_TRUE(sj["options"]["model"].is_null());        // unset
  EXPECT_TRUE(sj["catalog"].is_null());
  const Settings rs = readSettings(dir / "settings.json");
  EXPECT_EQ(rs.command, "scan");
  EXPECT_EQ(rs.intrinsics_origin, "sensor");
  EXPECT_EQ(rs.intrinsics->fx_px, s.intrinsics->fx_px);
  std::map<std::string, std::vector<std::string>> by_name;
  for (const OptionSetting& o : rs.options) by_name[o.name] = o.values;
  EXPECT_EQ(by_name["voxel-size"], (std::vector<std::string>{"0.005859375"}));
  EXPECT_EQ(by_name["no-color"], (std::vector<std::string>{"true"}));
  EXPECT_EQ(by_name["meshes"], (std::vector<std::string>{"1.ply", "2.ply"}));
  EXPECT_TRUE(by_name["model"].empty());
}

TEST(ResultsIo, DamagedFilesAreInputErrorsNamingTheFileAndKey) {
  TempDir dir;
  testing::writeBytes(dir / "hypotheses.json",
                      "{\"hypotheses\": [{\"rank\": 1, \"vertices\": [1, -4]}]}");
  testing::expectInputError([&] { readHypotheses(dir / "hypotheses.json"); },
                            dir / "hypotheses.json", "hypotheses[0].vertices");
  testing::writeBytes(dir / "hypotheses.json", "{\"scenes\": [{}], \"hypotheses\": []}");
  testing::expectInputError([&] { readHypotheses(dir / "hypotheses.json"); },
                            dir / "hypotheses.json", "scenes[0].mesh");
  testing::writeBytes(dir / "timings.json",
                      "{\"stages\": [{\"name\": \"fuse\", \"seconds\": \"x\"}]}");
  testing::expectInputError([&] { readTimings(dir / "timings.json"); }, dir / "timings.json",
                            "stages[0].seconds");
  testing::writeBytes(dir / "settings.json", "{\"command\": \"scan\"");
  testing::expectInputError([&] { readSettings(dir / "settings.json"); }, dir / "settings.json",
                            "not valid JSON");
  testing::writeBytes(dir / "settings.json",
                      "{\"command\": \"scan\", \"options\": {\"top\": [[1]]}}");
  testing::expectInputError([&] { readSettings(dir / "settings.json"); }, dir / "settings.json",
                            "options.top");
  testing::writeBytes(dir / "evaluation.json", "{\"objects\": \"three\"}");
  testing::expectInputError([&] { readEvaluation(dir / "evaluation.json"); },
                            dir / "evaluation.json", "\"objects\" is a string");
}

TEST(ResultsIo, PicturesAreSwappedInWholeAndReadBack) {
  TempDir dir;
  // The smallest valid PNG header is enough for the reader; the bytes go through unchanged.
  std::string png("\x89PNG\r\n\x1a\n\0\0\0\rIHDR\0\0\0\x20\0\0\0\x18", 24);
  png += std::string(16, '\0');
  Pictures p;
  p.overview = pictureFromPng(png, "overview");
  p.closeups[1] = pictureFromPng(png, "rank 1");
  p.camera = OverviewCamera{"top", Pose::Identity(), Intrinsics::xtionDefault()};
  p.camera->T_W_C.translation() = Eigen::Vector3f(1, 2, 3);
  fs::create_directories(dir / "renders");
  testing::writeBytes(dir / "renders" / "stale.png", png);
  writePictures(dir.path(), p);
  EXPECT_FALSE(fs::exists(dir / "renders" / "stale.png"));  // a new folder, not a mix
  EXPECT_FALSE(fs::exists(dir / "renders.partial"));
  const Pictures r = readPictures(dir.path(), {1, 2});
  ASSERT_TRUE(r.overview.has_value());
  EXPECT_EQ(r.overview->png, png);
  EXPECT_EQ(r.overview->width, 32u);
  EXPECT_EQ(r.overview->height, 24u);
  EXPECT_EQ(r.closeups.size(), 1u);
  EXPECT_FALSE(r.contact_sheet.has_value());
  ASSERT_TRUE(r.camera.has_value());
  EXPECT_EQ(r.camera->view, "top");
  EXPECT_EQ(r.camera->T_W_C.translation(), Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(r.camera->intrinsics.width_px, 640);
  testing::expectInputError([&] { (void)pictureFromPng("not a png", "x.png"); }, "x.png",
                            "not a PNG");
}

}  // namespace
}  // namespace objscan::report
