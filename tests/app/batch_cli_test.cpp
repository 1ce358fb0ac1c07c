// objscan batch against the real binary: one scan per recording, several at a time, a rerun that
// keeps complete results, a failed recording among good ones, Ctrl-C, and bad lists refused
// before anything runs.
#include <csignal>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_expect.h"
#include "objscan/core/atomic_file.h"
#include "objscan/discovery/catalog.h"
#include "objscan/report/results_io.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::objscan;
using testing::ProcessResult;
using testing::TempDir;

/// Short synthetic recordings: a scan of each takes a few seconds.
const std::vector<std::string> kSources = {"synth:3,frames=6,objects=2",
                                           "synth:4,frames=6,objects=2",
                                           "synth:5,frames=6,objects=2"};
const std::vector<std::string> kNames = {"synth_3_frames_6_objects_2", "synth_4_frames_6_objects_2",
                                         "synth_5_frames_6_objects_2"};

/// batch SOURCES... --out OUT --jobs 2 -- --no-ground-truth --top 2
std::vector<std::string> batchArgs(const fs::path& out, const std::vector<std::string>& sources) {
  std::vector<std::string> args = {"batch"};
  args.insert(args.end(), sources.begin(), sources.end());
  args.insert(args.end(), {"--out", out.string(), "--jobs", "2", "--", "--no-ground-truth",
                           "--top", "2"});
  return args;
}

std::size_t count(const std::string& text, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) {
    ++n;
  }
  return n;
}

TEST(BatchCli, ScansEachRecordingIntoItsOwnFolderAndARerunKeepsCompleteResults) {
  TempDir dir;
  const fs::path out = dir / "all";
  const ProcessResult r = objscan(batchArgs(out, kSources));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(count(r.out, "\ndone          "), 3u) << r.out;
  for (std::size_t i = 0; i < kSources.size(); ++i) {
    const fs::path scan = out / kNames[i];
    // Each is a complete scan of its own source, with the scan options after --, and its own
    // catalog holding that one scene.
    const report::Settings settings = report::readSettings(scan / report::kSettingsFile);
    EXPECT_EQ(settings.command, "scan");
    bool source_found = false, top_found = false;
    for (const report::OptionSetting& o : settings.options) {
      source_found |= o.name == "source" && o.values == std::vector<std::string>{kSources[i]};
      top_found |= o.name == "top" && o.values == std::vector<std::string>{"2"};
    }
    EXPECT_TRUE(source_found) << kNames[i];
    EXPECT_TRUE(top_found) << kNames[i];
    EXPECT_FALSE(report::readTimings(scan / report::kTimingsFile).interrupted);
    EXPECT_FALSE(report::readHypotheses(scan / report::kHypothesesFile).hypotheses.empty());
    EXPECT_TRUE(fs::is_regular_file(scan / report::kReportFile));
    EXPECT_EQ(discovery::Catalog(out / "catalogs" / (kNames[i] + ".sqlite")).scenes().size(), 1u);
    EXPECT_TRUE(fs::is_regular_file(out / "logs" / (kNames[i] + ".log")));
  }
  // The collection's catalog: the three scans' catalogs merged, read back whole (the catalog
  // checks the file on opening).
  std::size_t segments = 0;
  for (const std::string& name : kNames) {
    segments += discovery::Catalog(out / "catalogs" / (name + ".sqlite")).segmentCount();
  }
  {
    const discovery::Catalog collection(out / "catalog.sqlite");
    EXPECT_EQ(collection.scenes().size(), 3u);
    EXPECT_EQ(collection.segmentCount(), segments);
  }
  EXPECT_NE(r.out.find("catalog       " + (out / "catalog.sqlite").string() + ": 3 scenes"),
            std::string::npos)
      << r.out;
  // Every scene ranked again with the others: recurrence across the collection, which a scene
  // scanned alone (its catalog holding only itself) never has.
  const auto withRecurrence = [](const fs::path& file, std::size_t* scenes) {
    const nlohmann::json h = nlohmann::json::parse(readWholeFile(file));
    *scenes = h.at("scenes").size();
    std::size_t n = 0;
    for (const nlohmann::json& x : h.at("hypotheses")) {
      n += x.at("measures").at("recurrence").is_null() ? 0 : 1;
    }
    return n;
  };
  std::size_t scenes = 0;
  EXPECT_GT(withRecurrence(out / "collection" / report::kHypothesesFile, &scenes), 0u);
  EXPECT_EQ(scenes, 3u);
  for (const std::string& name : kNames) {
    EXPECT_EQ(withRecurrence(out / name / report::kHypothesesFile, &scenes), 0u) << name;
  }
  // The collection's page: the three scenes, objects across them, and every picture it shows
  // a PNG beside it (its check in a browser: ViewPage.TheCollectionPage...).
  const std::string index = readWholeFile(out / "index.html");
  EXPECT_NE(index.find("data-scenes=\"3\""), std::string::npos);
  EXPECT_EQ(index.find("data-groups=\"0\""), std::string::npos);
  std::size_t pictures = 0;
  for (std::size_t at = index.find("<img src=\""); at != std::string::npos;
       at = index.find("<img src=\"", at + 1)) {
    const std::size_t from = at + 10;
    const fs::path picture = out / index.substr(from, index.find('"', from) - from);
    EXPECT_EQ(readWholeFile(picture).substr(0, 4), "\x89PNG") << picture;
    ++pictures;
  }
  EXPECT_GE(pictures, 3u);
  EXPECT_NE(r.out.find("page          " + (out / "index.html").string() + ": 3 scenes"),
            std::string::npos)
      << r.out;
  const auto written = fs::last_write_time(out / kNames[1] / report::kHypothesesFile);

  // A person labels a segment of the collection (objscan view DIR/collection writes the
  // collection's catalog); the batch makes that catalog again below, and the label stays.
  std::string labelled_hash;
  std::vector<std::int32_t> labelled_vertices;
  {
    discovery::Catalog collection(out / "catalog.sqlite");
    const discovery::CatalogScene scene = collection.scenes().at(1);
    const discovery::CatalogSegment segment = collection.segments(scene.id, true).at(0);
    collection.setLabel(segment.id, 1, "tester");
    labelled_hash = scene.content_hash;
    labelled_vertices = segment.vertices;
  }

  // Again: nothing to do, nothing rewritten.
  const ProcessResult again = objscan(batchArgs(out, kSources));
  ASSERT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_EQ(count(again.out, "\ncomplete      "), 2u) << again.out;  // the first has no \n
  EXPECT_EQ(count(again.out, "complete      "), 3u) << again.out;
  EXPECT_EQ(count(again.out, "done          "), 0u) << again.out;
  EXPECT_EQ(fs::last_write_time(out / kNames[1] / report::kHypothesesFile), written);
  // Merged again from the same catalogs: the same collection, with the person's label.
  const discovery::Catalog collection(out / "catalog.sqlite");
  EXPECT_EQ(collection.scenes().size(), 3u);
  EXPECT_EQ(collection.segmentCount(), segments);
  std::size_t labels = 0;
  for (const discovery::CatalogScene& scene : collection.scenes()) {
    for (const discovery::CatalogSegment& s : collection.segments(scene.id, true)) {
      if (!s.label) continue;
      ++labels;
      EXPECT_EQ(scene.content_hash, labelled_hash);
      EXPECT_EQ(s.vertices, labelled_vertices);
      EXPECT_EQ(*s.label, 1);
      EXPECT_EQ(s.labelled_by, "tester");
    }
  }
  EXPECT_EQ(labels, 1u);
  // The catalog it replaced is kept beside it, label and history.
  EXPECT_EQ(discovery::Catalog(out / "catalog.previous.sqlite").scenes().size(), 3u);
}

