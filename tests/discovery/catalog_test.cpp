// The SQLite catalog on real files in a temporary folder: round trips, replacement, atomicity,
// and every kind of file that is not a catalog of this objscan. Files that other programs would
// make (a foreign database, a newer schema) are made here through SQLite's C API directly.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <future>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "objscan/core/error.h"
#include "objscan/discovery/catalog.h"
#include "test_support.h"

namespace objscan::discovery {
namespace {

namespace fs = std::filesystem;
using objscan::testing::expectInputError;
using objscan::testing::readBytes;
using objscan::testing::TempDir;
using objscan::testing::writeBytes;

/// Runs SQL on a file with SQLite itself; throws on any error.
void sql(const fs::path& file, const std::string& statements) {
  sqlite3* db = nullptr;
  int rc = sqlite3_open(file.c_str(), &db);
  if (rc == SQLITE_OK) rc = sqlite3_exec(db, statements.c_str(), nullptr, nullptr, nullptr);
  const std::string message = sqlite3_errmsg(db);
  sqlite3_close(db);
  if (rc != SQLITE_OK) throw std::runtime_error(message);
}

/// The single integer a query returns.
std::int64_t sqlInteger(const fs::path& file, const std::string& query) {
  sqlite3* db = nullptr;
  sqlite3_stmt* s = nullptr;
  std::int64_t value = -1;
  if (sqlite3_open(file.c_str(), &db) == SQLITE_OK &&
      sqlite3_prepare_v2(db, query.c_str(), -1, &s, nullptr) == SQLITE_OK &&
      sqlite3_step(s) == SQLITE_ROW) {
    value = sqlite3_column_int64(s, 0);
  }
  sqlite3_finalize(s);
  sqlite3_close(db);
  return value;
}

/// The text a query returns ("" when it returns nothing).
std::string sqlText(const fs::path& file, const std::string& query) {
  sqlite3* db = nullptr;
  sqlite3_stmt* s = nullptr;
  std::string value;
  if (sqlite3_open(file.c_str(), &db) == SQLITE_OK &&
      sqlite3_prepare_v2(db, query.c_str(), -1, &s, nullptr) == SQLITE_OK &&
      sqlite3_step(s) == SQLITE_ROW && sqlite3_column_text(s, 0) != nullptr) {
    value = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
  }
  sqlite3_finalize(s);
  sqlite3_close(db);
  return value;
}

/// A segment whose every number depends on `i`, including awkward floats.
CatalogSegment makeSegment(int i, std::size_t vertex_count = 5) {
  CatalogSegment s;
  const auto f = static_cast<float>(i);
  s.scale = 5.0f * f;
  s.centroid = {0.1f * f, -0.0f, 1e-40f};  // negative zero and a subnormal
  s.axes << 0.0f, 1.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f, -1.0f / (f + 3.0f);
  s.eigenvalues = {0.01f * f + 0.001f, 0.002f, 1.0f / 3.0f};
  s.extents = {0.3f + 0.01f * f, 0.1f, 0.05f};
  s.measures.compactness = 0.1 * i + 1.0 / 3.0;
  s.measures.symmetry = 1e-300;
  s.measures.smoothness = std::nextafter(0.9, 1.0);
  s.measures.local_convexity = i % 2 == 0 ? std::numeric_limits<double>::quiet_NaN() : 0.5;
  s.measures.global_convexity = 0.004 * i;
  s.measures.recurrence = 123.0;    // not stored: reads back as NaN
  if (i % 3 != 2) s.label = i % 3;  // 0, 1, unknown
  for (std::size_t v = 0; v < vertex_count; ++v) {
    s.vertices.push_back(static_cast<std::int32_t>(v * 1000 + static_cast<std::size_t>(i)));
  }
  if (vertex_count > 0) s.vertices.back() = std::numeric_limits<std::int32_t>::max();
  return s;
}

/// SQLite's REAL columns keep every double bit for bit but one: -0.0 reads back as 0.0.
bool sameBits(float a, float b) {
  return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b == 0.0f ? 0.0f : b);
}
bool sameBits(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) ||
         std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

void expectSameSegment(const CatalogSegment& got, const CatalogSegment& want, bool with_vertices) {
  EXPECT_TRUE(sameBits(got.scale, want.scale));
  for (int d = 0; d < 3; ++d) {
    EXPECT_TRUE(sameBits(got.centroid[d], want.centroid[d])) << d;
    EXPECT_TRUE(sameBits(got.eigenvalues[d], want.eigenvalues[d])) << d;
    EXPECT_TRUE(sameBits(got.extents[d], want.extents[d])) << d;
  }
  for (int i = 0; i < 9; ++i) EXPECT_TRUE(sameBits(got.axes(i), want.axes(i))) << i;
  EXPECT_TRUE(sameBits(got.measures.compactness, want.measures.compactness));
  EXPECT_TRUE(sameBits(got.measures.symmetry, want.measures.symmetry));
  EXPECT_TRUE(sameBits(got.measures.smoothness, want.measures.smoothness));
  EXPECT_TRUE(sameBits(got.measures.local_convexity, want.measures.local_convexity));
  EXPECT_TRUE(sameBits(got.measures.global_convexity, want.measures.global_convexity));
  EXPECT_TRUE(std::isnan(got.measures.recurrence));
  EXPECT_EQ(got.label, want.label);
  if (with_vertices) {
    EXPECT_EQ(got.vertices, want.vertices);
  } else {
    EXPECT_TRUE(got.vertices.empty());
  }
}

CatalogScene makeScene(const std::string& name, const std::string& hash,
                       const std::string& settings = "scales=5..2560") {
  return CatalogScene{0, name, hash, 1000, settings};
}

TEST(Catalog, NewFileIsAnEmptyCatalog) {
  TempDir dir;
  const Catalog catalog(dir / "catalog.sqlite");
  EXPECT_TRUE(fs::exists(dir / "catalog.sqlite"));
  EXPECT_TRUE(catalog.scenes().empty());
  EXPECT_EQ(catalog.segmentCount(), 0u);
  EXPECT_FALSE(catalog.findScene("0123456789abcdef", "scales=5..2560").has_value());
  EXPECT_TRUE(catalog.recurrenceEntries().empty());
  EXPECT_EQ(sqlInteger(dir / "catalog.sqlite", "PRAGMA user_version"), Catalog::kSchemaVersion);
}

TEST(Catalog, RoundTripsScenesSegmentsLabelsAndVertices) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::vector<CatalogSegment> first = {makeSegment(0), makeSegment(1), makeSegment(2, 0)};
  const std::vector<CatalogSegment> second = {makeSegment(3, 20000), makeSegment(4)};
  CatalogScene desk = makeScene("desk.ply", "00000000000000aa");
  desk.id = 999;  // ignored
  const std::int64_t a = catalog.addScene(desk, first);
  const std::int64_t b = catalog.addScene(makeScene("kitchen ü.ply", "00000000000000bb"), second);
  EXPECT_NE(a, b);

