// The Kinect v1 through libfreenect, tested through Debian's fakenect: the real replay library
// (libfreenect-bin) serves dumps written from frames with ground truth to the objscan binary
// through libfreenect's API. objscan loads whichever libfreenect the loader finds, so the children
// run with LD_LIBRARY_PATH naming fakenect's folder, exactly as the `fakenect` wrapper runs them.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "background_process.h"
#include "cli_expect.h"
#include "http_client.h"
#include "objscan/capture/folder_source.h"
#include "objscan/capture/freenect.h"
#include "objscan/capture/openni.h"
#include "objscan/capture/synthetic/synthetic_source.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/mesh_distance.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;
using testing::expectOneErrorLine;
using testing::ProcessOptions;
using testing::ProcessResult;
using testing::TempDir;

/// Debian's fakenect folder (libfreenect-bin), found by CMake.
const fs::path kFakenectDir = OBJSCAN_FAKENECT_DIR;

/// Runs objscan on fakenect replaying `dump` (no FAKENECT_PATH when `dump` is empty).
ProcessResult onFakenect(const fs::path& dump, std::vector<std::string> args) {
  ProcessOptions options;
  options.env = {"LD_LIBRARY_PATH=" + kFakenectDir.string()};
  if (!dump.empty()) options.env.push_back("FAKENECT_PATH=" + dump.string());
  args.insert(args.begin(), OBJSCAN_EXE);
  return testing::runProcess(args, options);
}

/// The value after `key` on the stdout line starting with `key` (e.g. "frames"), or "".
std::string lineOf(const std::string& out, const std::string& key) {
  for (const std::string& l : testing::lines(out)) {
    if (l.rfind(key, 0) == 0) return l;
  }
  return {};
}

/// The number in `line` right before `word`, e.g. numberBefore("12 read, 3 dropped", "dropped").
double numberBefore(const std::string& line, const std::string& word) {
  const std::size_t at = line.find(" " + word);
  if (at == std::string::npos) return -1.0;
  std::size_t start = line.rfind(' ', at - 1);
  start = start == std::string::npos ? 0 : start + 1;
  return std::stod(line.substr(start, at - start));
}

nlohmann::json readJson(const fs::path& file) { return nlohmann::json::parse(readWholeFile(file)); }

// --- The camera model ----------------------------------------------------------------------------

TEST(KinectModel, RawDisparityRoundTripsWithinHalfAStep) {
  const KinectModel m = KinectModel::nominal();
  EXPECT_EQ(m.rawFromMetres(0.0f), 2047);
  EXPECT_EQ(m.rawFromMetres(NAN), 2047);
  EXPECT_EQ(m.rawFromMetres(0.2f), 2047);  // nearer than the Kinect measures
  EXPECT_EQ(m.metresFromRaw(2047), 0.0f);
  for (float z = 0.5f; z <= 6.0f; z += 0.01f) {
    const std::uint16_t raw = m.rawFromMetres(z);
    ASSERT_LT(raw, 1090);
    // One raw step spans dz = z^2 / (8 b f) at depth z.
    const double step = z * z / (8.0 * m.projector_baseline_m * m.ir.fx_px);
    EXPECT_LE(std::abs(m.metresFromRaw(raw) - z), 0.5 * step * 1.05 + 1e-6) << z;
  }
  // The model's depth grows monotonically with the raw value.
  for (std::uint16_t raw = 1; raw < 1089; ++raw) {
    EXPECT_GT(m.metresFromRaw(raw), m.metresFromRaw(raw - 1)) << raw;
  }
}

/// The first frame of a synthetic desk (no noise: the depth is the truth).
RgbdFrame truthFrame() {
  const std::unique_ptr<FrameSource> source = openSynthOrFolderSource("synth:3,frames=1,noise=off");
  FrameResult r = source->next();
  if (r.status != FrameStatus::kOk) throw std::runtime_error("no synthetic frame");
  return r.frame;
}

/// Statistics of `got` against `truth` over the pixels where truth has depth.
struct DepthAgreement {
  double recovered = 0.0;  ///< fraction of truth's readings that `got` has
  double median_mm = 0.0, p95_mm = 0.0;
};