TEST(BatchCli, AFailedRecordingIsReportedTheOthersAreScannedAndARerunFillsTheGap) {
  TempDir dir;
  const fs::path out = dir / "all";
  fs::create_directories(out);
  // A file where the second recording's folder would go: its scan fails, the batch goes on.
  testing::writeBytes(out / kNames[1], "in the way");
  const ProcessResult r = objscan(batchArgs(out, kSources));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  // On stderr, so that --quiet shows it too: which recording, and why, from its scan.
  EXPECT_NE(r.err.find("error: " + kNames[1] + " (" + kSources[1] + ") failed after "),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("exit 1: " + (out / kNames[1]).string()), std::string::npos) << r.err;
  EXPECT_EQ(count(r.out, "done          "), 2u) << r.out;
  EXPECT_NE(r.out.find("2 scanned, 1 failed"), std::string::npos) << r.out;

  fs::remove(out / kNames[1]);
  const ProcessResult again = objscan(batchArgs(out, kSources));
  EXPECT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_EQ(count(again.out, "done          "), 1u) << again.out;
  EXPECT_NE(again.out.find("done          " + kNames[1]), std::string::npos) << again.out;
  EXPECT_EQ(count(again.out, "complete      "), 2u) << again.out;
}

TEST(BatchCli, CtrlCStopsTheScansAndARerunFinishesThem) {
  TempDir dir;
  const fs::path out = dir / "all";
  // Longer recordings: both scans are still fusing when the stop comes.
  const std::vector<std::string> sources = {"synth:3,frames=60,objects=2",
                                            "synth:4,frames=60,objects=2",
                                            "synth:5,frames=60,objects=2"};
  std::vector<std::string> args = batchArgs(out, sources);
  args.insert(args.begin(), OBJSCAN_EXE);
  testing::ProcessOptions options;
  options.signal = SIGINT;
  options.signal_when = "started       synth_4_frames_60_objects_2";
  options.signal_delay_ms = 500;
  const ProcessResult r = testing::runProcess(args, options);
  EXPECT_EQ(r.exit_code, 130) << r.out << r.err;
  // Both running scans were told, and stopped as a scan stops on Ctrl-C (exit 130), keeping
  // what they had; the third never started.
  EXPECT_EQ(count(r.out, "stopped       "), 2u) << r.out;
  EXPECT_EQ(count(r.out, "(exit 130)"), 2u) << r.out;
  EXPECT_EQ(count(r.out, "done          "), 0u) << r.out;
  EXPECT_NE(r.out.find("stopped by    Ctrl-C"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out / "synth_5_frames_60_objects_2"));

  const ProcessResult again = objscan(batchArgs(out, sources));
  EXPECT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_EQ(count(again.out, "done          "), 3u) << again.out;
}