  const std::vector<CatalogScene> scenes = catalog.scenes();
  ASSERT_EQ(scenes.size(), 2u);
  EXPECT_EQ(scenes[0].id, a);
  EXPECT_EQ(scenes[0].name, "desk.ply");
  EXPECT_EQ(scenes[0].content_hash, "00000000000000aa");
  EXPECT_EQ(scenes[0].settings, "scales=5..2560");
  EXPECT_EQ(scenes[0].vertex_count, 1000u);
  EXPECT_EQ(scenes[1].name, "kitchen ü.ply");
  const std::optional<CatalogScene> found = catalog.findScene("00000000000000bb", "scales=5..2560");
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->id, b);
  EXPECT_FALSE(catalog.findScene("00000000000000bb", "other settings").has_value());

  EXPECT_EQ(catalog.segmentCount(), 5u);
  for (const bool with_vertices : {true, false}) {
    const std::vector<CatalogSegment> got = catalog.segments(a, with_vertices);
    ASSERT_EQ(got.size(), first.size());
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].scene_id, a);
      expectSameSegment(got[i], first[i], with_vertices);
    }
    EXPECT_LT(got[0].id, got[1].id);
  }
  const std::vector<CatalogSegment> got = catalog.segments(b, true);
  ASSERT_EQ(got.size(), 2u);
  expectSameSegment(got[0], second[0], true);
  EXPECT_TRUE(catalog.segments(b + a + 100, true).empty());
}

TEST(Catalog, MergingAddsTheScenesNotThereAndTwiceChangesNothing) {
  TempDir dir;
  Catalog first(dir / "first.sqlite");
  first.addScene(makeScene("desk.ply", "00000000000000aa"), {makeSegment(0), makeSegment(1)});
  Catalog second(dir / "second.sqlite");
  second.addScene(makeScene("desk.ply", "00000000000000aa"), {makeSegment(0), makeSegment(1)});
  const std::vector<CatalogSegment> kitchen = {makeSegment(3, 20000), makeSegment(4)};
  second.addScene(makeScene("kitchen.ply", "00000000000000bb"), kitchen);

  Catalog collection(dir / "collection.sqlite");
  EXPECT_EQ(mergeCatalog(collection, first), 1u);
  EXPECT_EQ(mergeCatalog(collection, second), 1u);  // the desk is there already
  EXPECT_EQ(mergeCatalog(collection, second), 0u);
  EXPECT_EQ(mergeCatalog(collection, first), 0u);
  ASSERT_EQ(collection.scenes().size(), 2u);
  EXPECT_EQ(collection.segmentCount(), 4u);
  // The kitchen's segments as they were, vertices and labels included.
  const std::optional<CatalogScene> found =
      collection.findScene("00000000000000bb", "scales=5..2560");
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->name, "kitchen.ply");
  const std::vector<CatalogSegment> got = collection.segments(found->id, true);
  ASSERT_EQ(got.size(), kitchen.size());
  for (std::size_t i = 0; i < got.size(); ++i) expectSameSegment(got[i], kitchen[i], true);
}

TEST(Catalog, VerticesAreLittleEndianInt32) {
  TempDir dir;
  CatalogSegment s = makeSegment(1, 0);
  s.vertices = {1, 0x01020304};
  Catalog(dir / "c.sqlite").addScene(makeScene("s", "h"), {s});
  EXPECT_EQ(
      sqlInteger(dir / "c.sqlite", "SELECT vertices = x'0100000004030201' FROM segment_vertices"),
      1);
}

TEST(Catalog, ReopenedFileHoldsWhatWasAdded) {
  TempDir dir;
  std::int64_t id = 0;
  {
    Catalog catalog(dir / "catalog.sqlite");
    id = catalog.addScene(makeScene("desk", "aa"), {makeSegment(1), makeSegment(2)});
  }
  const Catalog reopened(dir / "catalog.sqlite");
  ASSERT_EQ(reopened.scenes().size(), 1u);
  EXPECT_EQ(reopened.scenes()[0].id, id);
  const std::vector<CatalogSegment> got = reopened.segments(id, true);
  ASSERT_EQ(got.size(), 2u);
  expectSameSegment(got[1], makeSegment(2), true);
}

TEST(Catalog, SecondConnectionSeesCommittedScenes) {
  TempDir dir;
  Catalog writer(dir / "catalog.sqlite");
  const Catalog reader(dir / "catalog.sqlite");
  writer.addScene(makeScene("desk", "aa"), {makeSegment(1)});
  EXPECT_EQ(reader.scenes().size(), 1u);
  EXPECT_EQ(reader.segmentCount(), 1u);
}

TEST(Catalog, SameHashAndSettingsReplacesTheScene) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::int64_t old_id =
      catalog.addScene(makeScene("desk", "aa"), {makeSegment(0), makeSegment(1), makeSegment(2)});
  const std::int64_t other = catalog.addScene(makeScene("desk", "aa", "coarser"), {makeSegment(5)});
  const std::int64_t new_id = catalog.addScene(makeScene("desk again", "aa"), {makeSegment(7)});
  EXPECT_GT(new_id, other);  // ids are never reused
  const std::vector<CatalogScene> scenes = catalog.scenes();
  ASSERT_EQ(scenes.size(), 2u);
  EXPECT_EQ(scenes[0].id, other);
  EXPECT_EQ(scenes[1].id, new_id);
  EXPECT_EQ(catalog.findScene("aa", "scales=5..2560")->name, "desk again");
  EXPECT_TRUE(catalog.segments(old_id, true).empty());
  EXPECT_EQ(catalog.segmentCount(), 2u);
  // The replaced scene's vertex lists went with its segments.
  EXPECT_EQ(sqlInteger(dir / "catalog.sqlite", "SELECT count(*) FROM segment_vertices"), 2);
}

