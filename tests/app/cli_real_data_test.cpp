// `objscan info`, `discover` and `eval` on the real data in ../shared/data (label: data).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_expect.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;

TEST(CliRealData, InfoOnYcbMugReports8188VerticesAnd16384Faces) {
  const std::string mug = std::string(OBJSCAN_DATA_DIR) + "/ycb_meshes/025_mug.ply";
  const testing::ProcessResult r = testing::runProcess({OBJSCAN_EXE, "info", mug});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("vertices      8188 (normals: yes, colours: no)"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("faces         16384 triangles"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ignored       vertex.s, vertex.t"), std::string::npos) << r.out;
}

TEST(CliRealData, InfoDescribesASevenScenesFolderAsFuseReadsIt) {
  // Issue 18: info refused the 7-Scenes folders fuse accepts.
  const std::string folder = std::string(OBJSCAN_DATA_DIR) + "/7scenes_300";
  const testing::ProcessResult r = testing::runProcess({OBJSCAN_EXE, "info", folder});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("type          recording (7-Scenes folder)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("frames        300"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fx 585.0 fy 585.0 cx 320.0 cy 240.0, 640x480 px"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("depth units   16-bit millimetres"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ground truth  300 poses"), std::string::npos) << r.out;
}

/// Two real single-view Kinect scans of mOSD's learn split (both in the half objscan's defaults
/// were not tuned on): three stacked boxes, and eight object parts of cylinders and boxes.
/// Evaluated on their label fields, object parts counted separately as the database intends.
TEST(CliRealData, EvalOnLabelledKinectScansFindsTheirObjects) {
  testing::TempDir dir;
  const std::string mosd = std::string(OBJSCAN_DATA_DIR) + "/mosd_learn/";
  const testing::ProcessResult r = testing::objscan(
      {"eval", mosd + "learn21.pcd", mosd + "learn33.pcd", "--out", (dir.path() / "e").string(),
       "--no-classifiers", "--category", "stacked=learn2.\\.pcd"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(dir.path() / "e" / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(in);
  const nlohmann::json& parts = summary.at("per_scene_objects");
  EXPECT_EQ(parts.at("objects").get<int>(), 11);
  // Measured 1.0 at both IoUs and AP 0.92 (objscan eval, these two scenes); the tolerance
  // allows one of the eleven parts to be lost.
  EXPECT_GE(parts.at("recall_0.5").get<double>(), 0.9);
  EXPECT_GE(parts.at("recall_0.7").get<double>(), 0.9);
  EXPECT_GE(parts.at("ap_0.5").get<double>(), 0.8);
  EXPECT_EQ(parts.at("categories").at("stacked").at("scenes").get<int>(), 1);
  EXPECT_EQ(summary.at("per_scene_whole_objects").at("objects").get<int>(), 8);
}

/// The demo's desk (recordings/tum_fr2_desk.oni) against its hand-checked labels
/// (tum_fr2_desk_50/objects/: nine objects; the plant, lamp, packaging box, monitor and teddy
/// ignored): the
/// labels move onto this fusion by the nearest labelled vertex within 1.5 cm, and each of the
/// five hypotheses a user sees first is one of the nine objects, cut out at IoU 0.5 or better.
/// Measured 2026-11-29 (fusion carving): tape, mouse, mug, front can and keyboard at IoU 0.97 to
/// 0.99, then the dice at 0.61, a piece of background and the book at 0.76; all 9 found at IoU 0.7
/// (7 before patches kept off creases: at least 8 must be, one lost to a borderline cut is
/// tolerated).
TEST(CliRealData, TheDemosTopFiveAreFiveOfTheNineLabelledObjectsOfItsDesk) {
  testing::TempDir dir;
  const std::string objects = std::string(OBJSCAN_DATA_DIR) + "/tum_fr2_desk_50/objects/";
  const fs::path out = dir.path() / "demo";
  const testing::ProcessResult r = testing::objscan(
      {"scan", (fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk.oni").string(), "--out",
       out.string(), "--no-catalog", "--ground-truth", objects + "labelled_mesh.ply"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(out / "evaluation.json");
  const nlohmann::json evaluation = nlohmann::json::parse(in);
  EXPECT_EQ(evaluation.at("objects").get<int>(), 9);
  EXPECT_EQ(evaluation.at("min_iou").get<double>(), 0.7);
  EXPECT_GE(evaluation.at("found").get<int>(), 8);
  const nlohmann::json& ranks = evaluation.at("hypotheses");
  ASSERT_GE(ranks.size(), 5u);
  std::set<int> ids;
  for (std::size_t k = 0; k < 5; ++k) {
    const nlohmann::json& rank = ranks.at(k);
    SCOPED_TRACE("rank " + std::to_string(k + 1) + ": " + rank.dump());
    EXPECT_FALSE(rank.at("ignored").get<bool>());
    EXPECT_NE(rank.at("object_id").get<int>(), 0);
    EXPECT_GE(rank.at("iou").get<double>(), 0.5);
    EXPECT_FALSE(rank.at("object").is_null());  // named from objects.json
    ids.insert(rank.at("object_id").get<int>());
  }
  EXPECT_EQ(ids.size(), 5u);
  // They are the object set's first five, which never overlap.
  std::ifstream hin(out / "hypotheses.json");
  const nlohmann::json hypotheses = nlohmann::json::parse(hin).at("hypotheses");
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_EQ(hypotheses.at(k).at("object_rank").get<std::size_t>(), k + 1);
  }
}

TEST(CliRealData, DiscoverReadsAKinectScanAndRefusesADamagedOne) {
  testing::TempDir dir;
  const std::string scan = std::string(OBJSCAN_DATA_DIR) + "/mosd_learn/learn1.pcd";
  testing::ProcessResult r =
      testing::objscan({"discover", scan, "--out", (dir.path() / "d").string(), "--no-catalog"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(dir.path() / "d" / "hypotheses.json");
  EXPECT_GE(nlohmann::json::parse(in).at("hypotheses").size(), 2u);
  const std::string bytes = testing::readBytes(scan);
  testing::writeBytes(dir.path() / "cut.pcd", bytes.substr(0, bytes.size() / 2));
  r = testing::objscan({"discover", (dir.path() / "cut.pcd").string(), "--out",
                        (dir.path() / "x").string(), "--no-catalog"});
  testing::expectOneErrorLine(r, 2, "truncated");
}

}  // namespace
}  // namespace objscan