DepthAgreement agreement(const cv::Mat& got, const cv::Mat& truth) {
  std::vector<double> errors;
  std::size_t valid = 0;
  for (int v = 0; v < truth.rows; ++v) {
    for (int u = 0; u < truth.cols; ++u) {
      const float t = truth.at<float>(v, u);
      if (!(t > 0.0f)) continue;
      ++valid;
      const float g = got.at<float>(v, u);
      if (g > 0.0f) errors.push_back(1e3 * std::abs(g - t));
    }
  }
  DepthAgreement a;
  if (valid == 0 || errors.empty()) return a;
  a.recovered = static_cast<double>(errors.size()) / static_cast<double>(valid);
  std::sort(errors.begin(), errors.end());
  a.median_mm = errors[errors.size() / 2];
  a.p95_mm = errors[errors.size() * 95 / 100];
  return a;
}

TEST(KinectModel, RegistrationUndoesTheMoveToTheIrCamera) {
  const RgbdFrame frame = truthFrame();
  const KinectModel m = KinectModel::nominal(frame.intrinsics);
  const cv::Mat ir = m.colorToIr(frame.depth_m);
  // The IR camera sees the scene 25 mm to the side: the images differ.
  EXPECT_GT(cv::norm(ir, frame.depth_m, cv::NORM_L1) / static_cast<double>(ir.total()), 0.01);
  const DepthAgreement a = agreement(m.registerToColor(ir), frame.depth_m);
  std::printf("registration round trip: %.4f recovered, median %.2f mm, 95%% %.2f mm\n",
              a.recovered, a.median_mm, a.p95_mm);
  // What the IR camera cannot see (the colour camera's view beside objects, its image's edge) is
  // lost, as on a Kinect.
  EXPECT_GT(a.recovered, 0.93);
  EXPECT_LT(a.median_mm, 1.0);
  EXPECT_LT(a.p95_mm, 10.0);
}

TEST(Freenect, SourceNames) {
  EXPECT_TRUE(isFreenectSource("freenect"));
  EXPECT_TRUE(isFreenectSource("freenect:1"));
  EXPECT_FALSE(isFreenectSource("freenectx"));
  EXPECT_FALSE(isFreenectSource("live"));
  EXPECT_EQ(freenectIndex("freenect"), 0);
  EXPECT_EQ(freenectIndex("freenect:3"), 3);
  for (const char* bad : {"freenect:", "freenect:-1", "freenect:x", "freenect:1x", "freenect:256",
                          "freenect: 1", "freenect:+1"}) {
    EXPECT_THROW(freenectIndex(bad), std::invalid_argument) << bad;
  }
}

// --- Through fakenect ----------------------------------------------------------------------------

/// A synthetic desk written by `objscan synth` (frames, scene_gt.ply, ground truth) and its
/// fakenect dump, made once for the tests that replay it.
class Fakenect : public ::testing::Test {
 protected:
  static constexpr int kFrames = 20;