TEST(Catalog, FailedAddSceneChangesNothing) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  Catalog catalog(file);
  const std::int64_t kept = catalog.addScene(makeScene("desk", "aa"), {makeSegment(1)});
  // The third segment is refused after the scene row and two segments were written.
  std::vector<CatalogSegment> bad = {makeSegment(2), makeSegment(3), makeSegment(4)};
  bad[2].scale = -1.0f;
  EXPECT_THROW(catalog.addScene(makeScene("shelf", "bb"), bad), std::invalid_argument);
  // The same as a replacement of the kept scene: the old one stays whole.
  EXPECT_THROW(catalog.addScene(makeScene("desk", "aa"), bad), std::invalid_argument);
  bad[2].scale = 1.0f;
  bad[2].label = 3;
  EXPECT_THROW(catalog.addScene(makeScene("shelf", "bb"), bad), std::invalid_argument);
  bad[2].label.reset();
  bad[2].extents[1] = -0.1f;
  EXPECT_THROW(catalog.addScene(makeScene("shelf", "bb"), bad), std::invalid_argument);

  const std::vector<CatalogScene> scenes = catalog.scenes();
  ASSERT_EQ(scenes.size(), 1u);
  EXPECT_EQ(scenes[0].id, kept);
  EXPECT_EQ(catalog.segmentCount(), 1u);
  EXPECT_EQ(catalog.segments(kept, true).size(), 1u);
  EXPECT_EQ(sqlInteger(file, "SELECT count(*) FROM segment_vertices"), 1);
  // And the catalog goes on working.
  bad[2].extents[1] = 0.1f;
  catalog.addScene(makeScene("shelf", "bb"), bad);
  EXPECT_EQ(catalog.segmentCount(), 4u);
}

TEST(Catalog, SetLabelsIsAllOrNothing) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::int64_t a =
      catalog.addScene(makeScene("desk", "aa"), {makeSegment(2), makeSegment(5)});
  const std::int64_t b = catalog.addScene(makeScene("shelf", "bb"), {makeSegment(8)});
  const std::vector<CatalogSegment> sa = catalog.segments(a, false);
  const std::int64_t in_b = catalog.segments(b, false)[0].id;
  ASSERT_FALSE(sa[0].label.has_value());
  catalog.setLabels(a, {{sa[0].id, 1}, {sa[1].id, 0}});
  EXPECT_EQ(catalog.segments(a, false)[0].label, 1);
  EXPECT_EQ(catalog.segments(a, false)[1].label, 0);
  // A segment of another scene, after a valid change: nothing is applied.
  EXPECT_THROW(catalog.setLabels(a, {{sa[0].id, 0}, {in_b, 1}}), std::invalid_argument);
  EXPECT_THROW(catalog.setLabels(a, {{sa[0].id, 0}, {sa[1].id, 3}}), std::invalid_argument);
  EXPECT_EQ(catalog.segments(a, false)[0].label, 1);
  EXPECT_EQ(catalog.segments(b, false)[0].label, makeSegment(8).label);
}

TEST(Catalog, RecurrenceEntriesAreEverySegment) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::int64_t a =
      catalog.addScene(makeScene("desk", "aa"), {makeSegment(0), makeSegment(1)});
  const std::int64_t b = catalog.addScene(makeScene("shelf", "bb"), {makeSegment(2)});
  const std::vector<RecurrenceEntry> entries = catalog.recurrenceEntries();
  ASSERT_EQ(entries.size(), 3u);
  const std::vector<std::int64_t> scene_ids = {a, a, b};
  for (std::size_t i = 0; i < 3; ++i) {
    const CatalogSegment want = makeSegment(static_cast<int>(i));
    EXPECT_EQ(entries[i].scene_id, scene_ids[i]);
    EXPECT_EQ(entries[i].extents, want.extents);
    const std::array<double, 5> m = recurrenceMeasures(want.measures);
    for (std::size_t j = 0; j < 5; ++j) EXPECT_TRUE(sameBits(entries[i].measures[j], m[j])) << j;
  }
}

TEST(Catalog, TextInANumericColumnAndNegativeExtentsAreADamagedCatalog) {
  // Issue 18, defect 9: SQLite reads "abc" in a REAL column as 0, which changed scores without a
  // word, and a negative extent silently switched recurrence off.
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  std::int64_t scene = 0;
  {
    Catalog catalog(file);
    scene = catalog.addScene(makeScene("desk", "aa"), {makeSegment(0), makeSegment(1)});
  }
  sql(file, "UPDATE segments SET compactness = 'abc' WHERE id = (SELECT min(id) FROM segments)");
  {
    const Catalog catalog(file);
    expectInputError([&] { catalog.segments(scene, false); }, file,
                     "damaged: column 'compactness' holds text where a number belongs");
    expectInputError([&] { catalog.recurrenceEntries(); }, file,
                     "damaged: column 'compactness' holds text where a number belongs");
  }
  // A negative extent breaks the table's CHECK: the file's check finds it when it is opened.
  sql(file,
      "UPDATE segments SET compactness = 0.5; PRAGMA ignore_check_constraints = 1; "
      "UPDATE segments SET extent_1 = -0.2 WHERE id = (SELECT max(id) FROM segments)");
  expectInputError([&] { Catalog catalog(file); }, file,
                   "damaged: SQLite's quick_check finds \"CHECK constraint failed in segments");
  // An undefined one (NaN is stored as NULL, which the CHECK lets pass) is found where it is read.
  sql(file, "UPDATE segments SET extent_1 = NULL WHERE id = (SELECT max(id) FROM segments)");
  const Catalog catalog(file);
  expectInputError([&] { catalog.segments(scene, false); }, file,
                   "has a negative or undefined extent");
  expectInputError([&] { catalog.recurrenceEntries(); }, file,
                   "has a negative or undefined extent");
}

