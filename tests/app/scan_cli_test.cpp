// `objscan scan` and `objscan render` end to end on a synthetic scene with ground truth: every
// output is there and readable, the overview paints exactly the top hypotheses of
// hypotheses.json, and those are the ground-truth objects the evaluation says; bad input gives one
// error line and the documented exit code.

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "background_process.h"
#include "cli_expect.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "objscan/render/offscreen_renderer.h"
#include "objscan/report/results_io.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::expectOneErrorLine;
using testing::ProcessResult;
using testing::TempDir;

using testing::objscan;

nlohmann::json readJson(const fs::path& file) { return nlohmann::json::parse(readWholeFile(file)); }

/// The overview's camera as render wrote it, through the results model's reader.
report::OverviewCamera readCamera(const fs::path& results) {
  const std::optional<report::OverviewCamera> camera = report::readPictures(results, {}).camera;
  if (!camera) throw std::runtime_error(results.string() + ": no overview_camera.json");
  return *camera;
}

/// Renders `mesh` with `labels` from the camera and returns the label image.
cv::Mat renderLabels(TriangleMesh mesh, std::vector<std::int32_t> labels,
                     const report::OverviewCamera& camera) {
  mesh.labels = std::move(labels);
  mesh.colors.clear();
  render::OffscreenRenderer renderer(camera.intrinsics, 0.005f, 200.0f);
  renderer.setMesh(mesh);
  return renderer.render(camera.T_W_C).label;
}

/// One scan of a synthetic desk (with ground truth beside it), shared by the tests that only read
/// its outputs.
class ScanCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    scene_ = *dir_ / "desk";
    const ProcessResult synth = objscan(
        {"synth", "--out", scene_.string(), "--frames", "30", "--objects", "6", "--seed", "11"});
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    out_ = *dir_ / "scan";
    scan_ =
        objscan({"scan", scene_.string(), "--out", out_.string(), "--no-catalog", "--ranks-image"});
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  static TempDir* dir_;
  static fs::path scene_, out_;
  static ProcessResult scan_;
};

TempDir* ScanCli::dir_ = nullptr;
fs::path ScanCli::scene_, ScanCli::out_;
ProcessResult ScanCli::scan_;

TEST_F(ScanCli, WritesEveryOutputAndEndsWithTheReportsPath) {
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const std::vector<std::string> out_lines = testing::lines(scan_.out);
  ASSERT_FALSE(out_lines.empty());
  EXPECT_EQ(out_lines.back(), "report        " + (out_ / "report.html").string());
  EXPECT_NE(scan_.out.find("30 read, 30 fused"), std::string::npos) << scan_.out;
  EXPECT_NE(scan_.err.find("scan [1/4] fusing frames"), std::string::npos) << scan_.err;

  EXPECT_GT(readPly(out_ / "mesh.ply").triangles.size(), 10000u);
  EXPECT_EQ(readTumTrajectory(out_ / "trajectory.txt").size(), 30u);
  const nlohmann::json hypotheses = readJson(out_ / "hypotheses.json");
  const std::size_t n = hypotheses.at("hypotheses").size();
  ASSERT_GE(n, 5u);
  for (std::size_t rank = 1; rank <= n; ++rank) {
    char name[32];
    std::snprintf(name, sizeof name, "rank_%03zu", rank);
    EXPECT_TRUE(fs::is_regular_file(out_ / "objects" / (std::string(name) + ".ply"))) << name;
    // Close-ups of the top 5 only.
    EXPECT_EQ(fs::exists(out_ / "renders" / (std::string(name) + ".png")), rank <= 5) << name;
  }
  const cv::Mat overview = cv::imread((out_ / "renders" / "overview.png").string());
  EXPECT_EQ(overview.size(), cv::Size(1280, 960));
  const cv::Mat close = cv::imread((out_ / "renders" / "rank_001.png").string());
  EXPECT_EQ(close.size(), cv::Size(480, 360));
  EXPECT_FALSE(cv::imread((out_ / "renders" / "contact_sheet.png").string()).empty());
  EXPECT_TRUE(fs::is_regular_file(out_ / "report.html"));
  EXPECT_TRUE(fs::is_regular_file(out_ / "settings.json"));

  const nlohmann::json timings = readJson(out_ / "timings.json");
  std::vector<std::string> stages;
  for (const auto& s : timings.at("stages")) {
    stages.push_back(s.at("name"));
    EXPECT_GE(s.at("seconds").get<double>(), 0.0);
  }
  EXPECT_EQ(stages, (std::vector<std::string>{"fuse", "mesh", "discover", "evaluation", "render",
                                              "report"}));
  EXPECT_FALSE(timings.at("interrupted").get<bool>());
  EXPECT_EQ(timings.at("frames").at("fused").get<int>(), 30);
  EXPECT_EQ(timings.at("hypotheses").get<std::size_t>(), n);
  // No temporary or staging files are left behind.
  for (const auto& entry : fs::directory_iterator(out_)) {
    const std::string name = entry.path().filename().string();
    EXPECT_EQ(name.find("partial"), std::string::npos) << name;
    EXPECT_EQ(name.find(".tmp"), std::string::npos) << name;
  }
}