  static void SetUpTestSuite() {
    dir_ = new TempDir;
    desk_ = *dir_ / "desk";
    const ProcessResult synth =
        testing::objscan({"synth", "--out", desk_.string(), "--seed", "3", "--frames",
                          std::to_string(kFrames), "--objects", "4"});
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  /// A dump of the desk in `name`, replayed at 30 Hz (a dump's replay waits for a slower reader).
  static fs::path dump(const std::string& name, const FakenectDumpOptions& options = {}) {
    const fs::path out = *dir_ / name;
    const std::unique_ptr<FrameSource> source = openFolderSource(desk_);
    writeFakenectDump(*source, out, options);
    return out;
  }

  static TempDir* dir_;
  static fs::path desk_;
};

TempDir* Fakenect::dir_ = nullptr;
fs::path Fakenect::desk_;

TEST_F(Fakenect, DumpIsWhatFakenectRecordWrites) {
  FakenectDumpOptions options;
  options.max_frames = 3;
  const fs::path d = dump("three", options);
  std::ifstream index(d / "INDEX.txt");
  std::string line;
  std::vector<std::string> names;
  while (std::getline(index, line)) names.push_back(line);
  ASSERT_EQ(names.size(), 6u);  // r, d per frame
  EXPECT_EQ(names[0][0], 'r');
  EXPECT_EQ(names[1][0], 'd');
  const std::string pgm = readWholeFile(d / names[1]);
  ASSERT_EQ(pgm.size(), std::string("P5 640 480 65535\n").size() + 640u * 480u * 2u);
  EXPECT_EQ(pgm.rfind("P5 640 480 65535\n", 0), 0u);
}

/// The median and 90th percentile distance of `mesh`'s vertices to `truth`, mm.
std::pair<double, double> meshAccuracyMm(const fs::path& mesh, const fs::path& truth) {
  const TriangleMesh m = readPly(mesh);
  const TriangleMesh t = readPly(truth);
  const MeshDistance to_truth(t, 0.1f);  // keeps a reference to t
  std::vector<double> d;
  for (const Eigen::Vector3f& p : m.positions)
    d.push_back(1e3 * std::min(0.1f, to_truth.closest(p).distance_m));
  std::sort(d.begin(), d.end());
  return {d[d.size() / 2], d[d.size() * 9 / 10]};
}

/// The ATE RMSE in mm from a fuse or scan's "ATE" line; -1 without one.
double ateMm(const std::string& out) {
  const std::string line = lineOf(out, "ATE");
  const std::size_t at = line.find("RMSE ");
  return at == std::string::npos ? -1.0 : std::stod(line.substr(at + 5));
}

// Done when: `objscan scan freenect` on fakenect finds the scene's objects as the same scene does
// from synth:<seed> (the folder `objscan synth --seed` wrote is synth:<seed>'s frames).
TEST_F(Fakenect, ScanFindsTheObjectsTheSameSceneGivesAsSynth) {
  const fs::path d = dump("scan");
  const fs::path truth = desk_ / "scene_gt.ply";
  const fs::path kinect = *dir_ / "scan-kinect", synth = *dir_ / "scan-synth";
  const ProcessResult k = onFakenect(d, {"scan", "freenect", "--out", kinect.string(),
                                         "--ground-truth", truth.string(), "--no-catalog"});
  ASSERT_EQ(k.exit_code, 0) << k.err;
  const ProcessResult s =
      testing::objscan({"scan", "synth:3,frames=" + std::to_string(kFrames) + ",objects=4", "--out",
                        synth.string(), "--ground-truth", truth.string(), "--no-catalog"});
  ASSERT_EQ(s.exit_code, 0) << s.err;

  EXPECT_NE(lineOf(k.out, "source").find("fakenect dump"), std::string::npos) << k.out;
  EXPECT_NE(lineOf(k.out, "intrinsics").find("the dump's intrinsics.json"), std::string::npos);
  const std::string frames = lineOf(k.out, "frames");
  EXPECT_EQ(numberBefore(frames, "read,"), kFrames) << frames;
  EXPECT_EQ(numberBefore(frames, "dropped"), 0) << frames;

  // Tracking: the 11-bit disparity's steps (2.9 mm at 1 m) cost little.
  const double ate_kinect = ateMm(k.out), ate_synth = ateMm(s.out);
  std::printf("ATE %.1f mm through fakenect, %.1f mm from synth\n", ate_kinect, ate_synth);
  ASSERT_GE(ate_kinect, 0.0) << k.out;  // the dump's groundtruth.txt was read
  EXPECT_LT(ate_kinect, 3.0);
  EXPECT_LT(ate_kinect, ate_synth + 2.0);

  // The surface: as close to the truth as synth's, within a millimetre.
  const auto [k_median, k_p90] = meshAccuracyMm(kinect / "mesh.ply", truth);
  const auto [s_median, s_p90] = meshAccuracyMm(synth / "mesh.ply", truth);
  std::printf("mesh to truth: median %.2f / %.2f mm, 90%% %.2f / %.2f mm (fakenect / synth)\n",
              k_median, s_median, k_p90, s_p90);
  EXPECT_LT(k_median, s_median + 1.0);
  EXPECT_LT(k_p90, s_p90 + 3.0);

  // The objects. synth:<seed> renders its frames afresh and the folder stores depth in steps of
  // 0.2 mm, so even the folder differs from synth by an object at IoU 0.7 (3 and 4 of 4 found,
  // AP 0.60 and 0.44 when written): against synth, at most one object fewer and AP within 0.2;
  // against the folder, the dump's very frames, the same objects found and AP within 0.1.
  const fs::path folder = *dir_ / "scan-folder";
  const ProcessResult f = testing::objscan({"scan", desk_.string(), "--out", folder.string(),
                                            "--ground-truth", truth.string(), "--no-catalog"});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  const nlohmann::json ke = readJson(kinect / "evaluation.json");
  const nlohmann::json se = readJson(synth / "evaluation.json");
  const nlohmann::json fe = readJson(folder / "evaluation.json");
  std::printf("found %d / %d / %d, AP %.3f / %.3f / %.3f (fakenect / synth / folder)\n",
              ke["found"].get<int>(), se["found"].get<int>(), fe["found"].get<int>(),
              ke["ap"].get<double>(), se["ap"].get<double>(), fe["ap"].get<double>());
  EXPECT_GE(ke["found"].get<int>(), 3);
  EXPECT_GE(ke["found"].get<int>(), se["found"].get<int>() - 1);
  EXPECT_NEAR(ke["ap"].get<double>(), se["ap"].get<double>(), 0.2);
  EXPECT_EQ(ke["found"].get<int>(), fe["found"].get<int>());
  EXPECT_NEAR(ke["ap"].get<double>(), fe["ap"].get<double>(), 0.1);
}

// `record` from a fakenect Kinect writes an .oni (through the virtual OpenNI2 sensor and
// OpenNI2's recorder) whose frames are the dump's, registered, and that fuse replays.
TEST_F(Fakenect, RecordWritesAnOniThatFuseReplaysFrameForFrame) {
  const fs::path d = dump("record");
  const fs::path oni = *dir_ / "kinect.oni";
  const ProcessResult r = onFakenect(d, {"record", "--device", "freenect", "--out", oni.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("frames        20 depth, 20 colour"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("dropped       0"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(oni.string() + ".groundtruth.txt"));

  // Frame for frame against the frames the dump was made of: colour exact, depth within the
  // disparity's quantisation where both the colour and the IR camera see the surface.
  std::unique_ptr<FrameSource> replay = openOniFile(oni);
  std::unique_ptr<FrameSource> truth = openFolderSource(desk_);
  ASSERT_EQ(replay->info().frame_count, std::optional<std::size_t>(kFrames));
  std::optional<double> first_replay, first_truth;
  for (int i = 0; i < kFrames; ++i) {
    FrameResult a = replay->next(), b = truth->next();
    ASSERT_EQ(a.status, FrameStatus::kOk) << i;
    ASSERT_EQ(b.status, FrameStatus::kOk) << i;
    EXPECT_EQ(cv::norm(a.frame.color_rgb, b.frame.color_rgb, cv::NORM_INF), 0.0) << i;
    const DepthAgreement g = agreement(a.frame.depth_m, b.frame.depth_m);
    EXPECT_GT(g.recovered, 0.9) << i;
    EXPECT_LT(g.median_mm, 3.0) << i;
    EXPECT_LT(g.p95_mm, 20.0) << i;
    if (i == 0) {
      std::printf("frame 0: %.3f recovered, median %.2f mm, 95%% %.2f mm\n", g.recovered,
                  g.median_mm, g.p95_mm);
    }
    // Time stamps keep the frames' spacing (to OpenNI2's microseconds).
    if (!first_replay) first_replay = a.frame.stamp_s, first_truth = b.frame.stamp_s;
    EXPECT_NEAR(a.frame.stamp_s - *first_replay, b.frame.stamp_s - *first_truth, 2e-6) << i;
  }
  EXPECT_EQ(replay->next().status, FrameStatus::kEndOfStream);
  replay.reset();

  const ProcessResult f =
      testing::objscan({"fuse", oni.string(), "--out", (*dir_ / "refused").string()});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  EXPECT_EQ(numberBefore(lineOf(f.out, "frames"), "fused,"), kFrames) << f.out;
  EXPECT_GE(ateMm(f.out), 0.0) << f.out;
  EXPECT_LT(ateMm(f.out), 3.0) << f.out;
}

// A dump cut short (the recorder killed while writing a frame) replays the frames before it; one
// with no whole depth frame is one error line.
TEST_F(Fakenect, ADumpCutShortReplaysTheFramesBeforeTheCut) {
  const fs::path d = dump("cut");
  std::vector<std::string> names = testing::lines(readWholeFile(d / "INDEX.txt"));
  // Frame 12's depth file is the 26th line (r and d per frame).
  ASSERT_EQ(names[25][0], 'd');
  fs::resize_file(d / names[25], 300000);
  const ProcessResult r =
      onFakenect(d, {"fuse", "freenect", "--out", (*dir_ / "cut-out").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("stops early (line 26 of INDEX.txt: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(names[25] + " is cut short: 300000 of 614417 bytes"), std::string::npos)
      << r.err;
  EXPECT_EQ(numberBefore(lineOf(r.out, "frames"), "read,"), 12) << r.out;

  fs::resize_file(d / names[1], 10);  // the first depth frame
  const fs::path none = *dir_ / "cut-none";
  expectOneErrorLine(onFakenect(d, {"fuse", "freenect", "--out", none.string()}), 2,
                     "holds no depth frame fakenect can replay");
  EXPECT_FALSE(fs::exists(none));
}

// Frames the Kinect dropped are gaps in its 60 MHz clock, and counted.
TEST_F(Fakenect, DroppedFramesAreCountedFromTheDeviceClock) {
  FakenectDumpOptions options;
  options.drop = {5, 6, 11};
  const fs::path d = dump("dropped", options);
  const ProcessResult r =
      onFakenect(d, {"fuse", "freenect", "--out", (*dir_ / "dropped-out").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string frames = lineOf(r.out, "frames");
  EXPECT_EQ(numberBefore(frames, "read,"), kFrames - 3) << frames;
  EXPECT_EQ(numberBefore(frames, "dropped"), 3) << frames;
}

/// Rewrites `dump`'s INDEX.txt: each line through `edit` (which may rename the file it names, or
/// return "" to leave the line out).
void editIndex(const fs::path& dump, const std::function<std::string(const std::string&)>& edit) {
  std::string index;
  for (const std::string& name : testing::lines(readWholeFile(dump / "INDEX.txt"))) {
    const std::string line = edit(name);
    if (!line.empty()) index += line + "\n";
  }
  writeFileAtomically(dump / "INDEX.txt", index);
}

/// The 0-based frame number of a dump file objscan's writer named (`...-000012.pgm`).
int frameOf(const std::string& name) { return std::stoi(name.substr(name.rfind('-') + 1)); }

// A Kinect that stops delivering (unplugged: here the dump's clock pauses two minutes, and
// fakenect sleeps through it) is a lost sensor: one error line, exit 1, the frames fused before
// it kept, and objscan does not wait for fakenect to wake up.
TEST_F(Fakenect, AKinectThatStopsIsALostSensorAndWhatWasFusedIsKept) {
  const fs::path d = dump("stall");
  editIndex(d, [&](const std::string& name) {
    if (frameOf(name) < 2) return name;
    char type = 0;
    double time_s = 0.0;
    unsigned ticks = 0;
    int rest = 0;
    EXPECT_EQ(std::sscanf(name.c_str(), "%c-%lf-%u-%n", &type, &time_s, &ticks, &rest), 3);
    char renamed[128];
    std::snprintf(renamed, sizeof(renamed), "%c-%.6f-%u-%s", type, time_s + 120.0, ticks,
                  name.c_str() + rest);
    fs::rename(d / name, d / renamed);
    return std::string(renamed);
  });
  const fs::path out = *dir_ / "stall-out";
  const auto start = std::chrono::steady_clock::now();
  const ProcessResult r = onFakenect(d, {"fuse", "freenect", "--out", out.string()});
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(took_s, 60.0);  // 3 s without a frame, then the outputs; not the dump's 120 s
  EXPECT_EQ(r.exit_code, 1) << r.err;
  std::size_t errors = 0;
  for (const std::string& l : testing::lines(r.err)) errors += l.rfind("objscan: error: ", 0) == 0;
  EXPECT_EQ(errors, 1u) << r.err;
  EXPECT_NE(r.err.find("gave no frame for 3 s after 2 frames"), std::string::npos) << r.err;
  EXPECT_EQ(readTumTrajectory(out / "trajectory.txt").size(), 2u);
  EXPECT_GT(readPly(out / "mesh.ply").triangles.size(), 1000u);
}

// Depth frames whose colour frame is missing are fused without colour, not lost; a FIFO or a
// tilt record of another libfreenect's size, which fakenect would block on or complain about on
// stdout, ends the replay there.
TEST_F(Fakenect, MissingColourAndHostileEntries) {
  const fs::path d = dump("hostile");
  editIndex(d, [](const std::string& name) {
    return name[0] == 'r' && frameOf(name) % 3 == 1 ? std::string() : name;
  });
  const ProcessResult r = onFakenect(d, {"fuse", "freenect", "--out", (*dir_ / "h1").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(numberBefore(lineOf(r.out, "frames"), "read,"), kFrames) << r.out;
  EXPECT_NE(r.err.find("7 depth frames came without a colour frame"), std::string::npos) << r.err;

  std::string fifo;
  editIndex(d, [&](const std::string& name) {
    if (name[0] == 'd' && frameOf(name) == 5) {
      fifo = name;
      fs::remove(d / name);
      EXPECT_EQ(mkfifo((d / name).c_str(), 0600), 0);
    }
    return name;
  });
  const ProcessResult f = onFakenect(d, {"fuse", "freenect", "--out", (*dir_ / "h2").string()});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  EXPECT_NE(f.err.find(fifo + " is missing or not a regular file"), std::string::npos) << f.err;
  EXPECT_EQ(numberBefore(lineOf(f.out, "frames"), "read,"), 5) << f.out;

  editIndex(d, [&](const std::string& name) {
    if (name != fifo) return name;
    writeFileAtomically(d / "a-1000.100000-0-x.dump", std::string(7, '\0'));
    return std::string("a-1000.100000-0-x.dump");
  });
  const ProcessResult a = onFakenect(d, {"fuse", "freenect", "--out", (*dir_ / "h3").string()});
  ASSERT_EQ(a.exit_code, 0) << a.err;
  EXPECT_NE(a.err.find("holds a tilt state of 7 bytes"), std::string::npos) << a.err;
  EXPECT_EQ(a.out.find("Warning"), std::string::npos) << a.out;  // fakenect said nothing
}

TEST_F(Fakenect, DevicesListsTheDumpAndDiscoverTakesAFrame) {
  const fs::path d = dump("devices");
  const ProcessResult r = onFakenect(d, {"devices"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("freenect:0\tMicrosoft Kinect v1, dump " + d.string(), 0), 0u) << r.out;
  EXPECT_NE(r.out.find("through libfreenect's fakenect"), std::string::npos) << r.out;

  const fs::path out = *dir_ / "frame";
  const ProcessResult f = onFakenect(
      d, {"discover", "freenect", "--frame", "3", "--out", out.string(), "--no-catalog"});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  EXPECT_FALSE(readJson(out / "hypotheses.json")["hypotheses"].empty());
}

TEST_F(Fakenect, BadSetupsAreOneErrorLine) {
  const fs::path out = *dir_ / "never";
  expectOneErrorLine(onFakenect({}, {"fuse", "freenect", "--out", out.string()}), 2,
                     "FAKENECT_PATH");
  expectOneErrorLine(onFakenect(*dir_ / "nowhere", {"fuse", "freenect", "--out", out.string()}), 2,
                     "INDEX.txt: is missing or not a regular file: not a fakenect dump");
  const fs::path d = dump("setup", FakenectDumpOptions{1.0, {}, 2});
  expectOneErrorLine(onFakenect(d, {"fuse", "freenect:1", "--out", out.string()}), 2,
                     "fakenect replays one device, freenect:0");
  expectOneErrorLine(onFakenect(d, {"fuse", "freenect:one", "--out", out.string()}), 2,
                     "must be 0 to 255");
  expectOneErrorLine(onFakenect(d, {"fuse", "freenect", "--start", "1", "--out", out.string()}), 2,
                     "not live sensors");
  // fakenect's place in the dump is global to the process: a second replay is refused.
  const ProcessResult twice = onFakenect(d, {"discover", "freenect", "freenect", "--frame", "1",
                                             "--out", out.string(), "--no-catalog"});
  EXPECT_EQ(twice.exit_code, 2) << twice.err;
  EXPECT_NE(twice.err.find("fakenect replays one dump once per process"), std::string::npos)
      << twice.err;
  EXPECT_FALSE(fs::exists(out));
}

// --serve: the live page follows a Kinect scan.
TEST_F(Fakenect, TheLivePageServesAKinectFuse) {
  const fs::path d = dump("serve");
  // BackgroundProcess passes this process's environment on.
  const char* saved = std::getenv("LD_LIBRARY_PATH");
  const std::optional<std::string> library_path =
      saved == nullptr ? std::nullopt : std::optional<std::string>(saved);
  ASSERT_EQ(setenv("LD_LIBRARY_PATH", kFakenectDir.c_str(), 1), 0);
  ASSERT_EQ(setenv("FAKENECT_PATH", d.c_str(), 1), 0);
  testing::BackgroundProcess fuse({OBJSCAN_EXE, "fuse", "freenect", "--out",
                                   (*dir_ / "served").string(), "--serve", "127.0.0.1:0",
                                   "--no-live-discovery"});
  if (library_path) {
    setenv("LD_LIBRARY_PATH", library_path->c_str(), 1);
  } else {
    unsetenv("LD_LIBRARY_PATH");
  }
  unsetenv("FAKENECT_PATH");
  const int port = testing::portOf(fuse.waitForLine("live page", 60));
  ASSERT_GT(port, 0) << fuse.err();
  ASSERT_FALSE(
      fuse.waitForLine("live page     http://127.0.0.1:" + std::to_string(port) + "/ shows", 120)
          .empty())
      << fuse.err();
  const testing::Answer state = testing::get(port, "/api/state?after=0");
  ASSERT_EQ(state.status, 200);
  const nlohmann::json j = nlohmann::json::parse(state.body);
  EXPECT_EQ(j["frames"]["fused"], kFrames) << state.body;
  EXPECT_EQ(j["final"]["outcome"], "finished") << state.body;
  fuse.signal(SIGTERM);
  EXPECT_EQ(fuse.wait(60), 0) << fuse.err();
}

// The real libfreenect on a machine with no Kinect: exit 3, as for OpenNI2 sensors.
TEST(Freenect, NoKinectAttachedIsExit3) {
  TempDir dir;
  expectOneErrorLine(testing::objscan({"fuse", "freenect", "--out", (dir / "x").string()}), 3,
                     "no Kinect found");
  EXPECT_FALSE(fs::exists(dir / "x"));
  // Recording goes through the virtual OpenNI2 sensor; the error and its exit code are the same.
  expectOneErrorLine(
      testing::objscan({"record", "--device", "freenect", "--out", (dir / "k.oni").string()}), 3,
      "no Kinect found");
  EXPECT_EQ(testing::entryCount(dir.path()), 0u);
}

// The TUM sample's real Kinect frames, turned back into the Kinect's raw 11-bit disparity seen
// from its IR camera, fuse through fakenect as they do from the folder.
TEST_F(Fakenect, TumFramesAsRawDisparityFuseLikeTheFolder) {
  const fs::path tum = fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk_10";
  const fs::path d = *dir_ / "tum";
  {
    const std::unique_ptr<FrameSource> source = openFolderSource(tum);
    writeFakenectDump(*source, d);
  }
  const ProcessResult k = onFakenect(d, {"fuse", "freenect", "--out", (*dir_ / "tum-k").string()});
  ASSERT_EQ(k.exit_code, 0) << k.err;
  const ProcessResult f =
      testing::objscan({"fuse", tum.string(), "--out", (*dir_ / "tum-f").string()});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  std::printf("TUM: ATE %.1f mm through fakenect, %.1f mm from the folder\n", ateMm(k.out),
              ateMm(f.out));
  EXPECT_NE(lineOf(k.out, "intrinsics").find("fx 520.90"), std::string::npos) << k.out;
  EXPECT_EQ(numberBefore(lineOf(k.out, "frames"), "fused,"), 10) << k.out;
  ASSERT_GE(ateMm(k.out), 0.0) << k.out;
  EXPECT_LT(ateMm(k.out), ateMm(f.out) + 10.0);
}

}  // namespace
}  // namespace objscan::capture
