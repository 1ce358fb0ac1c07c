// `objscan fuse` end to end: a synthetic recording in, a mesh and a trajectory out; bad input
// gives one error line and the documented exit code.

#include <gtest/gtest.h>

#include <csignal>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli_expect.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::expectOneErrorLine;
using testing::ProcessResult;
using testing::TempDir;

using testing::objscan;
using testing::readBytes;

/// A 320x240, 12-frame synthetic desk recording (TUM layout) under `dir`.
fs::path syntheticRecording(const TempDir& dir) {
  Intrinsics in;
  in.width_px = 320;
  in.height_px = 240;
  in.fx_px = in.fy_px = 285.15;
  in.cx_px = 159.5;
  in.cy_px = 119.5;
  writeIntrinsicsJson(dir / "small.json", in);
  const fs::path scene = dir / "scene";
  const ProcessResult r =
      objscan({"synth", "--out", scene.string(), "--frames", "12", "--objects", "3", "--seed", "2",
               "--intrinsics", (dir / "small.json").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return scene;
}

TEST(FuseCli, WritesAMeshAndATrajectoryThatReadBack) {
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  const fs::path out = dir / "out";
  const ProcessResult r = objscan({"fuse", scene.string(), "--out", out.string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("12 read, 12 fused, 0 lost"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ATE"), std::string::npos) << r.out;
  const TriangleMesh mesh = readPly(out / "mesh.ply");
  EXPECT_GT(mesh.triangles.size(), 1000u);
  EXPECT_TRUE(mesh.hasNormals());
  EXPECT_TRUE(mesh.hasColors());
  EXPECT_EQ(readTumTrajectory(out / "trajectory.txt").size(), 12u);
  // No temporary files are left beside the outputs (and the settings they were made with).
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(out)) files.insert(e.path().filename().string());
  EXPECT_EQ(files, (std::set<std::string>{"mesh.ply", "trajectory.txt", "settings.json"}));
}

// settings.json says whether the volume carved, and --config fuses again as it was fused:
// carved (the default), averaged (--no-carve), and from a file written when averaging was the
// default, which names "carve" (not given) and no "no-carve".
TEST(FuseCli, ASettingsFileFusesAgainWithOrWithoutCarvingAsItWasMade) {
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  const auto fuse = [&](const std::string& name, std::vector<std::string> args) {
    const fs::path out = dir / name;
    args.insert(args.begin(), "fuse");
    args.insert(args.end(), {"--out", out.string()});
    const ProcessResult r = objscan(args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return readPly(out / "mesh.ply").positions;
  };
  const auto carved = fuse("carved", {scene.string()});
  const auto averaged = fuse("averaged", {scene.string(), "--no-carve"});
  // On 12 frames round three objects some voxels that views saw as free are solid in the
  // average: the meshes differ.
  EXPECT_NE(carved, averaged);
  const auto settings = [&](const std::string& name) {
    return nlohmann::json::parse(readBytes(dir / name / "settings.json"));
  };
  EXPECT_EQ(settings("carved")["resolved"]["carve"], "true");
  EXPECT_EQ(settings("averaged")["resolved"]["carve"], "false");
  EXPECT_EQ(fuse("carved_again", {"--config", (dir / "carved" / "settings.json").string()}),
            carved);
  EXPECT_EQ(fuse("averaged_again", {"--config", (dir / "averaged" / "settings.json").string()}),
            averaged);
  nlohmann::json old = settings("averaged");
  old["options"].erase("no-carve");
  writeFileAtomically(dir / "old.json", old.dump());
  EXPECT_EQ(fuse("old_again", {"--config", (dir / "old.json").string()}), averaged);
  // The command line wins over the file.
  EXPECT_EQ(fuse("old_carved", {"--config", (dir / "old.json").string(), "--carve"}), carved);
}

TEST(FuseCli, SaysWhichIntrinsicsAndDepthUnitsItUsesAndWarnsWhenTheyAreAssumed) {
  // Issue 18, defect 9: a TUM folder without intrinsics.json was fused with the Xtion defaults
  // (fx 570.3 against fr2's 520.9: the mesh 10 % small) and only `info` said so.
  TempDir dir;
  const fs::path shipped = fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk_10";
  const ProcessResult own =
      objscan({"fuse", shipped.string(), "--out", (dir / "own").string(), "--end", "2"});
  ASSERT_EQ(own.exit_code, 0) << own.err;
  EXPECT_NE(own.out.find("intrinsics    fx 520.90 fy 521.00 cx 325.10 cy 249.70, 640x480 (" +
                         (shipped / "intrinsics.json").string() +
                         "); depth: 16-bit value / 5000 = metres"),
            std::string::npos)
      << own.out;
  EXPECT_EQ(own.err.find("ASSUMED"), std::string::npos) << own.err;

  fs::copy(shipped, dir / "bare", fs::copy_options::recursive);
  fs::remove(dir / "bare" / "intrinsics.json");
  const ProcessResult bare =
      objscan({"fuse", (dir / "bare").string(), "--out", (dir / "out").string(), "--end", "2"});
  ASSERT_EQ(bare.exit_code, 0) << bare.err;
  EXPECT_NE(bare.out.find("fx 570.30 fy 570.30 cx 319.50 cy 239.50, 640x480 (ASSUMED: Xtion "
                          "defaults (the folder has no intrinsics.json)"),
            std::string::npos)
      << bare.out;
  EXPECT_NE(bare.err.find("warning: the camera intrinsics are ASSUMED"), std::string::npos)
      << bare.err;
}

TEST(FuseCli, AVolumeOutgrowingMemoryStopsFusionAndKeepsWhatItHas) {
  // Issue 18, defect 4: fuse --voxel-size 0.001 took 5.8 GB, and discover on its mesh ended in
  // std::bad_alloc. OBJSCAN_MEMORY_LIMIT stands in for a small machine. The 10 shipped TUM
  // frames at 3 mm grow the volume (and the estimated peak of meshing it) frame by frame, past
  // 350 MB before the end (all 10 fit in 400 MB; with 4-byte voxels since 2026-11-25, the 84 MB
  // volume of 10 frames is estimated at 360 MB): fusion stops in the middle.
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  const fs::path tum = fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk_10";
  const fs::path out = dir / "out";
  testing::ProcessOptions small;
  small.env = {"OBJSCAN_MEMORY_LIMIT=350M"};
  const ProcessResult r = testing::runProcess(
      {OBJSCAN_EXE, "fuse", tum.string(), "--out", out.string(), "--voxel-size", "0.003"}, small);
  EXPECT_EQ(r.exit_code, 1) << r.err;  // the summary of what was written is on stdout
  EXPECT_NE(r.err.find("objscan: error: fusion stopped at frame "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("more than the 350 MB OBJSCAN_MEMORY_LIMIT allows; a larger --voxel-size "
                       "needs less"),
            std::string::npos)
      << r.err;
  const std::size_t fused = readTumTrajectory(out / "trajectory.txt").size();
  EXPECT_GT(fused, 1u);
  EXPECT_LT(fused, 10u);
  EXPECT_GT(readPly(out / "mesh.ply").triangles.size(), 0u);

  // Discovery of that mesh is refused before any work, with the figure.
  testing::ProcessOptions tiny;
  tiny.env = {"OBJSCAN_MEMORY_LIMIT=1M"};
  expectOneErrorLine(testing::runProcess({OBJSCAN_EXE, "discover", (out / "mesh.ply").string(),
                                          "--out", (dir / "found").string(), "--no-catalog"},
                                         tiny),
                     1, "more than the 1.0 MB OBJSCAN_MEMORY_LIMIT allows: fuse with a larger "
                        "--voxel-size");
  EXPECT_FALSE(fs::exists(dir / "found")) << "refused before the output folder is made";
  for (const char* bad : {"lots", "1e30", "0.5", "18446744073709551615"}) {
    tiny.env = {std::string("OBJSCAN_MEMORY_LIMIT=") + bad};
    expectOneErrorLine(testing::runProcess({OBJSCAN_EXE, "fuse", scene.string(), "--out",
                                            (dir / "never").string()},
                                           tiny),
                       2, std::string("OBJSCAN_MEMORY_LIMIT='") + bad + "' is not a size in bytes");
  }
  EXPECT_FALSE(fs::exists(dir / "never"));
}

TEST(FuseCli, AFileSizeLimitIsOneErrorLineAndLeavesNoTemporaryFile) {
  // Issue 18, defect 7: under `ulimit -f` SIGXFSZ killed fuse (exit 153, no message) and left
  // mesh.ply.tmp-PID-N behind. prlimit sets the limit as a shell's ulimit does, for the child
  // alone, with SIGXFSZ at its default.
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  const fs::path out = dir / "out";
  const ProcessResult r = testing::runProcess(
      {"/usr/bin/prlimit", "--fsize=20000", OBJSCAN_EXE, "fuse", scene.string(), "--out",
       out.string()},
      {});
  expectOneErrorLine(r, 1, (out / "mesh.ply").string() + ": write failed: File too large");
  EXPECT_EQ(testing::entryCount(out), 0u) << "no temporary file, no half mesh";
}

// Recordings and synthetic scenes are decoded on a read-ahead thread: the off-screen renderer of
// a synth: source and OpenNI2's file player must work there too.
TEST(FuseCli, ReadsASyntheticSceneAndAnOniRecordingAhead) {
  TempDir dir;
  const ProcessResult synth = objscan(
      {"fuse", "synth:5,frames=6,objects=2", "--out", (dir / "synth").string(), "--no-color"});
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  EXPECT_NE(synth.out.find("6 read, 6 fused, 0 lost"), std::string::npos) << synth.out;
  EXPECT_EQ(readTumTrajectory(dir / "synth" / "trajectory.txt").size(), 6u);
  const fs::path oni = fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk.oni";
  const ProcessResult replay =
      objscan({"fuse", oni.string(), "--out", (dir / "oni").string(), "--end", "8"});
  ASSERT_EQ(replay.exit_code, 0) << replay.err;
  EXPECT_NE(replay.out.find("8 read, 8 fused, 0 lost"), std::string::npos) << replay.out;
  EXPECT_GT(readPly(dir / "oni" / "mesh.ply").triangles.size(), 10000u);
}

TEST(FuseCli, CtrlCWritesWhatWasFusedSoFar) {
  TempDir dir;
  const fs::path out = dir / "out";
  testing::ProcessOptions interrupt;
  interrupt.signal = SIGINT;
  interrupt.signal_when = "fusing frames:  10%";  // the progress line after 20 of 200 frames
  const ProcessResult r = testing::runProcess(
      {OBJSCAN_EXE, "fuse", "synth:4,frames=200,objects=2", "--out", out.string(), "--no-color"},
      interrupt);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("stopped by    Ctrl-C"), std::string::npos) << r.out;
  const std::size_t fused = readTumTrajectory(out / "trajectory.txt").size();
  EXPECT_GE(fused, 20u);
  EXPECT_LT(fused, 200u);
  EXPECT_NE(r.out.find(std::to_string(fused) + " fused"), std::string::npos) << r.out;
  EXPECT_GT(readPly(out / "mesh.ply").triangles.size(), 1000u);
}

TEST(FuseCli, GivenPosesAndFrameSelection) {
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  const ProcessResult r = objscan({"fuse", scene.string(), "--out", (dir / "out").string(),
                                   "--poses", "groundtruth", "--every", "3", "--no-color"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("4 read, 4 fused"), std::string::npos) << r.out;
  EXPECT_FALSE(readPly(dir / "out" / "mesh.ply").hasColors());
}

TEST(FuseCli, ASourceWithoutUsableDepthIsOneErrorLine) {
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  for (const auto& e : fs::directory_iterator(scene / "depth")) {
    cv::imwrite(e.path().string(), cv::Mat(240, 320, CV_16UC1, cv::Scalar(0)));
  }
  expectOneErrorLine(objscan({"fuse", scene.string(), "--out", (dir / "out").string()}), 2,
                     "nothing to fuse");
  EXPECT_FALSE(fs::exists(dir / "out" / "mesh.ply"));
}

TEST(FuseCli, BadSettingsAndSourcesAreOneErrorLine) {
  TempDir dir;
  const fs::path scene = syntheticRecording(dir);
  const std::string out = (dir / "out").string();
  expectOneErrorLine(objscan({"fuse", scene.string(), "--out", out, "--voxel-size", "0"}), 2,
                     "voxel size");
  expectOneErrorLine(objscan({"fuse", scene.string(), "--out", out, "--truncation", "0.001"}), 2,
                     "truncation");
  expectOneErrorLine(objscan({"fuse", scene.string(), "--out", out, "--behind", "0.001"}), 2,
                     "band behind a reading");
  expectOneErrorLine(
      objscan({"fuse", scene.string(), "--out", out, "--behind", "0.01", "--behind-noise"}), 2,
      "--behind-noise");
  expectOneErrorLine(objscan({"fuse", scene.string(), "--out", out, "--carve", "--no-carve"}), 2,
                     "--carve");
  expectOneErrorLine(objscan({"fuse", (dir / "missing").string(), "--out", out}), 2, "missing");
  expectOneErrorLine(
      objscan({"fuse", scene.string(), "--out", out, "--poses", (dir / "none.txt").string()}), 2,
      "none.txt");
  // Intrinsics for another image size.
  writeIntrinsicsJson(dir / "vga.json", Intrinsics::xtionDefault());
  expectOneErrorLine(
      objscan({"fuse", scene.string(), "--out", out, "--intrinsics", (dir / "vga.json").string()}),
      2, "640x480");
  // An output folder that cannot be made: a file is in the way.
  testing::writeBytes(dir / "file", "x");
  expectOneErrorLine(objscan({"fuse", scene.string(), "--out", (dir / "file").string()}), 1,
                     "output folder");
}

}  // namespace
}  // namespace objscan
