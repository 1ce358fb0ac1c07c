// Faults on objscan's outputs (the fault audit): `fuse`, `discover`, `scan` and `record` killed
// with SIGKILL at random moments, run under a tiny file-size limit and on a full disk, and run
// twice at once on one results folder or one catalog. After each, every output file present must be
// complete and valid (read by objscan's own readers, the catalog through SQLite's integrity check,
// the recording replayed), nothing half-written may be under a final name, the files of a results
// folder must belong together, and a rerun must succeed.
//
// OBJSCAN_FAULT_KILLS sets the number of kills per command (default 25: in CI the test took 149 s
// of test time at 50; the fault audit in docs/fuzzing.md was made at 50).

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "background_process.h"
#include "cli_expect.h"
#include "objscan/capture/oni_container.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/ply_io.h"
#include "objscan/core/trajectory.h"
#include "objscan/report/results_io.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using testing::BackgroundProcess;
using testing::objscan;
using testing::ProcessResult;
using testing::TempDir;

int killsPerCommand() {
  const char* n = std::getenv("OBJSCAN_FAULT_KILLS");
  return n != nullptr && std::atoi(n) > 0 ? std::atoi(n) : 25;
}

/// A name objscan gives a file or folder while it writes it: never a final name.
bool temporaryName(const std::string& name) {
  return name.find(".tmp-") != std::string::npos || name.find(".partial") != std::string::npos ||
         (name.size() > 4 && name.compare(name.size() - 4, 4, ".old") == 0);
}

void expectCatalogIntact(const fs::path& file) {
  sqlite3* db = nullptr;
  // Read-write, as objscan opens it: a journal a killed run left is rolled back first.
  ASSERT_EQ(sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK) << file;
  sqlite3_stmt* statement = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &statement, nullptr), SQLITE_OK)
      << sqlite3_errmsg(db);
  ASSERT_EQ(sqlite3_step(statement), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(statement, 0)), "ok") << file;
  sqlite3_finalize(statement);
  sqlite3_close(db);
}

int catalogScenes(const fs::path& file) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  sqlite3_stmt* statement = nullptr;
  int n = -1;
  if (sqlite3_prepare_v2(db, "SELECT COUNT(*) FROM scenes", -1, &statement, nullptr) == SQLITE_OK &&
      sqlite3_step(statement) == SQLITE_ROW) {
    n = sqlite3_column_int(statement, 0);
  }
  sqlite3_finalize(statement);
  sqlite3_close(db);
  return n;
}

/// Every file under `dir` with a final name is complete and valid, and a results folder's files
/// belong together (report::readResults checks hypotheses.json against the mesh it names and
/// reads every other results file). Returns how many files it checked.
std::size_t expectValidOutputs(const fs::path& dir) {
  std::size_t checked = 0;
  bool results_folder = false;
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator();
       ++it) {
    const fs::path& path = it->path();
    const std::string name = path.filename().string();
    if (temporaryName(name)) {
      if (it->is_directory()) it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file()) continue;
    const std::string ext = path.extension().string();
    SCOPED_TRACE(path.string());
    try {
      if (ext == ".ply") {
        const TriangleMesh mesh = readPly(path);
        mesh.validate();
      } else if (name == "trajectory.txt" || name.ends_with(".groundtruth.txt")) {
        (void)readTumTrajectory(path);
      } else if (name == "hypotheses.json") {
        results_folder = true;
      } else if (name == "timings.json") {
        (void)report::readTimings(path);
      } else if (name == "settings.json") {
        (void)report::readSettings(path);
      } else if (name == "overview_camera.json") {
        (void)report::readOverviewCamera(path);
      } else if (ext == ".json") {
        EXPECT_FALSE(nlohmann::json::parse(readWholeFile(path)).is_discarded());
      } else if (ext == ".png") {
        EXPECT_FALSE(cv::imread(path.string(), cv::IMREAD_UNCHANGED).empty());
      } else if (ext == ".html") {
        const std::string html = readWholeFile(path);
        EXPECT_NE(html.rfind("</html>"), std::string::npos);
      } else if (ext == ".oni") {
        const capture::OniFileSummary summary = capture::inspectOniFile(path);
        EXPECT_FALSE(summary.streams.empty());
        // and OpenNI2's own player opens it (objscan info replays it).
        const ProcessResult info = objscan({"info", path.string()});
        EXPECT_EQ(info.exit_code, 0) << info.err;
      } else if (ext == ".sqlite") {
        expectCatalogIntact(path);
      } else {
        ADD_FAILURE() << "an output objscan does not name: " << name;
      }
    } catch (const std::exception& e) {
      ADD_FAILURE() << "not a valid output: " << e.what();
    }
    ++checked;
  }
  if (results_folder) {
    try {
      report::ResultsParts parts;
      parts.mesh = true;
      (void)report::readResults(dir, parts);
    } catch (const std::exception& e) {
      ADD_FAILURE() << dir << ": the results folder's files do not belong together: " << e.what();
    }
  }
  return checked;
}

