// objscan batch --slurm on a real one-node Slurm cluster that the suite starts (tests/slurm/cluster:
// munged, slurmctld and slurmd from Debian's packages, everything under a temporary folder) and
// stops: the cluster's results equal those of one scan at a time here, a cancelled array task is
// reported and its rerun fills the gap, a batch of one works, and bad lists are refused before
// anything is submitted. One process for the suite (SlurmBatch.all), so the cluster starts once.
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "build_paths.h"
#include "objscan/core/atomic_file.h"
#include "objscan/discovery/catalog.h"
#include "objscan/report/results_io.h"
#include "cli_expect.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::objscan;
using testing::ProcessResult;
using testing::TempDir;

class SlurmBatch : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    const ProcessResult r = testing::runProcess(
        {std::string(OBJSCAN_SOURCE_DIR) + "/tests/slurm/cluster", "start", cluster().string()},
        {});
    const std::size_t at = r.out.find("SLURM_CONF=");
    if (r.exit_code == 0 && at != std::string::npos) {
      std::string conf = r.out.substr(at + 11);
      conf = conf.substr(0, conf.find('\n'));
      ::setenv("SLURM_CONF", conf.c_str(), 1);
      started_ = true;
    } else {
      start_error_ = r.out + r.err;
    }
  }
  static void TearDownTestSuite() {
    testing::runProcess(
        {std::string(OBJSCAN_SOURCE_DIR) + "/tests/slurm/cluster", "stop", cluster().string()}, {});
    ::unsetenv("SLURM_CONF");
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override { ASSERT_TRUE(started_) << "the test cluster did not start: " << start_error_; }

  static fs::path cluster() { return dir_->path() / "cluster"; }

  /// `objscan batch --status DIR` until the batch's jobs have all left the queue (at most
  /// `timeout_s`); its last output.
  static std::string waitForTheBatch(const fs::path& out, int timeout_s = 240) {
    std::string status;
    const auto start = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - start < std::chrono::seconds(timeout_s)) {
      status = objscan({"batch", "--status", out.string()}).out;
      // No scan queued or running, and the merge out of the queue.
      if (status.find(" 0 running, 0 queued,") != std::string::npos &&
          (status.find("merge         ended") != std::string::npos ||
           status.find("merge         not in the queue") != std::string::npos)) {
        return status;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    ADD_FAILURE() << "the batch did not end in " << timeout_s << " s:\n" << status;
    return status;
  }

  static TempDir* dir_;
  static bool started_;
  static std::string start_error_;
};

TempDir* SlurmBatch::dir_ = nullptr;
bool SlurmBatch::started_ = false;
std::string SlurmBatch::start_error_;

std::string integrityCheck(const fs::path& file) {
  sqlite3* db = nullptr;
  std::string result;
  if (sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &s, nullptr) == SQLITE_OK &&
        sqlite3_step(s) == SQLITE_ROW) {
      result = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
    }
    sqlite3_finalize(s);
  }
  sqlite3_close(db);
  return result;
}

/// hypotheses.json without what differs between two runs of the same scans in two folders:
/// the absolute paths of the scenes and the catalog, and the time each stage took.
nlohmann::json comparable(const fs::path& file) {
  nlohmann::json h = nlohmann::json::parse(readWholeFile(file));
  for (nlohmann::json& s : h.at("scenes")) {
    s.erase("mesh_absolute");
    s.erase("timings_ms");
  }
  h.erase("catalog");
  return h;
}

/// The two files' comparable() forms are equal; else the first differences (a JSON patch).
void expectSame(const fs::path& a, const fs::path& b) {
  const nlohmann::json patch = nlohmann::json::diff(comparable(a), comparable(b));
  EXPECT_TRUE(patch.empty()) << a << " and " << b << " differ: "
                             << patch.dump().substr(0, 600);
}

std::string name(const std::string& source) {
  std::string n = "synth_" + source.substr(6);
  for (char& c : n) c = (c == ',' || c == '=') ? '_' : c;
  return n;
}