TEST(BatchCli, BadListsAreOneErrorEachBeforeAnythingRuns) {
  TempDir dir;
  const fs::path out = dir / "all";
  const fs::path missing = dir / "missing.oni";
  testing::expectOneErrorLine(objscan(batchArgs(out, {kSources[0], missing.string()})), 2,
                              missing.string() + ": missing");
  // Two sources whose results would share a folder.
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  testing::writeBytes(dir / "a" / "desk.oni", "not a recording");
  testing::writeBytes(dir / "b" / "desk.oni", "not a recording");
  testing::expectOneErrorLine(
      objscan(batchArgs(out, {(dir / "a" / "desk.oni").string(), (dir / "b" / "desk.oni").string()})),
      2, "its results folder would be desk, as that of " + (dir / "a" / "desk.oni").string());
  // A recording that cannot be read.
  testing::expectOneErrorLine(objscan(batchArgs(out, {(dir / "a" / "desk.oni").string()})), 2,
                              (dir / "a" / "desk.oni").string());
  // A sensor, an option a batch sets itself, an option scan does not have, an empty list.
  testing::expectOneErrorLine(objscan(batchArgs(out, {"live"})), 2, "a batch scans recordings");
  testing::expectOneErrorLine(
      objscan({"batch", kSources[0], "--out", out.string(), "--", "--catalog", "x.sqlite"}), 2,
      "--catalog is not a scan option a batch takes");
  testing::expectOneErrorLine(
      objscan({"batch", kSources[0], "--out", out.string(), "--", "--frobnicate"}), 2,
      "--frobnicate");
  testing::expectOneErrorLine(
      objscan({"batch", kSources[0], "--out", out.string(), "--", "--no-catalog=maybe"}), 2,
      "--no-catalog");
  // Option values scan would refuse before opening its source.
  testing::expectOneErrorLine(
      objscan({"batch", kSources[0], "--out", out.string(), "--", "--voxel-size", "0"}), 2,
      "voxel");
  testing::expectOneErrorLine(objscan({"batch", kSources[0], "--out", out.string(), "--", "--model",
                                       (dir / "none.model").string()}),
                              2, (dir / "none.model").string());
  // Folders whose names are ones the batch keeps for itself.
  for (const char* kept : {"logs", "collection"}) {
    fs::create_directories(dir / kept);
    testing::expectOneErrorLine(
        objscan(batchArgs(out, {(dir / kept).string()})), 2,
        std::string("gives no results folder name of its own (") + kept + ")");
  }
  const fs::path list = dir / "list.txt";
  testing::writeBytes(list, "# nothing but a comment\n\n");
  testing::expectOneErrorLine(objscan({"batch", "--list", list.string(), "--out", out.string()}),
                              2, "no sources");
  testing::expectOneErrorLine(
      objscan({"batch", "--list", (dir / "none.txt").string(), "--out", out.string()}), 2,
      (dir / "none.txt").string() + ": missing");
  EXPECT_FALSE(fs::exists(out));
}

TEST(BatchCli, AnotherSourcesResultsAreNotScannedOver) {
  TempDir dir;
  const fs::path out = dir / "all";
  ASSERT_EQ(objscan(batchArgs(out, {kSources[0]})).exit_code, 0);
  // Another recording whose folder name is the same: refused, the results left as they are.
  fs::create_directories(dir / "other");
  const fs::path other = dir / "other" / (kNames[0] + ".oni");
  fs::copy_file(fs::path(OBJSCAN_SOURCE_DIR) / "recordings" / "synth_desk.oni", other);
  const auto written = fs::last_write_time(out / kNames[0] / report::kHypothesesFile);
  testing::expectOneErrorLine(objscan(batchArgs(out, {other.string()})), 2,
                              (out / kNames[0]).string() + ": holds the results of " + kSources[0] +
                                  ", not of " + other.string());
  EXPECT_EQ(fs::last_write_time(out / kNames[0] / report::kHypothesesFile), written);
}

TEST(BatchCli, AListFileNamesTheSourcesAndNamesComeFromThem) {
  TempDir dir;
  const fs::path list = dir / "list.txt";
  testing::writeBytes(list, "# two scenes\n  " + kSources[0] + "  \n\n" + kSources[1] + "\n");
  const fs::path out = dir / "all";
  const ProcessResult r = objscan({"batch", "--list", list.string(), "--out", out.string(),
                                   "--jobs", "1", "--", "--no-ground-truth", "--top", "1"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_TRUE(fs::is_regular_file(out / kNames[0] / report::kReportFile));
  EXPECT_TRUE(fs::is_regular_file(out / kNames[1] / report::kReportFile));
  EXPECT_FALSE(fs::exists(out / kNames[2]));
}

}  // namespace
}  // namespace objscan