/// One command of the test, run into `out` (a results folder or a recording's folder).
struct Command {
  std::string name;
  std::vector<std::string> args;  ///< after the objscan executable; OUT stands for the output
  fs::path output;                ///< what OUT becomes
};

std::vector<std::string> argvOf(const Command& c) {
  std::vector<std::string> argv = {OBJSCAN_EXE};
  for (const std::string& a : c.args) argv.push_back(a == "OUT" ? c.output.string() : a);
  return argv;
}

/// The inputs, made once: a small synthetic desk recording (TUM layout) and its fused mesh.
class Faults : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir;
    scene_ = *dir_ / "desk";
    const ProcessResult synth = objscan(
        {"synth", "--out", scene_.string(), "--frames", "12", "--objects", "4", "--seed", "21"});
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    const ProcessResult fuse =
        objscan({"fuse", scene_.string(), "--out", (*dir_ / "fused").string()});
    ASSERT_EQ(fuse.exit_code, 0) << fuse.err;
    mesh_ = *dir_ / "fused" / "mesh.ply";
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  /// The four commands, writing under `root`.
  static std::vector<Command> commands(const fs::path& root) {
    const std::string catalog = (root / "catalog.sqlite").string();
    return {
        {"fuse", {"fuse", scene_.string(), "--out", "OUT"}, root / "fuse"},
        {"discover",
         {"discover", (root / "scene.ply").string(), "--catalog", catalog, "--out", "OUT"},
         root / "discover"},
        {"scan", {"scan", scene_.string(), "--catalog", catalog, "--out", "OUT"}, root / "scan"},
        {"record",
         {"record", "--device", "virtual:" + scene_.string() + "?fps=30", "--out", "OUT"},
         root / "rec" / "desk.oni"},
    };
  }

  /// discover's scene for run `i`: the fused mesh moved by i mm, so that every run adds a new
  /// scene to the catalog (a scene already there is not written again).
  static void writeScene(const fs::path& root, int i) {
    static const TriangleMesh fused = readPly(mesh_);  // read once, moved for every run
    TriangleMesh mesh = fused;
    for (auto& p : mesh.positions) p.x() += 0.001f * static_cast<float>(i);
    writePly(root / "scene.ply", mesh);
  }

  /// The folder to check after a run of `c`.
  static fs::path checkedFolder(const Command& c) {
    return c.name == "record" ? c.output.parent_path() : c.output;
  }

  static TempDir* dir_;
  static fs::path scene_, mesh_;
};

TempDir* Faults::dir_ = nullptr;
fs::path Faults::scene_, Faults::mesh_;