TEST_F(SlurmBatch, TheClusterGivesTheSameResultsAsOneScanAtATimeHere) {
  TempDir dir;
  std::vector<std::string> sources;
  for (int seed = 3; seed <= 8; ++seed) {
    sources.push_back("synth:" + std::to_string(seed) + ",frames=6,objects=2");
  }
  const auto batch = [&](const fs::path& out, std::vector<std::string> extra) {
    std::vector<std::string> args = {"batch"};
    args.insert(args.end(), sources.begin(), sources.end());
    args.insert(args.end(), {"--out", out.string()});
    args.insert(args.end(), extra.begin(), extra.end());
    args.insert(args.end(), {"--", "--no-ground-truth", "--top", "3"});
    return objscan(args);
  };
  const fs::path local = dir / "local", cluster = dir / "cluster";
  const ProcessResult here = batch(local, {"--jobs", "1"});
  ASSERT_EQ(here.exit_code, 0) << here.out << here.err;
  const ProcessResult submitted = batch(cluster, {"--slurm", "--max-running", "2"});
  ASSERT_EQ(submitted.exit_code, 0) << submitted.out << submitted.err;
  EXPECT_NE(submitted.out.find(": 6 recordings, 2 at a time; merge job "), std::string::npos)
      << submitted.out;
  const std::string status = waitForTheBatch(cluster);
  EXPECT_NE(status.find("batch         6 done, 0 running, 0 queued, 0 failed"), std::string::npos)
      << status;
  EXPECT_NE(status.find("merge         ended"), std::string::npos) << status;

  // The same hypotheses, scan by scan and for the collection (timings aside).
  for (const std::string& source : sources) {
    expectSame(cluster / name(source) / report::kHypothesesFile,
               local / name(source) / report::kHypothesesFile);
  }
  expectSame(cluster / "collection" / report::kHypothesesFile,
             local / "collection" / report::kHypothesesFile);
  EXPECT_EQ(integrityCheck(cluster / "catalog.sqlite"), "ok");
  EXPECT_EQ(discovery::Catalog(cluster / "catalog.sqlite").scenes().size(), 6u);
  EXPECT_NE(readWholeFile(cluster / "index.html").find("data-scenes=\"6\""), std::string::npos);
  // What was submitted is kept, to read and submit again.
  EXPECT_NE(readWholeFile(cluster / "slurm" / "submit.sh").find("--array=0-5%2"),
            std::string::npos);
  EXPECT_NE(readWholeFile(cluster / "slurm" / "scan.sbatch").find("#SBATCH --mem=1536M"),
            std::string::npos);
}