TEST_F(ScanCli, OverviewPaintsExactlyTheTopFiveOfHypothesesJson) {
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  // Render ranks again, independently of the renderer's painting: each vertex of the scene mesh
  // labelled with the best rank of the top-5 hypotheses in hypotheses.json that holds it.
  const TriangleMesh mesh = readPly(out_ / "mesh.ply");
  const nlohmann::json doc = readJson(out_ / "hypotheses.json");
  std::vector<std::int32_t> ranks(mesh.positions.size(), 0);
  for (int k = 4; k >= 0; --k) {
    for (std::int32_t v : doc.at("hypotheses").at(k).at("vertices")) ranks[v] = k + 1;
  }
  const report::OverviewCamera camera = readCamera(out_);
  const cv::Mat expected = renderLabels(mesh, ranks, camera);
  const cv::Mat painted =
      cv::imread((out_ / "renders" / "overview_ranks.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(painted.type(), CV_16UC1);
  ASSERT_EQ(painted.size(), expected.size());
  cv::Mat painted32;
  painted.convertTo(painted32, CV_32S);
  const int differing = cv::countNonZero(painted32 != expected);
  EXPECT_EQ(differing, 0);
  std::set<int> seen;
  for (int y = 0; y < painted32.rows; ++y) {
    for (int x = 0; x < painted32.cols; ++x) seen.insert(painted32.at<std::int32_t>(y, x));
  }
  seen.erase(0);
  // From where the sensor looked, all five show (the trajectory view frames them all).
  EXPECT_EQ(seen, (std::set<int>{1, 2, 3, 4, 5}));
  EXPECT_NE(scan_.out.find("visible: #1, #2, #3, #4, #5"), std::string::npos) << scan_.out;
}

TEST_F(ScanCli, PaintedHypothesesShowTheGroundTruthObjectsTheEvaluationNames) {
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const nlohmann::json evaluation = readJson(out_ / "evaluation.json");
  EXPECT_EQ(evaluation.at("ground_truth").get<std::string>(), (scene_ / "scene_gt.ply").string());
  EXPECT_EQ(evaluation.at("objects").get<int>(), 6);
  // The ground truth's object ids rendered from the overview's camera: under each painted rank
  // that found an object, most pixels show that object.
  const TriangleMesh truth = readPly(scene_ / "scene_gt.ply");
  const report::OverviewCamera camera = readCamera(out_);
  const cv::Mat truth_ids = renderLabels(truth, truth.labels, camera);
  const cv::Mat painted =
      cv::imread((out_ / "renders" / "overview_ranks.png").string(), cv::IMREAD_UNCHANGED);
  int checked = 0;
  for (int rank = 1; rank <= 5; ++rank) {
    const nlohmann::json& match = evaluation.at("hypotheses").at(rank - 1);
    ASSERT_EQ(match.at("rank").get<int>(), rank);
    if (match.at("iou").get<double>() < 0.5) continue;
    std::map<int, int> votes;
    for (int y = 0; y < painted.rows; ++y) {
      for (int x = 0; x < painted.cols; ++x) {
        if (painted.at<std::uint16_t>(y, x) == rank) ++votes[truth_ids.at<std::int32_t>(y, x)];
      }
    }
    int best = -1, best_votes = -1, total = 0;
    for (const auto& [id, count] : votes) {
      total += count;
      if (count > best_votes) {
        best = id;
        best_votes = count;
      }
    }
    EXPECT_EQ(best, match.at("object_id").get<int>()) << "rank " << rank;
    EXPECT_GT(best_votes, 0.7 * total) << "rank " << rank;
    ++checked;
  }
  EXPECT_GE(checked, 3);
  const double ap = evaluation.at("ap").get<double>();
  EXPECT_GT(ap, 0.3);
  EXPECT_LE(ap, 1.0);
}

TEST_F(ScanCli, RenderAgainReplacesTheRendersWithTheNewOptions) {
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const fs::path copy = *dir_ / "render_again";
  fs::copy(out_, copy, fs::copy_options::recursive);
  const ProcessResult r = objscan(
      {"render", copy.string(), "--top", "3", "--size", "640x480", "--view", "three-quarter"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(copy / "renders")) {
    files.insert(e.path().filename().string());
  }
  EXPECT_EQ(files, (std::set<std::string>{"overview.png", "overview_camera.json", "rank_001.png",
                                          "rank_002.png", "rank_003.png", "contact_sheet.png"}));
  EXPECT_EQ(cv::imread((copy / "renders" / "overview.png").string()).size(), cv::Size(640, 480));
  EXPECT_EQ(readJson(copy / "renders" / "overview_camera.json").at("view"), "three-quarter");
  EXPECT_NE(r.out.find("report        " + (copy / "report.html").string()), std::string::npos)
      << r.out;
  // The folder's settings now say how its pictures were made; the rest stays the scan's.
  std::map<std::string, std::vector<std::string>> options;
  for (const report::OptionSetting& o : report::readSettings(copy / "settings.json").options) {
    options[o.name] = o.values;
  }
  EXPECT_EQ(options["top"], std::vector<std::string>{"3"});
  EXPECT_EQ(options["view"], std::vector<std::string>{"three-quarter"});
  EXPECT_EQ(options["size"], std::vector<std::string>{"640x480"});
  EXPECT_EQ(options["source"], std::vector<std::string>{scene_.string()});
}

TEST_F(ScanCli, PicturesThatWouldNotFitInMemoryAreRefusedBeforeRendering) {
  // OSMesa crashed (SIGSEGV, exit 139) when it ran out of memory; the pictures are refused first.
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const fs::path copy = *dir_ / "small_machine";
  fs::create_directories(copy);
  for (const char* name : {"mesh.ply", "hypotheses.json", "trajectory.txt"}) {
    fs::copy_file(out_ / name, copy / name);
  }
  testing::ProcessOptions small;
  small.env = {"OBJSCAN_MEMORY_LIMIT=100M"};
  expectOneErrorLine(testing::runProcess({OBJSCAN_EXE, "render", copy.string()}, small), 1,
                     "more than the 100 MB OBJSCAN_MEMORY_LIMIT allows");
  EXPECT_FALSE(fs::exists(copy / "renders"));
}

TEST_F(ScanCli, RenderNamesWhatIsMissing) {
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const fs::path missing = *dir_ / "nothing_here";
  expectOneErrorLine(objscan({"render", missing.string()}), 2, missing.string() + ": missing");

  const fs::path empty = *dir_ / "empty_results";
  fs::create_directories(empty);
  expectOneErrorLine(objscan({"render", empty.string()}), 2,
                     (empty / "hypotheses.json").string() + ": missing");

  // hypotheses.json without its mesh (and the mesh it names gone too).
  const fs::path no_mesh = *dir_ / "no_mesh";
  fs::create_directories(no_mesh);
  nlohmann::json doc = readJson(out_ / "hypotheses.json");
  doc["scenes"][0]["mesh"] = (no_mesh / "gone.ply").string();
  doc["scenes"][0]["mesh_absolute"] = (no_mesh / "gone.ply").string();
  for (auto& h : doc["hypotheses"]) h["scene"] = (no_mesh / "gone.ply").string();
  writeFileAtomically(no_mesh / "hypotheses.json", doc.dump());
  expectOneErrorLine(objscan({"render", no_mesh.string()}), 2,
                     (no_mesh / "mesh.ply").string() + ": missing");

  // A mesh that is not the one the hypotheses were found in.
  writePly(no_mesh / "mesh.ply", testing::makeCube());
  expectOneErrorLine(objscan({"render", no_mesh.string()}), 2,
                     (no_mesh / "mesh.ply").string() + ": has 8 vertices");

  // A hypothesis naming a vertex the scene does not have: refused before any picture is made.
  nlohmann::json bad = readJson(out_ / "hypotheses.json");
  bad["hypotheses"][2]["vertices"].push_back(bad["scenes"][0]["vertices"].get<int>());
  const fs::path bad_dir = *dir_ / "bad_vertex";
  fs::create_directories(bad_dir);
  fs::copy_file(out_ / "mesh.ply", bad_dir / "mesh.ply");
  writeFileAtomically(bad_dir / "hypotheses.json", bad.dump());
  expectOneErrorLine(objscan({"render", bad_dir.string()}), 2,
                     (bad_dir / "hypotheses.json").string() + ": hypothesis 3 names vertex");
  EXPECT_EQ(testing::entryCount(bad_dir), 2u);  // no renders/, no renders.partial/

  // A hypothesis of a scene the file does not list (issue 18: render painted nothing, exit 0).
  nlohmann::json stray = readJson(out_ / "hypotheses.json");
  stray["hypotheses"][1]["scene"] = "elsewhere.ply";
  writeFileAtomically(bad_dir / "hypotheses.json", stray.dump());
  expectOneErrorLine(objscan({"render", bad_dir.string()}), 2,
                     (bad_dir / "hypotheses.json").string() +
                         ": \"hypotheses[1].scene\" names a scene that \"scenes\" does not list");

  // No hypotheses: the overview alone, and the progress bar ends at 100 % (it stopped at 50 %).
  nlohmann::json none = readJson(out_ / "hypotheses.json");
  none["hypotheses"] = nlohmann::json::array();
  writeFileAtomically(bad_dir / "hypotheses.json", none.dump());
  const ProcessResult empty_render = objscan({"render", bad_dir.string()});
  EXPECT_EQ(empty_render.exit_code, 0) << empty_render.err;
  EXPECT_NE(empty_render.err.find("100% (1/1)"), std::string::npos) << empty_render.err;
  EXPECT_NE(empty_render.out.find("written       1 picture ("), std::string::npos)
      << empty_render.out;

  // Truncated JSON.
  writeFileAtomically(no_mesh / "hypotheses.json", doc.dump().substr(0, 100));
  expectOneErrorLine(objscan({"render", no_mesh.string()}), 2,
                     (no_mesh / "hypotheses.json").string() + ": not valid JSON");
  EXPECT_FALSE(fs::exists(no_mesh / "renders"));
  expectOneErrorLine(objscan({"render", out_.string(), "--size", "640-480"}), 2, "--size");
}

/// hypotheses.json's bytes with the scenes' stage timings (wall time, never the same twice) zeroed
/// and each scene named by its absolute path (folders in different places name the same mesh by
/// different relative paths).
std::string withoutTimings(const fs::path& file) {
  report::Hypotheses h = report::readHypotheses(file);
  for (report::SceneRecord& s : h.scenes) {
    if (s.findings) s.findings->timings_ms = {};
    for (report::HypothesisRecord& r : h.hypotheses) {
      if (r.scene == s.mesh) r.scene = s.mesh_absolute;
    }
    s.mesh = s.mesh_absolute;
  }
  const fs::path copy = file.parent_path() / "untimed.json";
  report::writeHypotheses(copy, h);
  const std::string bytes = readWholeFile(copy);
  fs::remove(copy);
  return bytes;
}

TEST_F(ScanCli, HypothesesAreExactlyWhatDiscoverFindsOnTheWrittenMesh) {
  // scan hands its mesh to discovery in memory; discover reads mesh.ply back from disk. The two
  // must agree to the byte: the mesh file holds exactly what was discovered on.
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const fs::path again = *dir_ / "discover_again";
  const ProcessResult r =
      objscan({"discover", (out_ / "mesh.ply").string(), "--out", again.string(), "--no-catalog"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(withoutTimings(out_ / "hypotheses.json"), withoutTimings(again / "hypotheses.json"));
  EXPECT_EQ(readWholeFile(out_ / "objects" / "rank_001.ply"),
            readWholeFile(again / "objects" / "rank_001.ply"));
}

TEST_F(ScanCli, ConfigRepeatsARunFromAnotherDirectoryWithTheSameMeshAndCatalogScene) {
  // settings.json kept its paths as typed, so --config failed from another directory; and the
  // fused mesh's vertex order followed the thread schedule, so the catalog (which keys a scene by
  // its content) took the repeat for a new desk and recurrence matched the scan against itself.
  // A run made with relative paths, repeated from another directory: the same mesh to the byte,
  // the same catalog scene, the same hypotheses.
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  fs::create_directories(*dir_ / "elsewhere");
  testing::ProcessOptions in_dir;
  in_dir.cwd = dir_->path();
  const ProcessResult first =
      testing::runProcess({OBJSCAN_EXE, "scan", scene_.filename().string(), "--out",
                           "repeat_first", "--catalog", "repeat.sqlite", "--frames", "15"},
                          in_dir);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  testing::ProcessOptions elsewhere;
  elsewhere.cwd = *dir_ / "elsewhere";
  const ProcessResult again = testing::runProcess(
      {OBJSCAN_EXE, "scan", "--config", "../repeat_first/settings.json", "--out", "again"},
      elsewhere);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const fs::path a = *dir_ / "repeat_first", b = *dir_ / "elsewhere/again";
  EXPECT_TRUE(readWholeFile(a / "mesh.ply") == readWholeFile(b / "mesh.ply"))
      << "the same frames fused twice give another mesh.ply";
  const report::Settings settings = report::readSettings(a / "settings.json");
  for (const report::OptionSetting& o : settings.options) {
    if (o.name == "source" || o.name == "catalog" || o.name == "out") {
      ASSERT_EQ(o.values.size(), 1u) << o.name;
      EXPECT_TRUE(fs::path(o.values[0]).is_absolute()) << o.name << ": " << o.values[0];
    }
  }
  const report::Hypotheses h1 = report::readHypotheses(a / "hypotheses.json");
  const report::Hypotheses h2 = report::readHypotheses(b / "hypotheses.json");
  ASSERT_TRUE(h1.catalog && h2.catalog);
  EXPECT_EQ(h1.catalog->path, (*dir_ / "repeat.sqlite").string());
  EXPECT_EQ(h2.catalog->path, h1.catalog->path);
  EXPECT_EQ(h2.catalog->scenes, 1u) << "the repeat was added as a second scene";
  ASSERT_EQ(h1.scenes.size(), 1u);
  ASSERT_EQ(h2.scenes.size(), 1u);
  EXPECT_EQ(h2.scenes[0].catalog_scene, h1.scenes[0].catalog_scene);
  ASSERT_EQ(h1.hypotheses.size(), h2.hypotheses.size());
  ASSERT_FALSE(h1.hypotheses.empty());
  for (std::size_t i = 0; i < h1.hypotheses.size(); ++i) {
    const report::HypothesisRecord &x = h1.hypotheses[i], &y = h2.hypotheses[i];
    EXPECT_EQ(x.vertices, y.vertices) << "rank " << i + 1;
    EXPECT_EQ(x.score, y.score) << "rank " << i + 1;
  }
}

TEST_F(ScanCli, SettingsJsonSaysHowTheRunWasMadeAndConfigRepeatsIt) {
  ASSERT_EQ(scan_.exit_code, 0) << scan_.err;
  const report::Settings settings = report::readSettings(out_ / "settings.json");
  EXPECT_EQ(settings.command, "scan");
  EXPECT_FALSE(settings.objscan_version.empty());
  EXPECT_EQ(settings.intrinsics_origin.empty(), false);
  ASSERT_TRUE(settings.intrinsics.has_value());
  EXPECT_EQ(settings.intrinsics->width_px, 640);
  EXPECT_FALSE(settings.catalog.has_value());  // --no-catalog
  std::map<std::string, std::vector<std::string>> options;
  for (const report::OptionSetting& o : settings.options) options[o.name] = o.values;
  EXPECT_EQ(options["source"], std::vector<std::string>{scene_.string()});
  EXPECT_EQ(options["no-catalog"], std::vector<std::string>{"true"});
  EXPECT_EQ(options["ranks-image"], std::vector<std::string>{"true"});
  EXPECT_EQ(options["voxel-size"], std::vector<std::string>{"0.005859375"});  // every digit
  // The truncation is left to its default (it follows the voxel size), and the value used noted.
  EXPECT_TRUE(options["truncation"].empty());
  // So is whether the volume carved (the flags say only what was given).
  const auto resolvedOf = [](const report::Settings& s) {
    std::map<std::string, std::vector<std::string>> values;
    for (const report::OptionSetting& o : s.resolved) values[o.name] = o.values;
    return values;
  };
  EXPECT_EQ(resolvedOf(settings), (std::map<std::string, std::vector<std::string>>{
                                      {"truncation", {"0.03"}}, {"carve", {"true"}}}));
  EXPECT_EQ(options["top"], std::vector<std::string>{"5"});
  // The report shows them.
  EXPECT_NE(readWholeFile(out_ / "report.html").find("id=\"settings\""), std::string::npos);

  // The same run again from the file; flags on the command line override it: a smaller top, a
  // coarser voxel (the truncation, left to its default, follows it: 3 voxels = 6 cm), and a
  // catalog where the file says --no-catalog (the two exclude each other: the file's gives way).
  const fs::path again = *dir_ / "scan_again";
  const fs::path catalog = *dir_ / "again.sqlite";
  const ProcessResult r =
      objscan({"scan", "--config", (out_ / "settings.json").string(), "--out", again.string(),
               "--top", "2", "--voxel-size", "0.02", "--catalog", catalog.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(again / "renders" / "rank_002.png"));
  EXPECT_FALSE(fs::exists(again / "renders" / "rank_003.png"));
  EXPECT_TRUE(
      fs::exists(again / "renders" / "overview_ranks.png"));  // --ranks-image, from the file
  EXPECT_TRUE(fs::exists(catalog));
  const report::Settings repeated = report::readSettings(again / "settings.json");
  std::map<std::string, std::vector<std::string>> repeated_options;
  for (const report::OptionSetting& o : repeated.options) repeated_options[o.name] = o.values;
  options["out"] = {again.string()};
  options["top"] = {"2"};
  options["voxel-size"] = {"0.02"};
  options["catalog"] = {catalog.string()};
  options["no-catalog"] = {"false"};
  EXPECT_EQ(repeated_options, options);
  EXPECT_EQ(resolvedOf(repeated), (std::map<std::string, std::vector<std::string>>{
                                      {"truncation", {"0.06"}}, {"carve", {"true"}}}));
  ASSERT_TRUE(repeated.catalog.has_value());
  EXPECT_EQ(repeated.catalog->path, catalog.string());

  // Settings of another command, or a damaged file: one error line naming it, exit 2.
  expectOneErrorLine(objscan({"discover", "--config", (out_ / "settings.json").string(), "--out",
                              (*dir_ / "nope").string()}),
                     2, (out_ / "settings.json").string() + ": the settings of objscan scan");
  const fs::path broken = *dir_ / "broken_settings.json";
  writeFileAtomically(broken, "{\"command\": \"scan\", \"options\": ");
  expectOneErrorLine(objscan({"scan", "--config", broken.string(), "--out", again.string()}), 2,
                     broken.string() + ": not valid JSON");
  const fs::path foreign = *dir_ / "foreign_settings.json";
  writeFileAtomically(foreign, "{\"command\": \"scan\", \"options\": {\"frobnicate\": 1}}");
  expectOneErrorLine(
      objscan({"scan", "--config", foreign.string(), "--out", again.string()}), 2,
      foreign.string() + ": \"options.frobnicate\" is not an option of objscan scan");
}

/// Whether this test, and with it the objscan it runs, is built with AddressSanitizer.
constexpr bool kAddressSanitizer =
#if defined(__SANITIZE_ADDRESS__)
    true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    true;
#else
    false;
#endif
#else
    false;
#endif

/// objscan with `args`, guarded so that a regression fails instead of hanging or exhausting the
/// machine: killed after 10 s (exit -1; a FIFO opened for reading waits for a writer forever)
/// and held to 3 GB (/dev/zero read to its end takes all memory): of address space, or under
/// AddressSanitizer, which reserves terabytes of it for its shadow, of resident memory.
ProcessResult guardedObjscan(const std::vector<std::string>& args) {
  const char* asan_options = std::getenv("ASAN_OPTIONS");
  std::string command =
      kAddressSanitizer
          ? "ASAN_OPTIONS='" + std::string(asan_options ? asan_options : "") +
                ":hard_rss_limit_mb=3000' exec '" + std::string(OBJSCAN_EXE) + "'"
          : "ulimit -v 3000000 && exec '" + std::string(OBJSCAN_EXE) + "'";
  for (const std::string& a : args) command += " '" + a + "'";  // test paths hold no quote
  testing::BackgroundProcess run({"/bin/sh", "-c", command});
  ProcessResult r;
  r.exit_code = run.wait(10);
  r.out = run.out();
  r.err = run.err();
  return r;
}

TEST(ScanCliErrors, SettingsThatAreNoRegularFileOrTooLargeAreRefusedBeforeAnyRead) {
  TempDir dir;
  const fs::path fifo = dir / "settings.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // 2 GB that take no disk: a sparse file.
  const fs::path sparse = dir / "sparse.json";
  testing::writeBytes(sparse, "");
  ASSERT_EQ(::truncate(sparse.c_str(), std::int64_t{2} << 30), 0);
  for (const fs::path& file : {fs::path("/dev/zero"), fs::path("/dev/urandom"), fifo, sparse}) {
    const fs::path out = dir / "out";
    const ProcessResult r =
        guardedObjscan({"scan", "--config", file.string(), "--out", out.string()});
    expectOneErrorLine(r, 2, file.string() + ": ");
    EXPECT_NE(r.err.find(file == sparse ? "more than the 1048576" : "not a regular file"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(out)) << file;
  }
}

TEST(ScanCliErrors, AnOutputFolderThatCannotBeWrittenFailsBeforeFusing) {
  TempDir dir;
  fs::path read_only = dir / "read_only";
  fs::create_directory(read_only);
  fs::permissions(read_only, fs::perms::owner_read | fs::perms::owner_exec);
  // Root writes anywhere permissions say no; sysfs takes no new files, even from root.
  if (::access(read_only.c_str(), W_OK) == 0) read_only = "/sys";
  const ProcessResult r = objscan({"scan", "synth:3,frames=5", "--out", read_only.string()});
  expectOneErrorLine(r, 1, read_only.string() + ": cannot write into the output folder");
  EXPECT_EQ(r.err.find("fusing"), std::string::npos) << r.err;

  testing::writeBytes(dir / "a_file", "x");
  expectOneErrorLine(objscan({"scan", "synth:3,frames=5", "--out", (dir / "a_file").string()}), 1,
                     (dir / "a_file").string());
  fs::permissions(dir / "read_only", fs::perms::owner_all);
}

TEST(ScanCliErrors, MissingSourceIsBadInput) {
  TempDir dir;
  const fs::path missing = dir / "missing.oni";
  expectOneErrorLine(objscan({"scan", missing.string(), "--out", (dir / "out").string()}), 2,
                     missing.string());
  expectOneErrorLine(objscan({"scan", "synth:3,frames=5", "--out", (dir / "out").string(),
                              "--ground-truth", (dir / "gt.ply").string()}),
                     2, (dir / "gt.ply").string() + ": missing");
}

TEST(ScanCliErrors, CtrlCWhileFusingKeepsTheMeshAndSaysWhatWasNotProduced) {
  TempDir dir;
  const fs::path out = dir / "out";
  testing::ProcessOptions interrupt;
  interrupt.signal = SIGINT;
  interrupt.signal_when = "fusing frames:  10%";
  const ProcessResult r = testing::runProcess({OBJSCAN_EXE, "scan", "synth:4,frames=200,objects=2",
                                               "--out", out.string(), "--no-color", "--no-catalog"},
                                              interrupt);
  EXPECT_EQ(r.exit_code, 130) << r.err;
  EXPECT_NE(r.out.find("not produced: hypotheses.json, objects/, renders/, report.html"),
            std::string::npos)
      << r.out;
  const std::size_t fused = readTumTrajectory(out / "trajectory.txt").size();
  EXPECT_GE(fused, 20u);
  EXPECT_LT(fused, 200u);
  EXPECT_GT(readPly(out / "mesh.ply").triangles.size(), 1000u);
  const nlohmann::json timings = readJson(out / "timings.json");
  EXPECT_TRUE(timings.at("interrupted").get<bool>());
  EXPECT_EQ(timings.at("not_produced").size(), 4u);
  for (const char* name : {"hypotheses.json", "objects", "renders", "report.html"}) {
    EXPECT_FALSE(fs::exists(out / name)) << name;
  }
}

}  // namespace
}  // namespace objscan

namespace objscan {
namespace {

/// A synthetic desk recording (a TUM folder with ground truth) for the virtual sensor to stream.
fs::path syntheticDesk(const TempDir& dir, const std::string& frames, const std::string& objects,
                       const std::string& seed) {
  const fs::path scene = dir / "scene";
  const ProcessResult r = objscan(
      {"synth", "--out", scene.string(), "--frames", frames, "--objects", objects, "--seed", seed});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return scene;
}

TEST(ScanCliLive, VirtualSensorIsFusedAndRecordedAtOnce) {
  TempDir dir;
  const fs::path scene = syntheticDesk(dir, "20", "4", "6");
  const fs::path out = dir / "out", oni = dir / "session.oni";
  const ProcessResult r = objscan({"scan", "virtual:" + scene.string(), "--out", out.string(),
                                   "--record", oni.string(), "--no-catalog"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_regular_file(out / "report.html"));
  EXPECT_TRUE(fs::is_regular_file(out / "renders" / "overview.png"));
  // The recording replays, and holds at least every frame that was fused.
  const std::size_t fused = readTumTrajectory(out / "trajectory.txt").size();
  const ProcessResult info = objscan({"info", oni.string()});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  std::size_t recorded = 0;
  for (const std::string& line : testing::lines(info.out)) {
    if (line.rfind("frames", 0) == 0) recorded = std::stoul(line.substr(6));
  }
  EXPECT_GE(recorded, fused);
  EXPECT_LE(recorded, 20u);
  EXPECT_NE(r.out.find("recording     "), std::string::npos) << r.out;
}

TEST(ScanCliLive, ASensorUnpluggedMidScanStillGivesEveryOutputThenExitOne) {
  TempDir dir;
  const fs::path scene = syntheticDesk(dir, "20", "4", "6");
  const fs::path out = dir / "out", oni = dir / "session.oni";
  const ProcessResult r =
      objscan({"scan", "virtual:" + scene.string() + "?unplug_after=12", "--out", out.string(),
               "--record", oni.string(), "--no-catalog"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  std::size_t errors = 0;
  for (const std::string& l : testing::lines(r.err)) {
    errors += l.rfind("objscan: error: ", 0) == 0 ? 1 : 0;
  }
  EXPECT_EQ(errors, 1u) << r.err;
  EXPECT_NE(r.err.find("(it was unplugged)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("; " + oni.string() + " holds the "), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_regular_file(out / "report.html"));
  const std::size_t fused = readTumTrajectory(out / "trajectory.txt").size();
  EXPECT_GE(fused, 1u);
  EXPECT_LE(fused, 12u);
  EXPECT_EQ(objscan({"info", oni.string()}).exit_code, 0);
  EXPECT_NE(readJson(out / "timings.json").at("sensor_lost").get<std::string>().find(oni.string()),
            std::string::npos);
}

TEST(ScanCliLive, ASensorUnpluggedMidScanWithoutRecordingIsExitOneAndInTimings) {
  // Issue 18, defect 2: without --record, scan said nothing and exited 0.
  TempDir dir;
  const fs::path scene = syntheticDesk(dir, "20", "4", "6");
  const fs::path out = dir / "out";
  const ProcessResult r = objscan({"scan", "virtual:" + scene.string() + "?unplug_after=12",
                                   "--out", out.string(), "--no-catalog"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("(it was unplugged)"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::is_regular_file(out / "report.html"));
  EXPECT_NE(readJson(out / "timings.json").at("sensor_lost").get<std::string>().find("unplugged"),
            std::string::npos);
}

TEST(ScanCliLive, CtrlCEndsLiveCaptureAndTheScanGoesOn) {
  TempDir dir;
  const fs::path scene = syntheticDesk(dir, "40", "3", "8");
  // The virtual sensor streams at 4 Hz, slower than fusion even under the sanitizers, so that
  // Ctrl-C (after 4 of its 40 frames) comes while it still streams.
  const fs::path out = dir / "out";
  testing::ProcessOptions interrupt;
  interrupt.signal = SIGINT;
  interrupt.signal_when = "fusing frames:  10%";
  const ProcessResult r =
      testing::runProcess({OBJSCAN_EXE, "scan", "virtual:" + scene.string() + "?fps=4", "--out",
                           out.string(), "--no-catalog"},
                          interrupt);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("capture       ended by Ctrl-C after"), std::string::npos) << r.out;
  const std::size_t fused = readTumTrajectory(out / "trajectory.txt").size();
  // What the scan said (skipped frames, lost tracking) explains a short trajectory.
  EXPECT_GE(fused, 4u) << r.out << r.err;
  EXPECT_LT(fused, 40u);
  EXPECT_TRUE(fs::is_regular_file(out / "report.html"));
  EXPECT_FALSE(readJson(out / "timings.json").at("interrupted").get<bool>());
}

TEST(ScanCliLive, NoSensorAttachedIsExitCodeThree) {
  TempDir dir;
  expectOneErrorLine(objscan({"scan", "--out", (dir / "out").string()}), 3, "no sensor found");
  // Nothing is made before the source is open.
  EXPECT_FALSE(fs::exists(dir / "out"));
  // `live` is the sensor, also where a folder of that name is in the working directory (which
  // ./live names).
  fs::create_directories(dir / "live");
  testing::ProcessOptions in_dir;
  in_dir.cwd = dir.path();
  expectOneErrorLine(testing::runProcess({OBJSCAN_EXE, "scan", "--out", "out"}, in_dir), 3,
                     "no sensor found");
  expectOneErrorLine(testing::runProcess({OBJSCAN_EXE, "scan", "live", "--out", "out"}, in_dir), 3,
                     "no sensor found");
  EXPECT_FALSE(fs::exists(dir / "out"));
  expectOneErrorLine(testing::runProcess({OBJSCAN_EXE, "scan", "./live", "--out", "out"}, in_dir),
                     2, "live: is neither a TUM RGB-D folder");
  // --record belongs to live sources only.
  expectOneErrorLine(objscan({"scan", "synth:3,frames=5", "--out", (dir / "out").string(),
                              "--record", (dir / "x.oni").string()}),
                     2, "--record needs a live source");
}

}  // namespace
}  // namespace objscan