TEST(Catalog, MovedCatalogKeepsWorking) {
  TempDir dir;
  Catalog a(dir / "catalog.sqlite");
  Catalog b(std::move(a));
  b.addScene(makeScene("desk", "aa"), {makeSegment(0)});
  Catalog c(dir / "other.sqlite");
  c = std::move(b);
  EXPECT_EQ(c.segmentCount(), 1u);
}

TEST(Catalog, RandomBytesAreAnInputErrorNamingTheFile) {
  TempDir dir;
  const fs::path file = dir / "noise.sqlite";
  std::mt19937 rng(1);
  std::string bytes(8192, '\0');
  for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
  writeBytes(file, bytes);
  expectInputError([&] { Catalog catalog(file); }, file, "not an SQLite database");
  EXPECT_EQ(readBytes(file), bytes);  // left alone
}

TEST(Catalog, DamagedSchemaPageIsAnInputError) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  Catalog(file).addScene(makeScene("desk", "aa"), {makeSegment(0)});
  std::string bytes = readBytes(file);
  ASSERT_GE(bytes.size(), 4096u);
  for (std::size_t i = 100; i < 4096; ++i) bytes[i] = static_cast<char>(0xa5);
  writeBytes(file, bytes);
  expectInputError([&] { Catalog catalog(file); }, file, "damaged");
}

TEST(Catalog, DamagedPageFoundByQuickCheckIsAnInputErrorAndTheFileIsLeftAlone) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  {
    Catalog catalog(file);
    std::vector<CatalogSegment> segments;
    for (int i = 0; i < 40; ++i) segments.push_back(makeSegment(i, 3000));  // many pages
    catalog.addScene(makeScene("desk", "aa"), segments);
  }
  // The schema page (page 1) stays whole, so the file opens as it did; the b-tree page header of
  // the last page is garbage, which only a check of every page finds.
  std::string bytes = readBytes(file);
  const std::size_t page = static_cast<std::size_t>(sqlInteger(file, "PRAGMA page_size"));
  ASSERT_GE(bytes.size(), 8 * page);
  for (std::size_t i = bytes.size() - page; i < bytes.size() - page + 12; ++i) {
    bytes[i] = static_cast<char>(0xa5);
  }
  writeBytes(file, bytes);
  ASSERT_NE(sqlText(file, "PRAGMA quick_check"), "ok");
  expectInputError([&] { Catalog catalog(file); }, file, "damaged: SQLite's quick_check finds");
  EXPECT_EQ(readBytes(file), bytes);
  EXPECT_FALSE(fs::exists(dir / "catalog.sqlite-journal"));
}

TEST(Catalog, AnEmptyFileIsNotACatalogAndIsLeftEmpty) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  writeBytes(file, "");
  expectInputError([&] { Catalog catalog(file); }, file, "is empty (0 bytes), not a catalog");
  EXPECT_EQ(fs::file_size(file), 0u);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(Catalog, DevicesAndFifosAreRefusedBeforeSqliteOpensThem) {
  // SQLite would make /dev/null-journal (as root it can). Only where none was there before can
  // the test tell.
  const bool journal_before = fs::exists("/dev/null-journal");
  expectInputError([] { Catalog catalog("/dev/null"); }, "/dev/null", "is not a regular file");
  if (!journal_before) {
    EXPECT_FALSE(fs::exists("/dev/null-journal"));
  }
  TempDir dir;
  const fs::path fifo = dir / "catalog.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Guarded: opened for reading, a FIFO would wait for a writer forever.
  auto opened = std::async(std::launch::async, [&] {
    try {
      Catalog catalog(fifo);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("opened");
  });
  if (opened.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    ADD_FAILURE() << "opening a FIFO as the catalog did not return";
    // Lets it go on: an open for reading returns once a writer comes, and a read, should the
    // catalog have opened the FIFO for reading and writing, returns the bytes written.
    const int writer = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
    if (writer >= 0) {
      const std::string junk(4096, 'x');
      (void)!::write(writer, junk.data(), junk.size());
      ::close(writer);
    }
  }
  const std::string message = opened.get();
  EXPECT_EQ(message.rfind(fifo.string() + ": is not a regular file", 0), 0u) << message;
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(Catalog, ProcessesCreatingOneCatalogAtOnceAllOpenIt) {
  // Created under a temporary name and linked into place: none of them meets a file another is
  // still making (which, empty, is not a catalog).
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  std::vector<std::future<std::size_t>> openers;
  for (int i = 0; i < 8; ++i) {
    openers.push_back(std::async(std::launch::async, [&] { return Catalog(file).segmentCount(); }));
  }
  for (auto& o : openers) EXPECT_EQ(o.get(), 0u);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1)
      << "no temporary file is left";
  EXPECT_EQ(sqlText(file, "PRAGMA quick_check"), "ok");
}

TEST(Catalog, NewerSchemaVersionIsAnInputError) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  { Catalog catalog(file); }
  sql(file, "PRAGMA user_version = 3");
  expectInputError([&] { Catalog catalog(file); }, file,
                   "catalog schema version 3 is newer than this objscan's (2)");
}

TEST(Catalog, SqliteDatabaseWithoutOurTablesIsAnInputError) {
  TempDir dir;
  const fs::path notes = dir / "notes.sqlite";
  sql(notes, "CREATE TABLE notes (id INTEGER PRIMARY KEY, text TEXT)");
  const std::string before = readBytes(notes);
  expectInputError([&] { Catalog catalog(notes); }, notes, "not an objscan catalog");
  EXPECT_EQ(readBytes(notes), before);  // no tables added to someone else's database
  // Our table names at our version, but not our columns.
  const fs::path lookalike = dir / "lookalike.sqlite";
  sql(lookalike,
      "CREATE TABLE scenes (id INTEGER PRIMARY KEY); CREATE TABLE segments (id INTEGER);"
      "CREATE TABLE segment_vertices (id INTEGER); PRAGMA user_version = 1");
  expectInputError([&] { Catalog catalog(lookalike); }, lookalike, "not an objscan catalog");
  EXPECT_EQ(sqlInteger(lookalike, "PRAGMA user_version"), 1);  // not "upgraded"
  EXPECT_EQ(sqlInteger(lookalike, "SELECT count(*) FROM sqlite_schema WHERE type = 'table'"), 3);
}

