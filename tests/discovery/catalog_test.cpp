// The SQLite catalog on real files in a temporary folder: round trips, replacement, atomicity,
// and every kind of file that is not a catalog of this objscan. Files that other programs would
// make (a foreign database, a newer schema) are made here through SQLite's C API directly.

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
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
  bad[2].label = 2;
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
  sql(file,
      "UPDATE segments SET compactness = 0.5; PRAGMA ignore_check_constraints = 1; "
      "UPDATE segments SET extent_1 = -0.2 WHERE id = (SELECT max(id) FROM segments)");
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

TEST(Catalog, EmptyFileBecomesANewCatalog) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  writeBytes(file, "");
  Catalog(file).addScene(makeScene("desk", "aa"), {makeSegment(0)});
  EXPECT_EQ(Catalog(file).segmentCount(), 1u);
}

TEST(Catalog, NewerSchemaVersionIsAnInputError) {
  TempDir dir;
  const fs::path file = dir / "catalog.sqlite";
  { Catalog catalog(file); }
  sql(file, "PRAGMA user_version = 2");
  expectInputError([&] { Catalog catalog(file); }, file,
                   "catalog schema version 2 is newer than this objscan's (1)");
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