TEST_F(SlurmBatch, ACancelledTaskIsReportedAndTheRerunFillsTheGap) {
  TempDir dir;
  const fs::path out = dir / "all";
  // The last recording is long enough to be cancelled while it is scanned.
  const std::vector<std::string> sources = {"synth:3,frames=6,objects=2",
                                            "synth:4,frames=6,objects=2",
                                            "synth:5,frames=400,objects=2"};
  std::vector<std::string> args = {"batch"};
  args.insert(args.end(), sources.begin(), sources.end());
  args.insert(args.end(), {"--out", out.string(), "--slurm", "--", "--no-ground-truth"});
  const ProcessResult r = objscan(args);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json jobs = nlohmann::json::parse(readWholeFile(out / "slurm" / "jobs.json"));
  const std::string task = jobs.at("array").get<std::string>() + "_2";
  // While its jobs are queued or running, the batch is not submitted again, nor run here: two
  // scans would write one folder.
  testing::expectOneErrorLine(objscan(args), 1, "still queued or running");
  std::vector<std::string> here = args;
  here.erase(std::find(here.begin(), here.end(), "--slurm"));
  testing::expectOneErrorLine(objscan(here), 1, "still queued or running");
  // Cancelled once it is fusing (its log says so).
  bool fusing = false;
  for (int i = 0; i < 1200 && !fusing; ++i) {
    const fs::path log = out / "logs" / (name(sources[2]) + ".log");
    fusing = fs::exists(log) && readWholeFile(log).find("fusing frames") != std::string::npos;
    if (!fusing) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(fusing) << objscan({"batch", "--status", out.string()}).out;
  const ProcessResult cancel = testing::runProcess({"/usr/bin/env", "scancel", task}, {});
  ASSERT_EQ(cancel.exit_code, 0) << cancel.err;
  std::string status = waitForTheBatch(out);
  EXPECT_NE(status.find("batch         2 done, 0 running, 0 queued, 1 failed"), std::string::npos)
      << status;
  EXPECT_NE(status.find("failed        " + name(sources[2])), std::string::npos) << status;
  // The merge ran after the failure: the collection of the two complete recordings.
  EXPECT_EQ(integrityCheck(out / "catalog.sqlite"), "ok");
  EXPECT_EQ(discovery::Catalog(out / "catalog.sqlite").scenes().size(), 2u);
  EXPECT_NE(readWholeFile(out / "index.html").find("data-scenes=\"2\""), std::string::npos);

  // Again: only the cancelled one is submitted, and the collection is whole.
  const ProcessResult again = objscan(args);
  ASSERT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_NE(again.out.find(": 1 recordings; merge job "), std::string::npos) << again.out;
  status = waitForTheBatch(out);
  EXPECT_NE(status.find("batch         3 done, 0 running, 0 queued, 0 failed"), std::string::npos)
      << status;
  EXPECT_EQ(integrityCheck(out / "catalog.sqlite"), "ok");
  EXPECT_EQ(discovery::Catalog(out / "catalog.sqlite").scenes().size(), 3u);
  EXPECT_NE(readWholeFile(out / "index.html").find("data-scenes=\"3\""), std::string::npos);
}

TEST_F(SlurmBatch, ABatchOfOneRecordingWorks) {
  TempDir dir;
  const fs::path out = dir / "one";
  const ProcessResult r = objscan({"batch", "synth:6,frames=6,objects=2", "--out", out.string(),
                                   "--slurm", "--", "--no-ground-truth"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const std::string status = waitForTheBatch(out);
  EXPECT_NE(status.find("batch         1 done"), std::string::npos) << status;
  EXPECT_EQ(integrityCheck(out / "catalog.sqlite"), "ok");
  const std::string index = readWholeFile(out / "index.html");
  EXPECT_NE(index.find("data-scenes=\"1\""), std::string::npos);
  EXPECT_NE(index.find("One scene: there is no other scene"), std::string::npos);
}

TEST_F(SlurmBatch, BadListsAreOneErrorEachBeforeAnythingIsSubmitted) {
  TempDir dir;
  const fs::path out = dir / "bad";
  testing::writeBytes(dir / "junk.oni", "not a recording");
  testing::writeBytes(dir / "list.txt", "synth:3,frames=6\n" + (dir / "missing.oni").string() + "\n");
  const std::string queue_before = testing::runProcess({"/usr/bin/env", "squeue", "-h"}, {}).out;
  const std::string list = (dir / "list.txt").string(), junk = (dir / "junk.oni").string();
  testing::expectOneErrorLine(
      objscan({"batch", "--list", list, "--out", out.string(), "--slurm"}), 2,
      (dir / "missing.oni").string() + ": missing");
  testing::expectOneErrorLine(
      objscan({"batch", "synth:3,frames=6", "synth:3,frames=6", "--out", out.string(), "--slurm"}),
      2, "its results folder would be synth_3_frames_6, as that of synth:3,frames=6");
  testing::expectOneErrorLine(objscan({"batch", junk, "--out", out.string(), "--slurm"}), 2, junk);
  testing::expectOneErrorLine(
      objscan({"batch", "--list", (dir / "absent.txt").string(), "--out", out.string(), "--slurm"}),
      2, "absent.txt: missing");
  testing::expectOneErrorLine(
      objscan({"batch", "synth:3,frames=6", "--out", out.string(), "--partition", "test"}), 2,
      "go with --slurm");
  testing::expectOneErrorLine(
      objscan({"batch", "synth:3,frames=6", "--out", out.string(), "--slurm", "--jobs", "2"}), 2,
      "--max-running");
  EXPECT_FALSE(fs::exists(out / "slurm"));
  EXPECT_EQ(testing::runProcess({"/usr/bin/env", "squeue", "-h"}, {}).out, queue_before);
}

}  // namespace
}  // namespace objscan