TEST(Catalog, MissingFolderIsAnOutputErrorAndAFolderAnInputError) {
  TempDir dir;
  const fs::path file = dir / "no such folder" / "catalog.sqlite";
  try {
    Catalog catalog(file);
    ADD_FAILURE() << "no error";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "no such folder"));
  expectInputError([&] { Catalog catalog(dir.path()); }, dir.path(), "is a folder");
}

// --- People's labels (schema version 2) ---

/// ISO 8601 UTC with milliseconds, as the catalog writes who-and-when.
bool isUtcTime(const std::string& at) {
  // YYYY-MM-DDTHH:MM:SS.mmmZ, a digit wherever the pattern has a 9. (Not std::regex: GCC 12's
  // <regex> trips -Wmaybe-uninitialized in the sanitizer build.)
  constexpr std::string_view kPattern = "9999-99-99T99:99:99.999Z";
  if (at.size() != kPattern.size()) return false;
  for (std::size_t i = 0; i < at.size(); ++i) {
    const bool digit = at[i] >= '0' && at[i] <= '9';
    if (kPattern[i] == '9' ? !digit : at[i] != kPattern[i]) return false;
  }
  return true;
}

/// A catalog with one scene of `n` unlabelled segments; its segment ids.
std::vector<std::int64_t> unlabelledScene(Catalog& catalog, int n, const std::string& hash = "aa") {
  std::vector<CatalogSegment> segments;
  for (int i = 0; i < n; ++i) {
    segments.push_back(makeSegment(i, 3));
    segments.back().label.reset();
  }
  const std::int64_t scene = catalog.addScene(makeScene("desk", hash), segments);
  std::vector<std::int64_t> ids;
  for (const CatalogSegment& s : catalog.segments(scene, false)) ids.push_back(s.id);
  return ids;
}

TEST(CatalogLabels, SetChangeAndClearRecordWhoWhenAndThePreviousLabel) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::vector<std::int64_t> ids = unlabelledScene(catalog, 3);
  const std::int64_t scene = catalog.scenes()[0].id;
  const LabelEvent set = catalog.setLabel(ids[1], 1, "ana");
  EXPECT_EQ(set.segment_id, ids[1]);
  EXPECT_EQ(set.scene_id, scene);
  EXPECT_EQ(set.label, 1);
  EXPECT_FALSE(set.previous.has_value());
  EXPECT_EQ(set.by, "ana");
  EXPECT_TRUE(isUtcTime(set.at)) << set.at;
  EXPECT_FALSE(set.undoes.has_value());
  std::vector<CatalogSegment> segments = catalog.segments(scene, false);
  EXPECT_EQ(segments[1].label, 1);
  EXPECT_EQ(segments[1].labelled_by, "ana");
  EXPECT_EQ(segments[1].labelled_at, set.at);
  EXPECT_FALSE(segments[0].label.has_value());
  EXPECT_EQ(segments[0].labelled_by, "");
  EXPECT_EQ(segments[0].labelled_at, "");

  const LabelEvent changed =
      catalog.setLabel(ids[1], static_cast<int>(SegmentLabel::kUnsure), "ben");
  EXPECT_GT(changed.id, set.id);
  EXPECT_EQ(changed.label, 2);
  EXPECT_EQ(changed.previous, 1);
  EXPECT_GE(changed.at, set.at);  // the format sorts as the time does
  EXPECT_EQ(catalog.segments(scene, false)[1].labelled_by, "ben");
  const LabelEvent cleared = catalog.setLabel(ids[1], std::nullopt, "ana");
  EXPECT_FALSE(cleared.label.has_value());
  EXPECT_EQ(cleared.previous, 2);
  segments = catalog.segments(scene, true);
  EXPECT_FALSE(segments[1].label.has_value());
  EXPECT_EQ(segments[1].labelled_by, "");
  EXPECT_EQ(segments[1].vertices, makeSegment(1, 3).vertices);

  // The history, oldest first, as setLabel returned it.
  const std::vector<LabelEvent> events = catalog.labelEvents(scene);
  ASSERT_EQ(events.size(), 3u);
  const std::vector<LabelEvent> want = {set, changed, cleared};
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(events[i].id, want[i].id);
    EXPECT_EQ(events[i].segment_id, ids[1]);
    EXPECT_EQ(events[i].scene_id, scene);
    EXPECT_EQ(events[i].label, want[i].label);
    EXPECT_EQ(events[i].previous, want[i].previous);
    EXPECT_EQ(events[i].by, want[i].by);
    EXPECT_EQ(events[i].at, want[i].at);
    EXPECT_FALSE(events[i].undoes.has_value());
  }
  EXPECT_TRUE(catalog.labelEvents(scene + 100).empty());
}

TEST(CatalogLabels, UndoPutsThePreviousLabelBackAndUndoingAnUndoRedoes) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::vector<std::int64_t> ids = unlabelledScene(catalog, 2);
  const std::int64_t scene = catalog.scenes()[0].id;
  const LabelEvent first = catalog.setLabel(ids[0], 0, "ana");
  const LabelEvent second = catalog.setLabel(ids[0], 1, "ana");
  const LabelEvent undo = catalog.undoLabel(second.id, "ana");
  EXPECT_GT(undo.id, second.id);
  EXPECT_EQ(undo.undoes, second.id);
  EXPECT_EQ(undo.label, 0);
  EXPECT_EQ(undo.previous, 1);
  EXPECT_EQ(catalog.segments(scene, false)[0].label, 0);
  EXPECT_EQ(catalog.segments(scene, false)[0].labelled_by, "ana");
  // Undoing the undo puts the label it took away back.
  const LabelEvent redo = catalog.undoLabel(undo.id, "ben");
  EXPECT_EQ(redo.undoes, undo.id);
  EXPECT_EQ(redo.label, 1);
  EXPECT_EQ(catalog.segments(scene, false)[0].label, 1);
  // The label that comes back is ana's (second's), with its time: not credited to ben.
  EXPECT_EQ(catalog.segments(scene, false)[0].labelled_by, "ana");
  EXPECT_EQ(catalog.segments(scene, false)[0].labelled_at, second.at);
  EXPECT_EQ(redo.by, "ben");
  // Events in effect after it (the redo) keep the first from being undone.
  EXPECT_THROW(catalog.undoLabel(first.id, "ana"), LabelConflict);
  EXPECT_EQ(catalog.labelEvents(scene).size(), 4u);
  // Undoing a first label clears it (it had none before).
  const LabelEvent other = catalog.setLabel(ids[1], 2, "ana");
  const LabelEvent cleared = catalog.undoLabel(other.id, "ana");
  EXPECT_FALSE(cleared.label.has_value());
  EXPECT_EQ(cleared.previous, 2);
  EXPECT_FALSE(catalog.segments(scene, false)[1].label.has_value());
  EXPECT_EQ(catalog.labelCounts(scene).labelled, 1u);
}