TEST_F(Faults, KilledAtRandomMomentsLeavesOnlyValidOutputsAndARerunSucceeds) {
  TempDir root;
  fs::create_directories(root / "rec");
  writeScene(root.path(), 0);
  const int kills = killsPerCommand();
  std::mt19937 random(20261126);
  for (const Command& c : commands(root.path())) {
    SCOPED_TRACE(c.name);
    // How long an undisturbed run takes (the shorter of two: the second finds the files cached):
    // the kills fall anywhere in its first 90 %.
    double seconds = 1e9;
    for (int run = 0; run < 2; ++run) {
      const auto start = Clock::now();
      const ProcessResult undisturbed = testing::runProcess(argvOf(c));
      seconds = std::min(seconds, std::chrono::duration<double>(Clock::now() - start).count());
      ASSERT_EQ(undisturbed.exit_code, 0) << undisturbed.err;
      expectValidOutputs(checkedFolder(c));
    }
    // A run that ends before its kill was quicker than the two above (they may have shared the
    // cores with another test): the kills then fall within its time.
    int killed = 0;
    for (int i = 0; i < kills; ++i) {
      if (c.name == "discover") writeScene(root.path(), i + 1);
      std::uniform_real_distribution<double> moment(0.0, 0.9 * seconds);
      const auto start = Clock::now();
      BackgroundProcess run(argvOf(c));
      std::this_thread::sleep_for(std::chrono::duration<double>(moment(random)));
      run.signal(SIGKILL);
      const int status = run.wait(60.0);
      killed += status == 128 + SIGKILL;
      if (status == 0) {
        seconds = std::min(seconds, std::chrono::duration<double>(Clock::now() - start).count());
      }
      ASSERT_TRUE(status == 0 || status == 128 + SIGKILL) << status << ": " << run.err();
      ASSERT_GT(expectValidOutputs(checkedFolder(c)), 0u) << "kill " << i;
      if (fs::exists(root / "catalog.sqlite")) expectCatalogIntact(root / "catalog.sqlite");
      if (HasFailure()) return;
    }
    // Most runs really were killed mid-way (the rest had finished).
    EXPECT_GE(killed, kills * 3 / 4) << "of " << kills << " runs of " << seconds << " s";
    const ProcessResult rerun = testing::runProcess(argvOf(c));
    EXPECT_EQ(rerun.exit_code, 0) << rerun.err;
    expectValidOutputs(checkedFolder(c));
    if (c.name != "record") {  // a results folder: the rerun cleared what the killed runs left
      std::vector<std::string> left;
      for (const auto& e : fs::recursive_directory_iterator(checkedFolder(c))) {
        if (temporaryName(e.path().filename().string())) left.push_back(e.path().string());
      }
      EXPECT_TRUE(left.empty()) << left.size() << " left, e.g. " << left.front();
    }
    std::cout << c.name << ": " << killed << " of " << kills << " runs killed within a " << seconds
              << " s run; outputs valid after each\n";
  }
}

/// A run that ran out of room: exit 1 with one error line, or (record, which stops while the
/// closing records still fit) a shorter recording and exit 0.
void expectFailedCleanly(const Command& c, const ProcessResult& r) {
  std::size_t error_lines = 0;
  for (const std::string& l : testing::lines(r.err))
    error_lines += l.rfind("objscan: error:", 0) == 0;
  if (c.name == "record" && r.exit_code == 0) {
    EXPECT_EQ(error_lines, 0u) << r.err;
    return;
  }
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(error_lines, 1u) << r.err;
  for (const std::string& l : testing::lines(r.err)) {
    if (l.rfind("objscan: error:", 0) == 0) std::cout << c.name << ": " << l << "\n";
  }
}

TEST_F(Faults, ATinyFileSizeLimitIsOneErrorLineAndLeavesNoHalfFile) {
  TempDir root;
  fs::create_directories(root / "rec");
  writeScene(root.path(), 0);
  for (const Command& c : commands(root.path())) {
    SCOPED_TRACE(c.name);
    ProcessResult r;
    {
      // 20 kB: every command's mesh, pictures or recording is larger.
      testing::FileSizeLimit limit(20000);
      r = testing::runProcess(argvOf(c));
    }
    expectFailedCleanly(c, r);
    expectValidOutputs(checkedFolder(c));
    const ProcessResult rerun = testing::runProcess(argvOf(c));
    EXPECT_EQ(rerun.exit_code, 0) << rerun.err;
    expectValidOutputs(checkedFolder(c));
  }
}