TEST(CatalogLabels, UndoingTwiceGoesBackTwoStepsWithTheEarlierLabellersNames) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::vector<std::int64_t> ids = unlabelledScene(catalog, 1);
  const std::int64_t scene = catalog.scenes()[0].id;
  const LabelEvent a = catalog.setLabel(ids[0], 1, "ana");
  const LabelEvent b = catalog.setLabel(ids[0], 0, "ben");
  EXPECT_EQ(b.previous_by, "ana");
  EXPECT_EQ(b.previous_at, a.at);
  // ben undoes his label: ana's comes back as hers, at her time.
  catalog.undoLabel(b.id, "ben");
  CatalogSegment s = catalog.segments(scene, false)[0];
  EXPECT_EQ(s.label, 1);
  EXPECT_EQ(s.labelled_by, "ana");
  EXPECT_EQ(s.labelled_at, a.at);
  // b is undone, so a is the label in effect and can be undone too: no label at all.
  EXPECT_THROW(catalog.undoLabel(b.id, "ben"), LabelConflict);  // already undone
  const LabelEvent second_undo = catalog.undoLabel(a.id, "ana");
  EXPECT_FALSE(second_undo.label.has_value());
  EXPECT_FALSE(catalog.segments(scene, false)[0].label.has_value());
  EXPECT_EQ(catalog.labelCounts(scene).labelled, 0u);
  EXPECT_EQ(catalog.labelEvents(scene).size(), 4u);
}

TEST(CatalogLabels, UndoAfterSomebodyElsesChangeIsAConflictThatChangesNothing) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  Catalog mine(file);
  Catalog theirs(file);  // another tab's or person's server
  const std::vector<std::int64_t> ids = unlabelledScene(mine, 2);
  const std::int64_t scene = mine.scenes()[0].id;
  const LabelEvent e = mine.setLabel(ids[0], 1, "ana");
  theirs.setLabel(ids[0], 0, "ben");
  try {
    mine.undoLabel(e.id, "ana");
    ADD_FAILURE() << "no conflict";
  } catch (const LabelConflict& conflict) {
    EXPECT_NE(std::string(conflict.what()).find("by ben"), std::string::npos) << conflict.what();
  }
  // Even when the label is back to the event's: the change since is somebody's decision.
  theirs.setLabel(ids[0], 1, "ben");
  EXPECT_THROW(mine.undoLabel(e.id, "ana"), LabelConflict);
  EXPECT_EQ(mine.segments(scene, false)[0].label, 1);
  EXPECT_EQ(mine.labelEvents(scene).size(), 3u);
  // An event already undone is a conflict too.
  const LabelEvent latest = mine.labelEvents(scene).back();
  theirs.undoLabel(latest.id, "ben");
  try {
    mine.undoLabel(latest.id, "ana");
    ADD_FAILURE() << "no conflict";
  } catch (const LabelConflict& conflict) {
    EXPECT_NE(std::string(conflict.what()).find("already undone"), std::string::npos)
        << conflict.what();
  }
  EXPECT_EQ(mine.labelEvents(scene).size(), 4u);
  EXPECT_EQ(mine.segments(scene, false)[0].label, 0);
}

TEST(CatalogLabels, BadLabelsUnknownIdsAndNoNameAreRefusedLeavingTheFileAlone) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  Catalog catalog(file);
  const std::vector<std::int64_t> ids = unlabelledScene(catalog, 2);
  const LabelEvent e = catalog.setLabel(ids[0], 1, "ana");
  const std::string before = readBytes(file);
  EXPECT_THROW(catalog.setLabel(ids[1], 3, "ana"), std::invalid_argument);
  EXPECT_THROW(catalog.setLabel(ids[1], -1, "ana"), std::invalid_argument);
  EXPECT_THROW(catalog.setLabel(ids[1] + 1000, 1, "ana"), std::invalid_argument);
  EXPECT_THROW(catalog.setLabel(ids[1], 1, ""), std::invalid_argument);
  EXPECT_THROW(catalog.undoLabel(e.id + 1000, "ana"), std::invalid_argument);
  EXPECT_THROW(catalog.undoLabel(e.id, ""), std::invalid_argument);
  // Names that are not names: what a terminal obeys (an escape, a text-direction override), and
  // what shows nothing (invisible spaces only, a leading byte order mark), or is not UTF-8.
  for (const char* by : {"a\x1b[31mb", "ana\u202e", "\u200f", "\u200b\u00a0\u3000", "\ufeffana",
                         "a\nb", "\xc0\xaf", "a\u0085b"}) {
    EXPECT_THROW(catalog.setLabel(ids[1], 1, by), std::invalid_argument) << by;
    EXPECT_THROW(catalog.undoLabel(e.id, by), std::invalid_argument) << by;
    EXPECT_FALSE(labellerNameProblem(by).empty()) << by;
    EXPECT_EQ(labellerNameProblem(by).find(by), std::string::npos) << "the name is not quoted";
  }
  EXPECT_EQ(labellerNameProblem("Zoë Ångström-李"), "");
  EXPECT_THROW(catalog.setLabels(catalog.scenes()[0].id, {{ids[1], 1}, {ids[0], 7}}),
               std::invalid_argument);
  EXPECT_EQ(readBytes(file), before);
  EXPECT_EQ(catalog.labelEvents(catalog.scenes()[0].id).size(), 1u);
}

TEST(CatalogLabels, CountsAndScenesWithAHash) {
  TempDir dir;
  Catalog catalog(dir / "catalog.sqlite");
  const std::vector<std::int64_t> ids = unlabelledScene(catalog, 6);
  const std::int64_t scene = catalog.scenes()[0].id;
  LabelCounts counts = catalog.labelCounts(scene);
  EXPECT_EQ(counts.segments, 6u);
  EXPECT_EQ(counts.labelled, 0u);
  catalog.setLabel(ids[0], 1, "ana");
  catalog.setLabel(ids[1], 1, "ana");
  catalog.setLabel(ids[2], 0, "ana");
  catalog.setLabel(ids[3], 2, "ana");
  catalog.setLabel(ids[4], 2, "ana");
  catalog.setLabel(ids[4], std::nullopt, "ana");
  counts = catalog.labelCounts(scene);
  EXPECT_EQ(counts.segments, 6u);
  EXPECT_EQ(counts.labelled, 4u);
  EXPECT_EQ(counts.objects, 2u);
  EXPECT_EQ(counts.not_objects, 1u);
  EXPECT_EQ(counts.unsure, 1u);
  EXPECT_EQ(catalog.labelCounts(scene + 100).segments, 0u);
  // setLabels counts and records events too.
  catalog.setLabels(scene, {{ids[5], 0}, {ids[0], 0}}, "bulk");
  counts = catalog.labelCounts(scene);
  EXPECT_EQ(counts.objects, 1u);
  EXPECT_EQ(counts.not_objects, 3u);
  EXPECT_EQ(catalog.labelEvents(scene).back().by, "bulk");
  EXPECT_EQ(catalog.labelEvents(scene).back().previous, 1);

  const std::int64_t coarse =
      catalog.addScene(makeScene("desk", "aa", "coarser"), {makeSegment(1)});
  catalog.addScene(makeScene("shelf", "bb"), {makeSegment(1)});
  const std::vector<CatalogScene> same = catalog.scenesWithHash("aa");
  ASSERT_EQ(same.size(), 2u);
  EXPECT_EQ(same[0].id, scene);
  EXPECT_EQ(same[1].id, coarse);
  EXPECT_EQ(same[1].settings, "coarser");
  EXPECT_TRUE(catalog.scenesWithHash("cc").empty());

  // A replaced scene's labels and history go with its segments.
  const std::int64_t replaced = catalog.addScene(makeScene("desk", "aa"), {makeSegment(1)});
  EXPECT_TRUE(catalog.labelEvents(scene).empty());
  EXPECT_EQ(catalog.labelCounts(replaced).labelled, 1u);  // makeSegment(1)'s own label
  EXPECT_EQ(catalog.segments(replaced, false)[0].labelled_by, "objscan");
  EXPECT_EQ(sqlInteger(dir / "catalog.sqlite", "SELECT count(*) FROM segment_labels"), 3);
}

/// The schema objscan wrote before labels had who and when (version 1), verbatim.
constexpr const char* kSchemaVersion1 = R"sql(
CREATE TABLE scenes (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  name TEXT NOT NULL,
  content_hash TEXT NOT NULL,
  settings TEXT NOT NULL,
  vertex_count INTEGER NOT NULL CHECK (vertex_count >= 0),
  added TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%SZ', 'now')),
  UNIQUE (content_hash, settings));
CREATE TABLE segments (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  scene_id INTEGER NOT NULL REFERENCES scenes(id) ON DELETE CASCADE,
  scale REAL CHECK (scale >= 0),
  centroid_x REAL, centroid_y REAL, centroid_z REAL,
  axes BLOB NOT NULL CHECK (length(axes) = 36),
  eigenvalue_0 REAL, eigenvalue_1 REAL, eigenvalue_2 REAL,
  extent_0 REAL CHECK (extent_0 >= 0),
  extent_1 REAL CHECK (extent_1 >= 0),
  extent_2 REAL CHECK (extent_2 >= 0),
  compactness REAL, symmetry REAL, smoothness REAL, local_convexity REAL, global_convexity REAL,
  label INTEGER CHECK (label IN (0, 1)));
CREATE INDEX segments_by_scene ON segments(scene_id);
CREATE TABLE segment_vertices (
  segment_id INTEGER PRIMARY KEY REFERENCES segments(id) ON DELETE CASCADE,
  vertices BLOB NOT NULL);
PRAGMA user_version = 1;
)sql";

/// A version-1 catalog: one scene of three segments labelled 1, 0 and nothing, with vertices.
void writeVersion1Catalog(const fs::path& file, const std::string& labels = "1, 0, NULL") {
  std::string rows;
  const std::string axes = "x'" + std::string(72, '0') + "'";
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t comma = labels.find(',', start);
    const std::string label = labels.substr(start, comma - start);
    start = comma + 1;
    rows +=
        "INSERT INTO segments (scene_id, scale, centroid_x, centroid_y, centroid_z, axes, "
        "eigenvalue_0, eigenvalue_1, eigenvalue_2, extent_0, extent_1, extent_2, compactness, "
        "symmetry, smoothness, local_convexity, global_convexity, label) VALUES (1, 5, 0, 0, "
        "0, " +
        axes + ", 1, 1, 1, 0.1, 0.1, 0.1, 0.5, 0.5, 0.5, 0.5, " + std::to_string(0.1 * i) + ", " +
        label + ");" +
        "INSERT INTO segment_vertices VALUES (last_insert_rowid(), x'0100000002000000');";
  }
  sql(file, std::string(kSchemaVersion1) +
                "PRAGMA ignore_check_constraints = 1;"
                "INSERT INTO scenes (name, content_hash, settings, vertex_count) "
                "VALUES ('desk.ply', 'aa', 'scales=5..2560', 10);" +
                rows);
}