TEST_F(Faults, AFullDiskIsOneErrorLineAndLeavesNoHalfFile) {
  // A 300 kB tmpfs mounted in a private mount namespace (unshare -rm: no root needed), written
  // to by the real command, then copied out to be checked. The paths reach the shell as its
  // arguments, never inside the script's text.
  TempDir root;
  const fs::path mount = root / "disk", copy = root / "copy";
  fs::create_directories(mount);
  const ProcessResult probe =
      testing::runProcess({"/usr/bin/unshare", "-rm", "/bin/sh", "-c",
                           "mount -t tmpfs -o size=300k tmpfs \"$0\"", mount.string()});
  ASSERT_EQ(probe.exit_code, 0)
      << "this test mounts a tmpfs in a user and mount namespace (unshare -rm, util-linux), which "
         "this machine does not allow: "
      << probe.err;
  for (Command c : commands(mount)) {
    SCOPED_TRACE(c.name);
    fs::remove_all(copy);
    fs::create_directories(copy);
    // discover's scene is read from outside the small disk
    for (std::string& a : c.args) {
      if (a == (mount / "scene.ply").string()) a = mesh_.string();
    }
    // sh -c SCRIPT MOUNT COPY objscan ARGS...: $0 is the mount point, $1 the copy, "$@" the run.
    const std::string script =
        "mount -t tmpfs -o size=300k tmpfs \"$0\" || exit 99; mkdir -p \"$0/rec\"; copy=$1; "
        "shift; \"$@\"; rc=$?; cp -a \"$0/.\" \"$copy/\"; exit $rc";
    std::vector<std::string> argv = {"/usr/bin/unshare", "-rm",        "/bin/sh", "-c", script,
                                     mount.string(),     copy.string()};
    for (const std::string& a : argvOf(c)) argv.push_back(a);
    const ProcessResult r = testing::runProcess(argv);
    ASSERT_NE(r.exit_code, 99) << "cannot mount a tmpfs for the test: " << r.err;
    expectFailedCleanly(c, r);
    const fs::path written = copy / fs::relative(checkedFolder(c), mount);
    if (fs::exists(written)) expectValidOutputs(written);
  }
}

TEST_F(Faults, TwoRunsOnOneFolderOneWinsAndTwoOnOneCatalogBothFinish) {
  TempDir root;
  const std::string catalog = (root / "catalog.sqlite").string();
  // One results folder: the second run is refused while the first holds it, or both finish.
  for (const char* command : {"discover", "fuse"}) {
    SCOPED_TRACE(command);
    const fs::path out = root / (std::string(command) + "_out");
    const std::vector<std::string> argv =
        std::string(command) == "fuse"
            ? std::vector<std::string>{OBJSCAN_EXE, "fuse", scene_.string(), "--out", out.string()}
            : std::vector<std::string>{OBJSCAN_EXE,    "discover", mesh_.string(),
                                       "--no-catalog", "--out",    out.string()};
    BackgroundProcess a(argv), b(argv);
    const int status_a = a.wait(120.0), status_b = b.wait(120.0);
    EXPECT_TRUE(status_a == 0 || status_b == 0) << a.err() << b.err();
    for (const auto* run : {&a, &b}) {
      const int status = run == &a ? status_a : status_b;
      if (status != 0) {
        EXPECT_EQ(status, 1) << run->err();
        EXPECT_NE(run->err().find("another objscan"), std::string::npos) << run->err();
      }
    }
    expectValidOutputs(out);
  }
  // One catalog, two scenes at once: both are added, the catalog intact.
  const fs::path other = root / "other.ply";
  {
    TriangleMesh mesh = readPly(mesh_);
    for (auto& p : mesh.positions) p.x() += 0.5f;  // another scene (another content hash)
    writePly(other, mesh);
  }
  BackgroundProcess a({OBJSCAN_EXE, "discover", mesh_.string(), "--catalog", catalog, "--out",
                       (root / "a").string()});
  BackgroundProcess b({OBJSCAN_EXE, "discover", other.string(), "--catalog", catalog, "--out",
                       (root / "b").string()});
  EXPECT_EQ(a.wait(120.0), 0) << a.err();
  EXPECT_EQ(b.wait(120.0), 0) << b.err();
  expectCatalogIntact(catalog);
  expectValidOutputs(root / "a");
  expectValidOutputs(root / "b");
  EXPECT_EQ(catalogScenes(catalog), 2);
}

}  // namespace
}  // namespace objscan