TEST(CatalogLabels, AVersion1FileIsUpgradedKeepingItsLabels) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  writeVersion1Catalog(file);
  {
    Catalog catalog(file);
    EXPECT_EQ(sqlInteger(file, "PRAGMA user_version"), 2);
    const std::vector<CatalogSegment> segments = catalog.segments(1, true);
    ASSERT_EQ(segments.size(), 3u);
    EXPECT_EQ(segments[0].label, 1);
    EXPECT_EQ(segments[1].label, 0);
    EXPECT_FALSE(segments[2].label.has_value());
    EXPECT_EQ(segments[0].labelled_by, "objscan (schema 1)");
    EXPECT_TRUE(isUtcTime(segments[0].labelled_at)) << segments[0].labelled_at;
    EXPECT_EQ(segments[2].labelled_by, "");
    EXPECT_EQ(segments[1].vertices, (std::vector<std::int32_t>{1, 2}));
    EXPECT_DOUBLE_EQ(segments[2].measures.global_convexity, 0.2);
    const std::vector<LabelEvent> events = catalog.labelEvents(1);
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(events[0].segment_id, segments[0].id);
    EXPECT_EQ(events[0].label, 1);
    EXPECT_FALSE(events[0].previous.has_value());
    EXPECT_EQ(events[1].label, 0);
    EXPECT_EQ(events[1].by, "objscan (schema 1)");
    // The old column is gone: labels have one home.
    EXPECT_EQ(sqlInteger(file,
                         "SELECT count(*) FROM pragma_table_info('segments') "
                         "WHERE name = 'label'"),
              0);
    catalog.setLabel(segments[2].id, 2, "ana");
  }
  // Reopened: already version 2, nothing to do.
  const Catalog reopened(file);
  EXPECT_EQ(reopened.labelCounts(1).labelled, 3u);
  EXPECT_EQ(reopened.labelEvents(1).size(), 3u);
  EXPECT_EQ(sqlText(file, "PRAGMA integrity_check"), "ok");
}

TEST(CatalogLabels, AVersion1FileThatCannotBeUpgradedIsAnErrorAndLeftAsItWas) {
  TempDir dir;
  // A label version 1 never allowed (its CHECK switched off): the check of the whole file finds
  // it before the upgrade would.
  const fs::path damaged = dir / "damaged.sqlite";
  writeVersion1Catalog(damaged, "1, 5, NULL");
  std::string before = readBytes(damaged);
  expectInputError([&] { Catalog catalog(damaged); }, damaged,
                   "damaged: SQLite's quick_check finds \"CHECK constraint failed");
  EXPECT_EQ(readBytes(damaged), before);
  // A file that cannot be written (here: no byte may be written, as on a full disk).
  const fs::path full = dir / "full.sqlite";
  writeVersion1Catalog(full);
  before = readBytes(full);
  try {
    const objscan::testing::FileSizeLimit limit(0);
    Catalog catalog(full);
    ADD_FAILURE() << "no error";
  } catch (const OutputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(full.string() + ": ", 0), 0u) << what;
    EXPECT_NE(what.find("schema version 1"), std::string::npos) << what;
    EXPECT_NE(what.find("the file is unchanged"), std::string::npos) << what;
  }
  EXPECT_EQ(readBytes(full), before);
  EXPECT_EQ(sqlInteger(full, "PRAGMA user_version"), 1);
  // And once it can be written, it is upgraded.
  EXPECT_EQ(Catalog(full).labelCounts(1).objects, 1u);
}

TEST(CatalogLabels, TwoConnectionsLabellingAtOnceLoseNoEvent) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  constexpr int kLabels = 200;
  std::vector<std::int64_t> ids;
  std::int64_t scene = 0;
  {
    Catalog catalog(file);
    ids = unlabelledScene(catalog, 20);
    scene = catalog.scenes()[0].id;
  }
  // Two viewers' servers on one file, each labelling the same segments over and over.
  const auto label = [&](const std::string& who, int value) {
    Catalog catalog(file);
    for (int i = 0; i < kLabels; ++i) {
      catalog.setLabel(ids[static_cast<std::size_t>(i) % ids.size()], value, who);
    }
  };
  std::thread ana(label, "ana", 1), ben(label, "ben", 0);
  ana.join();
  ben.join();

  const Catalog catalog(file);
  const std::vector<LabelEvent> events = catalog.labelEvents(scene);
  ASSERT_EQ(events.size(), 2u * kLabels);
  // Each event saw the label the one before it (of its segment) left: no write was lost.
  std::map<std::int64_t, std::optional<int>> label_of;
  std::size_t by_ana = 0;
  for (std::size_t i = 0; i < events.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(events[i].id, events[i - 1].id);
      EXPECT_GE(events[i].at, events[i - 1].at);
    }
    EXPECT_EQ(events[i].previous, label_of[events[i].segment_id]) << i;
    label_of[events[i].segment_id] = events[i].label;
    by_ana += events[i].by == "ana";
  }
  EXPECT_EQ(by_ana, static_cast<std::size_t>(kLabels));
  for (const CatalogSegment& s : catalog.segments(scene, false)) EXPECT_EQ(s.label, label_of[s.id]);
  EXPECT_EQ(sqlText(file, "PRAGMA integrity_check"), "ok");
}

/// FNV-1a, 64 bits, byte by byte: the reference for contentHash().
std::string fnv1a(const std::string& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ull;
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

TEST(ContentHash, MatchesFnv1aTestVectors) {
  TempDir dir;
  // The published FNV-1a 64-bit test vectors (Fowler, Noll, Vo).
  writeBytes(dir / "empty", "");
  writeBytes(dir / "a", "a");
  writeBytes(dir / "foobar", "foobar");
  EXPECT_EQ(contentHash(dir / "empty"), "cbf29ce484222325");
  EXPECT_EQ(contentHash(dir / "a"), "af63dc4c8601ec8c");
  EXPECT_EQ(contentHash(dir / "foobar"), "85944171f73967e8");
}

TEST(ContentHash, LongFilesHashAcrossReadChunks) {
  TempDir dir;
  std::mt19937 rng(5);
  std::string bytes(3 * (1 << 20) + 7, '\0');
  for (char& c : bytes) c = static_cast<char>(rng() & 0xff);
  writeBytes(dir / "mesh.ply", bytes);
  EXPECT_EQ(contentHash(dir / "mesh.ply"), fnv1a(bytes));
  bytes[bytes.size() / 2] ^= 1;
  writeBytes(dir / "mesh.ply", bytes);
  EXPECT_EQ(contentHash(dir / "mesh.ply"), fnv1a(bytes));
}

TEST(ContentHash, UnreadableFileIsAnInputError) {
  TempDir dir;
  expectInputError([&] { contentHash(dir / "missing.ply"); }, dir / "missing.ply",
                   "cannot be opened");
  expectInputError([&] { contentHash(dir.path()); }, dir.path(), "is a folder");
}

}  // namespace
}  // namespace objscan::discovery
